!> The template half of src/io/hdf5_files: how a rank's case files start from its first one (the
!> type file_template there says what it keeps). The first file records its root attributes and
!> leaves its images; a later file compares its root attributes with the recorded ones, writes
!> only those that differ once it is opened, and, if its datasets have the first file's layout,
!> opens from a copy of that file's image with its own values put in place.
submodule (hdf5_files) hdf5_file_templates
  implicit none (type, external)

contains

  !> Creates a file in memory from `template` (type file_template): as an empty file whose root
  !> attributes are recorded in it if it holds none yet; else the file is opened only at
  !> settle_template, as a copy of one of the template's images, and until then its root
  !> attributes are compared with the template's and those that differ wait there. So between
  !> this call and settle_template only the root attribute writers (set_text .. set_integers,
  !> without `object`) may be used. Call template_datasets and settle_template once the root
  !> attributes are set, before any dataset is written. A failure if HDF5 failed.
  module procedure create_from_template
    if (.not. template%ready) then
      call self%create_in_memory(failure)
      if (failure%failed()) return
      template%recording = .true.
      template%count = 0
      if (.not. allocated(template%attributes)) allocate (template%attributes(256))
      self%template => template
      self%origin => template
      self%first_of_template = .true.
      return
    end if
    call open_library(failure)
    if (failure%failed()) return
    self%id = -1
    self%deferred = .true.
    self%from_datasets = .false.
    self%origin => template
    self%first_of_template = .false.
    self%fresh = .true.
    template%waiting_count = 0
    if (.not. allocated(template%waiting)) allocate (template%waiting(64))
    template%recording = .false.
    template%touched = spread(.false., 1, template%count)
    template%cursor = 0
    self%template => template
  end procedure create_from_template

  !> Before the datasets are written, with their `layout` (hdf5_series; '' for none to share):
  !> `held` if the file will hold them from its template's image (then `put_values` gives each
  !> numeric dataset its values, and nothing else is written to them). The first file of a
  !> template records the layout. Nothing held for a file without a template.
  module procedure template_datasets
    held = .false.
    if (.not. associated(self%origin)) return
    associate (template => self%origin)
      if (self%first_of_template) then
        template%layout = layout
      else if (self%deferred .and. allocated(template%dataset_image)) then
        held = len(layout) > 0 .and. layout == template%layout
        if (held) template%copy = template%dataset_image
      end if
    end associate
    self%from_datasets = held
  end procedure template_datasets

  !> The values of the numeric dataset `name` of a file that holds its template's datasets
  !> (template_datasets), as the bytes of the stored type: `bytes` must fill the dataset.
  !> A failure if the template has no such dataset or not of that size.
  module procedure put_values
    integer :: k, first, last

    call hdf5_failure(failure, -1, name)
    if (.not. (associated(self%origin) .and. self%from_datasets)) return
    associate (template => self%origin)
      first = 1
      do k = 1, size(template%offsets)
        last = first + index(template%names(first:), new_line('a')) - 2
        if (template%names(first:last) == name) then
          if (template%sizes(k) /= len(bytes, int64)) return
          template%copy(template%offsets(k) + 1:template%offsets(k) + template%sizes(k)) = bytes
          if (template%sealed(k)) call c_seal_chunk(template%copy(template%offsets(k) + 1:), &
                                                    int(template%sizes(k), c_long))
          failure = failure_type()
          return
        end if
        first = last + 2
      end do
    end associate
  end procedure put_values

  !> Ends the root attributes' writing from a template (create_from_template): a recorded file
  !> leaves its image in the template; a file made from one is opened (from the image with its
  !> datasets if template_datasets said so, else from the root attributes' image), given the
  !> root attributes that differ and loses the template's attributes it did not set. Nothing to
  !> do for a file without a template. A failure if HDF5 failed.
  module procedure settle_template
    integer(c_long) :: size
    integer(c_int64_t) :: id
    character(len=32) :: label
    integer :: k, stat

    stat = 0
    if (.not. associated(self%template)) return
    associate (template => self%template)
      if (template%recording) then
        template%recording = .false.
        size = c_image_size(int(self%id, c_int64_t))
        if (size > 0) then
          if (allocated(template%image)) deallocate (template%image)
          allocate (character(len=size) :: template%image)
          template%ready = c_copy_image(int(self%id, c_int64_t), template%image, size) == 0
          template%image_texts = book_of(self%id)
        end if
      else
        if (self%deferred) then
          memory_files = memory_files + 1
          write (label, '("eme_memory_file_", i0)') memory_files
          if (self%from_datasets) then
            stat = int(c_open_image(trim(label)//c_null_char, template%copy, len(template%copy, kind=c_long), id))
            if (stat == 0) stat = start_book(id, template%dataset_texts)
          else
            stat = int(c_open_image(trim(label)//c_null_char, template%image, len(template%image, kind=c_long), id))
            if (stat == 0) stat = start_book(id, template%image_texts)
          end if
          self%id = int(id, hid_t)
          self%deferred = .false.
          call hdf5_failure(failure, stat, 'settle_template')
          do k = 1, template%waiting_count
            if (failure%failed()) exit
            call write_remembered(self%id, template%waiting(k), failure)
          end do
          template%waiting_count = 0
        end if
        do k = 1, template%count
          if (failure%failed()) exit
          if (.not. template%touched(k)) &
            stat = int(c_delete_attribute(int(self%id, c_int64_t), template%attributes(k)%name//c_null_char))
          call hdf5_failure(failure, stat, template%attributes(k)%name)
        end do
      end if
    end associate
    nullify (self%template)
  end procedure settle_template

  !> Once the datasets are written (before the attributes that differ from file to file): the
  !> first file of a template leaves there its image and where its numeric datasets' values lie
  !> (template_datasets), if each lies in one place (contiguous, or one chunk with its checksum).
  !> Keeping them only saves later files work: if they cannot be kept, later files make their
  !> own datasets.
  module procedure keep_template_datasets
    integer(c_long) :: image_size
    integer(c_int) :: count
    character(len=8192) :: names
    character(len=:), allocatable :: image
    integer(c_int64_t) :: offsets(256), sizes(256)
    integer(c_int) :: sealed(256)

    if (.not. associated(self%origin)) return
    associate (template => self%origin)
      if (self%first_of_template .and. template%ready .and. len(template%layout) > 0) then
        image_size = c_image_size(int(self%id, c_int64_t))
        if (image_size > 0) then
          allocate (character(len=image_size) :: image)
          if (c_copy_image(int(self%id, c_int64_t), image, image_size) /= 0) image_size = 0
        end if
        count = int(size(offsets), c_int)
        ! Nonzero: a dataset whose values do not lie in one place (several chunks, or a checksum
        ! not computed as here), more datasets or names than the room here, or an HDF5 error;
        ! each only leaves later files to make their datasets.
        if (image_size > 0) then
          if (c_numeric_datasets(int(self%id, c_int64_t), image, image_size, names, int(len(names), c_int), offsets, &
                                 sizes, sealed, count) == 0) then
            template%names = names(1:index(names, c_null_char) - 1)
            template%offsets = int(offsets(1:count), int64)
            template%sizes = int(sizes(1:count), int64)
            template%sealed = sealed(1:count) /= 0
            call move_alloc(image, template%dataset_image)
            template%dataset_texts = book_of(self%id)
          end if
        end if
      end if
    end associate
    nullify (self%origin)
    self%first_of_template = .false.
    self%from_datasets = .false.
  end procedure keep_template_datasets

  ! The texts the open file `id` holds, as the book of its text checksum keeps them
  ! (src/io/hdf5_text_checksum.c): kept with an image of the file, for the files made from it.
  ! '' if none.
  function book_of(id) result(text)
    integer(hid_t), intent(in) :: id
    character(len=:), allocatable :: text
    integer(c_long) :: size

    text = ''
    size = c_texts_export(int(id, c_int64_t), text, 0_c_long)
    if (size <= 0) return
    deallocate (text)
    allocate (character(len=size) :: text)
    if (c_texts_export(int(id, c_int64_t), text, size) /= size) text = ''
  end function book_of

  ! Starts the book of the text checksum of `id`, a file just opened from an image, from the texts
  ! kept with the image (read back from the file if none were kept). 0, or -1.
  integer function start_book(id, texts)
    integer(c_int64_t), intent(in) :: id
    character(len=:), allocatable, intent(in) :: texts

    if (allocated(texts)) then
      if (len(texts) > 0) then
        start_book = int(c_texts_import(id, texts, len(texts, kind=c_long)))
        return
      end if
    end if
    start_book = int(c_texts_begin(id, 1_c_int))
  end function start_book

  ! A root attribute `name` about to be written with `value` (a kind letter and its bytes):
  ! recorded while a template records; against a template, `write` only if the template's value
  ! differs, and `fresh` (no existence query) only if the template has no such attribute; in a
  ! `deferred` file (not open yet), what is to be written waits in the template instead.
  ! Without a template: written, fresh as the file is.
  module procedure compare_with_template
    integer :: k, i

    write = .true.
    fresh = file_fresh
    if (.not. associated(template)) return
    if (template%recording) then
      call remember(template%attributes, template%count, name, value)
      return
    end if
    ! The attributes come in the template's order: look at the next one first.
    k = 0
    if (template%cursor < template%count) then
      if (template%attributes(template%cursor + 1)%name == name) k = template%cursor + 1
    end if
    if (k == 0) then
      do i = 1, template%count
        if (template%attributes(i)%name == name) then
          k = i
          exit
        end if
      end do
    end if
    if (k /= 0) then                    ! else not in the template: created as in a new file
      template%cursor = k
      template%touched(k) = .true.
      fresh = .false.
      write = template%attributes(k)%value /= value .or. len(template%attributes(k)%value) /= len(value)
    end if
    if (write .and. deferred) then
      call remember(template%waiting, template%waiting_count, name, merge('F', 'E', fresh)//value)
      write = .false.
    end if
  end procedure compare_with_template

  ! Appends (name, value) to list(1:count), growing the list as needed.
  subroutine remember(list, count, name, value)
    type(remembered_attribute), allocatable, intent(inout) :: list(:)
    integer, intent(inout) :: count
    character(len=*), intent(in) :: name, value
    type(remembered_attribute), allocatable :: larger(:)
    integer :: i

    if (count == size(list)) then
      allocate (larger(2*count))
      do i = 1, count
        call move_alloc(list(i)%name, larger(i)%name)
        call move_alloc(list(i)%value, larger(i)%value)
      end do
      call move_alloc(larger, list)
    end if
    count = count + 1
    list(count)%name = name
    list(count)%value = value
  end subroutine remember

  ! Writes a root attribute that waited (compare_with_template) into the now open file `file`:
  ! its value is 'F' (fresh) or 'E' (may exist), the kind letter and the value's bytes.
  subroutine write_remembered(file, attribute, failure)
    integer(hid_t), intent(in) :: file
    type(remembered_attribute), intent(in) :: attribute
    type(failure_type), intent(out) :: failure
    logical :: fresh
    integer :: count

    fresh = attribute%value(1:1) == 'F'
    count = (len(attribute%value) - 2)/8
    associate (letter => attribute%value(2:2), bytes => attribute%value(3:))
      select case (letter)
      case ('t')
        call hdf5_failure(failure, int(c_write_text_attribute(int(file, c_int64_t), attribute%name//c_null_char, &
                                       bytes//c_null_char, merge(1_c_int, 0_c_int, fresh))), attribute%name)
      case ('a')
        call hdf5_failure(failure, int(c_write_text_array_attribute(int(file, c_int64_t), attribute%name//c_null_char, &
                                                                     bytes//c_null_char)), attribute%name)
      case ('r', 'i')
        call write_numeric_attribute(file, attribute%name, transfer(bytes, [0.0_real64], count), .true., fresh, failure, &
                                     integer_valued=letter == 'i')
      case ('v', 'n')
        call write_numeric_attribute(file, attribute%name, transfer(bytes, [0.0_real64], count), .false., fresh, &
                                     failure, integer_valued=letter == 'n')
      case default
        call hdf5_failure(failure, -1, attribute%name)
      end select
    end associate
  end subroutine write_remembered
end submodule hdf5_file_templates
