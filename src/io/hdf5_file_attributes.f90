!> The attribute half of src/io/hdf5_files: text, real and integer attributes of a file's root
!> (compared with the file's template first, if it has one: src/io/hdf5_file_templates) or of one
!> of its objects, numbers rewritten in place when their count is unchanged; and the root's text
!> and numbers read back.
submodule (hdf5_files) hdf5_file_attributes
  use hdf5, only: hsize_t, h5screate_simple_f, h5screate_f, h5sclose_f, H5S_SCALAR_F, h5dopen_f, h5dclose_f, &
                  H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER, h5acreate_f, h5aclose_f, h5awrite_f, h5aexists_f, h5aopen_f, &
                  h5aread_f, h5aget_space_f, h5sget_simple_extent_npoints_f
  implicit none (type, external)

  interface
    function c_read_text_attribute(object, name, text, capacity) result(status) &
        bind(c, name='eme_h5_read_text_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object
      character(kind=c_char), intent(in) :: name(*)
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: capacity
      integer(c_int) :: status
    end function c_read_text_attribute
  end interface

contains

  !> Text attribute on the file root, or on object `object` if given (replaces an old value).
  module procedure set_text
    integer(hid_t) :: target_id
    logical :: write, fresh

    target_id = self%id
    fresh = self%fresh
    if (present(object)) then
      target_id = object
    else
      call compare_with_template(self%template, name, 't'//value, write, fresh, self%fresh, self%deferred)
      if (.not. write) return
    end if
    call hdf5_failure(failure, int(c_write_text_attribute(int(target_id, c_int64_t), name//c_null_char, &
                                   value//c_null_char, merge(1_c_int, 0_c_int, fresh))), name)
  end procedure set_text

  !> Array of texts as one attribute on the file root, or on object `object` if given (h5py: an
  !> array of str).
  module procedure set_texts
    integer(hid_t) :: target_id
    logical :: write, fresh

    target_id = self%id
    if (present(object)) then
      target_id = object
    else
      call compare_with_template(self%template, name, 'a'//joined_lines(values), write, fresh, self%fresh, self%deferred)
      if (.not. write) return
    end if
    call hdf5_failure(failure, int(c_write_text_array_attribute(int(target_id, c_int64_t), name//c_null_char, &
                                                                 joined_lines(values)//c_null_char)), name)
  end procedure set_texts

  !> Array of texts as one attribute of the dataset `dataset` (h5py: an array of str).
  module procedure set_dataset_texts
    integer(hid_t) :: dataset_id
    integer :: stat, close_stat

    call h5dopen_f(self%id, dataset, dataset_id, stat)
    if (stat == 0) then
      stat = int(c_write_text_array_attribute(int(dataset_id, c_int64_t), name//c_null_char, &
                                              joined_lines(values)//c_null_char))
      call h5dclose_f(dataset_id, close_stat)
      if (stat == 0) stat = close_stat
    end if
    call hdf5_failure(failure, stat, dataset//' '//name)
  end procedure set_dataset_texts

  !> Scalar real attribute on the file root; with `units`, a text attribute <name>_units too.
  module procedure set_real
    logical :: write, fresh

    call compare_with_template(self%template, name, 'r'//bytes_of([value]), write, fresh, self%fresh, self%deferred)
    if (write) call write_numeric_attribute(self%id, name, [value], .true., fresh, failure)
    if (.not. failure%failed() .and. present(units)) call self%set_text(name//'_units', units, failure)
  end procedure set_real

  !> Real-array attribute on the file root; with `units`, a text attribute <name>_units too.
  module procedure set_reals
    logical :: write, fresh

    call compare_with_template(self%template, name, 'v'//bytes_of(values), write, fresh, self%fresh, self%deferred)
    if (write) call write_numeric_attribute(self%id, name, values, .false., fresh, failure, row_length=row_length)
    if (.not. failure%failed() .and. present(units)) call self%set_text(name//'_units', units, failure)
  end procedure set_reals

  !> Scalar integer attribute on the file root; with `units`, a text attribute <name>_units too.
  module procedure set_integer
    logical :: write, fresh

    call compare_with_template(self%template, name, 'i'//bytes_of([real(value, real64)]), write, fresh, self%fresh, self%deferred)
    if (write) call write_numeric_attribute(self%id, name, [real(value, real64)], .true., fresh, failure, &
                                            integer_valued=.true.)
    if (.not. failure%failed() .and. present(units)) call self%set_text(name//'_units', units, failure)
  end procedure set_integer

  !> Integer-array attribute on the file root, or on object `object` if given.
  module procedure set_integers
    integer(hid_t) :: target_id
    logical :: write, fresh

    target_id = self%id
    fresh = self%fresh
    write = .true.
    if (present(object)) then
      target_id = object
    else
      call compare_with_template(self%template, name, 'n'//bytes_of(real(values, real64)), write, fresh, self%fresh, self%deferred)
    end if
    if (write) call write_numeric_attribute(target_id, name, real(values, real64), .false., fresh, failure, &
                                            integer_valued=.true.)
  end procedure set_integers

  !> The text attribute `name` of the file root, whole however long (a run's effective namelist
  !> of per-spring arrays runs to tens of kB); a failure if it is missing.
  module procedure get_text
    character(len=:), allocatable :: buffer
    integer :: capacity, length

    capacity = 4096
    do
      allocate (character(len=capacity) :: buffer)
      call hdf5_failure(failure, int(c_read_text_attribute(int(self%id, c_int64_t), name//c_null_char, buffer, &
                                                           int(capacity, c_int))), name)
      length = max(0, index(buffer, c_null_char) - 1)
      if (failure%failed() .or. length < capacity - 1) exit
      ! The text filled the buffer, so C may have cut it: read it again into twice the room.
      deallocate (buffer)
      capacity = 2*capacity
    end do
    value = buffer(1:length)
  end procedure get_text

  !> The numeric attribute `name` of the file root (a scalar or an array, as reals); a failure if
  !> it is missing or not numeric.
  module procedure get_reals
    integer(hid_t) :: attribute, space
    integer(hsize_t) :: points, dims(1)
    integer :: stat, ignored

    allocate (values(0))
    call h5aopen_f(self%id, name, attribute, stat)
    call hdf5_failure(failure, stat, name)
    if (stat /= 0) return
    call h5aget_space_f(attribute, space, stat)
    if (stat == 0) call h5sget_simple_extent_npoints_f(space, points, stat)
    if (stat == 0) then
      deallocate (values)
      allocate (values(points))
      dims = [points]
      call h5aread_f(attribute, H5T_NATIVE_DOUBLE, values, dims, stat)
      call h5sclose_f(space, ignored)
    end if
    call h5aclose_f(attribute, ignored)
    call hdf5_failure(failure, stat, name)
  end procedure get_reals

  !> A numeric attribute of `object`: a scalar or an array of `values` (with `row_length`, rows of
  !> that many values: h5py's shape (size(values)/row_length, row_length)), stored as integers if
  !> `integer_valued`; an existing one is rewritten in place if it holds as many values, else
  !> replaced (`fresh`: the object has no attributes yet, nothing to look up).
  module procedure write_numeric_attribute
    integer(hid_t) :: space, attribute
    integer(hsize_t), allocatable :: dims(:)
    integer(hsize_t) :: points
    logical :: exists, as_integer
    integer :: stat, ignored, close_stat

    as_integer = .false.
    if (present(integer_valued)) as_integer = integer_valued
    dims = [int(size(values), hsize_t)]
    if (present(row_length)) then
      if (row_length > 0) dims = [int(row_length, hsize_t), int(size(values)/row_length, hsize_t)]
    end if
    stat = 0
    steps: block
      if (.not. fresh) then
        call h5aexists_f(object, name, exists, stat)
        if (stat /= 0) exit steps
        if (exists) then
          ! In place if the stored attribute has the same number of values (no change to the object
          ! header's layout); otherwise it is replaced.
          call h5aopen_f(object, name, attribute, stat)
          if (stat /= 0) exit steps
          call h5aget_space_f(attribute, space, stat)
          if (stat == 0) call h5sget_simple_extent_npoints_f(space, points, stat)
          if (stat == 0) call h5sclose_f(space, ignored)
          if (stat == 0 .and. points == size(values, kind=hsize_t)) then
            call write_values()
            exit steps
          end if
          call h5aclose_f(attribute, ignored)
          stat = int(c_delete_attribute(int(object, c_int64_t), name//c_null_char))
          if (stat /= 0) exit steps
        end if
      end if
      if (scalar) then
        call h5screate_f(H5S_SCALAR_F, space, stat)
      else
        call h5screate_simple_f(size(dims), dims, space, stat)
      end if
      if (stat /= 0) exit steps
      if (as_integer) then
        call h5acreate_f(object, name, H5T_NATIVE_INTEGER, space, attribute, stat)
      else
        call h5acreate_f(object, name, H5T_NATIVE_DOUBLE, space, attribute, stat)
      end if
      if (stat == 0) call write_values()    ! created: write, then close whatever the write did
      call h5sclose_f(space, ignored)
    end block steps
    call hdf5_failure(failure, stat, name)

  contains

    ! Writes the values into the open attribute and closes it; stat keeps the first failure.
    subroutine write_values()
      if (as_integer) then
        call h5awrite_f(attribute, H5T_NATIVE_INTEGER, nint(values), dims, stat)
      else
        call h5awrite_f(attribute, H5T_NATIVE_DOUBLE, values, dims, stat)
      end if
      call h5aclose_f(attribute, close_stat)
      if (stat == 0) stat = close_stat
    end subroutine write_values
  end procedure write_numeric_attribute

  ! The bytes of `values`, as a text to compare.
  pure function bytes_of(values) result(bytes)
    real(real64), intent(in) :: values(:)
    character(len=8*size(values)) :: bytes

    bytes = transfer(values, bytes)
  end function bytes_of

  ! The texts, each trimmed and ended by a newline.
  pure function joined_lines(texts) result(joined)
    character(len=*), intent(in) :: texts(:)
    character(len=:), allocatable :: joined
    integer :: i

    joined = ''
    do i = 1, size(texts)
      joined = joined//trim(texts(i))//new_line('a')
    end do
  end function joined_lines

end submodule hdf5_file_attributes
