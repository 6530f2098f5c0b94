!> HDF5 datasets that grow by rows, in a file of src/io/hdf5_files (built in memory and written in
!> one checked write; later rows are appended in short windows after their disk space is
!> reserved, to a copy that then takes the file's name: src/run/run_output.f90).
!> A `series_table` groups datasets that gain a row together (one per time point, or one per
!> step). Rows are buffered in memory (bounded: `capacity_rows`) and written a window at a time.
!> Datasets whose final length is known when they are first written are contiguous; the others
!> are chunked and extendible, and deflated (with the shuffle filter) when a compression level is
!> set. Datasets are (rows) or (rows, width) as h5py shows them. A table's first dataset can be
!> the HDF5 dimension scale of the others' rows (src/io/hdf5_scales.c). A row of the file can
!> stand for several rows given to the table (`accumulate`, then `commit`): each dataset keeps
!> the last, the sum, the minimum, the maximum or the mean of them.
module hdf5_series
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_int64_t, c_null_char
  use hdf5, only: hid_t, hsize_t, h5screate_simple_f, h5sclose_f, H5S_UNLIMITED_F, H5S_SELECT_SET_F, &
                  h5sselect_hyperslab_f, h5pcreate_f, h5pclose_f, h5pset_chunk_f, h5pset_layout_f, H5D_CONTIGUOUS_F, &
                  H5P_DATASET_CREATE_F, h5dcreate_f, h5dopen_f, h5dclose_f, h5dwrite_f, h5dset_extent_f, h5dget_space_f, &
                  h5pset_deflate_f, h5pset_shuffle_f, H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER
  use hdf5_files, only: hdf5_file
  implicit none (type, external)
  private
  public :: series_table

  !> One dataset fed from columns offset+1 .. offset+width of its table's rows.
  type :: series
    character(len=:), allocatable :: name, units, description, columns, rows, source
    character(len=:), allocatable :: coordinates         !! CF auxiliary coordinates, '' for none
    integer :: width = 1
    logical :: vector = .false.          !! (rows, width) if true, (rows) if false
    logical :: integer_valued = .false.
    integer :: offset = 0
    character(len=4) :: combine = 'last' !! a file row for several given rows: last, sum, min, max or mean
    character(len=16), allocatable :: column_units(:)   !! of a vector's columns (attribute column_units)
    integer, allocatable :: flag_values(:)              !! CF flag_values and flag_meanings, if allocated
    character(len=:), allocatable :: flag_meanings
  end type series

  !> Datasets that gain a row together, with the row buffer. A writer that keeps two copies of a
  !> file (src/run/run_output) writes each row twice: `write` can keep the rows it wrote, and
  !> `forget` drops them once every copy holds them.
  type :: series_table
    type(series), allocatable :: items(:)
    integer :: row_width = 0
    !> Rows per chunk of a long run's datasets: 64 kB chunks of a scalar dataset, so that a window
    !> (at most 2 capacity_rows rows) adds a few chunks a dataset; the widest (15-column) chunk,
    !> 983 kB, still fits HDF5's 1 MiB chunk cache.
    integer :: chunk_rows = 8192
    integer :: capacity_rows = 16384     !! rows buffered at most before they must be written
    real(real64), allocatable :: buffer(:, :)
    integer :: buffered = 0
    integer(int64) :: first_row = 0      !! the row (from 0) of the datasets that buffer column 1 holds
    integer(int64) :: written = 0        !! rows in the file written last
    logical :: created = .false.         !! the datasets exist in the file
    logical :: scale = .false.           !! the first dataset is the dimension scale of the others' rows
    integer :: compression = 0           !! deflate level 0 (none) to 9 of chunked datasets
    real(real64), allocatable :: pending(:)   !! the combined row being accumulated
    integer :: pending_count = 0         !! rows accumulated into it
  contains
    procedure :: define
    procedure :: set_flags
    procedure :: append
    procedure :: accumulate
    procedure :: commit
    procedure :: full
    procedure :: window_bytes
    procedure :: layout
    procedure :: write => write_table
    procedure :: forget
  end type series_table

  interface
    function c_column_scale(file, name, joined, scale) result(status) bind(c, name='eme_h5_column_scale')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: name(*), joined(*)
      integer(c_int64_t), intent(out) :: scale
      integer(c_int) :: status
    end function c_column_scale
    function c_attach_scales(scale, name, count, datasets, columns) result(status) bind(c, name='eme_h5_attach_scales')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: scale
      character(kind=c_char), intent(in) :: name(*)
      integer(c_int), value :: count
      integer(c_int64_t), intent(in) :: datasets(*), columns(*)
      integer(c_int) :: status
    end function c_attach_scales
  end interface

contains

  !> Adds a dataset of `width` values per row (a (rows, width) dataset if vector, else (rows))
  !> with `units` and `description` attributes, `columns` (names separated by blanks) and
  !> `column_units` for a vector, `rows` (what a row is), `source` (who defines it) and CF
  !> `coordinates` (auxiliary coordinate datasets); no `units` where they are ''. `combine` says
  !> what a file row that stands for several given rows holds ('last' by default). It is created
  !> in a file by the table's first `write`.
  subroutine define(self, name, width, vector, units, description, integer_valued, columns, rows, source, &
                    column_units, combine, coordinates)
    class(series_table), intent(inout) :: self
    character(len=*), intent(in) :: name, units, description
    integer, intent(in) :: width
    logical, intent(in) :: vector
    logical, intent(in), optional :: integer_valued
    character(len=*), intent(in), optional :: columns, rows, source, combine, coordinates
    character(len=*), intent(in), optional :: column_units(:)
    type(series) :: item

    item%name = name
    item%units = units
    item%description = description
    item%columns = ''
    item%rows = ''
    item%source = ''
    item%coordinates = ''
    if (present(coordinates)) item%coordinates = coordinates
    if (present(columns)) item%columns = columns
    if (present(rows)) item%rows = rows
    if (present(source)) item%source = source
    if (present(column_units)) item%column_units = column_units
    if (present(combine)) item%combine = combine
    item%width = width
    item%vector = vector
    if (present(integer_valued)) item%integer_valued = integer_valued
    item%offset = self%row_width
    self%row_width = self%row_width + width
    call append_series(self%items, item)
    if (allocated(self%buffer)) deallocate (self%buffer)
    allocate (self%buffer(self%row_width, 64))
  end subroutine define

  !> Gives dataset `name` the CF attributes flag_values and flag_meanings (a legend of codes).
  subroutine set_flags(self, name, values, meanings)
    class(series_table), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: values(:)
    character(len=*), intent(in) :: meanings(:)
    integer :: i, k

    do i = 1, size(self%items)
      if (self%items(i)%name /= name) cycle
      self%items(i)%flag_values = values
      self%items(i)%flag_meanings = ''
      do k = 1, size(meanings)
        if (k > 1) self%items(i)%flag_meanings = self%items(i)%flag_meanings//' '
        self%items(i)%flag_meanings = self%items(i)%flag_meanings//trim(meanings(k))
      end do
    end do
  end subroutine set_flags

  !> Combines `row` into the pending file row, each dataset by its `combine` rule.
  subroutine accumulate(self, row)
    class(series_table), intent(inout) :: self
    real(real64), intent(in) :: row(:)
    integer :: i

    if (.not. allocated(self%pending)) allocate (self%pending(self%row_width))
    if (self%pending_count == 0) then
      self%pending = row
    else
      do i = 1, size(self%items)
        associate (p => self%pending(self%items(i)%offset + 1:self%items(i)%offset + self%items(i)%width), &
                   r => row(self%items(i)%offset + 1:self%items(i)%offset + self%items(i)%width))
          select case (self%items(i)%combine)
          case ('sum', 'mean')
            p = p + r
          case ('min')
            p = min(p, r)
          case ('max')
            p = max(p, r)
          case default
            p = r
          end select
        end associate
      end do
    end if
    self%pending_count = self%pending_count + 1
  end subroutine accumulate

  !> Buffers the pending file row (if any rows were accumulated) and starts a new one.
  subroutine commit(self)
    class(series_table), intent(inout) :: self
    integer :: i

    if (self%pending_count == 0) return
    do i = 1, size(self%items)
      if (self%items(i)%combine /= 'mean') cycle
      associate (p => self%pending(self%items(i)%offset + 1:self%items(i)%offset + self%items(i)%width))
        p = p/self%pending_count
      end associate
    end do
    call self%append(self%pending)
    self%pending_count = 0
  end subroutine commit

  !> Buffers one row (all datasets of the table at once). The buffer grows to capacity_rows rows
  !> not yet written, plus the rows a second copy of the file still needs.
  subroutine append(self, row)
    class(series_table), intent(inout) :: self
    real(real64), intent(in) :: row(:)
    real(real64), allocatable :: larger(:, :)

    if (self%buffered == size(self%buffer, 2)) then
      allocate (larger(self%row_width, max(self%buffered + 1, min(2*self%buffered, 2*self%capacity_rows))))
      larger(:, 1:self%buffered) = self%buffer(:, 1:self%buffered)
      call move_alloc(larger, self%buffer)
    end if
    self%buffered = self%buffered + 1
    self%buffer(:, self%buffered) = row
  end subroutine append

  !> Whether capacity_rows rows are buffered that no file holds yet: they must be written.
  logical function full(self)
    class(series_table), intent(in) :: self

    full = self%first_row + self%buffered - self%written >= self%capacity_rows
  end function full

  !> Disk space the table's buffered rows take when appended to its chunked datasets (whole new
  !> chunks) in a file that holds first_row rows, plus room for the chunk index.
  integer(int64) function window_bytes(self)
    class(series_table), intent(in) :: self
    integer(int64) :: chunks, chunk
    integer :: i

    chunk = self%chunk_rows
    chunks = (self%first_row + self%buffered + chunk - 1)/chunk - (self%first_row + chunk - 1)/chunk
    ! A compressed chunk that grows is written anew elsewhere in the file.
    if (self%compression > 0) chunks = chunks + 1
    window_bytes = 0
    do i = 1, size(self%items)
      window_bytes = window_bytes + chunks*chunk*self%items(i)%width*merge(4, 8, self%items(i)%integer_valued) + 4096
    end do
  end function window_bytes

  !> What the table's first write (`final` or not) would create in a file, as a text: every
  !> dataset's name, shape, layout and attributes (the values aside). Two tables of the same
  !> layout create the same datasets; '' if the datasets exist already or the write would not
  !> fill them whole.
  function layout(self, final) result(text)
    class(series_table), intent(in) :: self
    logical, intent(in) :: final
    character(len=:), allocatable :: text
    character(len=:), allocatable :: buffer
    character(len=64) :: numbers
    integer :: i, k, used

    text = ''
    if (self%created .or. self%first_row /= 0) return
    allocate (character(len=4096) :: buffer)
    used = 0
    write (numbers, '(l1, 1x, l1, 3(1x, i0))') final, self%scale, self%compression, self%chunk_rows, self%buffered
    call add(trim(numbers))
    do i = 1, size(self%items)
      associate (item => self%items(i))
        write (numbers, '(i0, 1x, l1, 1x, l1)') item%width, item%vector, item%integer_valued
        call add(item%name)
        call add(trim(numbers))
        call add(item%units)
        call add(item%description)
        call add(item%columns)
        call add(item%rows)
        call add(item%source)
        call add(item%coordinates)
        if (allocated(item%column_units)) then
          do k = 1, size(item%column_units)
            call add(trim(item%column_units(k)))
          end do
        end if
        if (allocated(item%flag_values)) then
          do k = 1, size(item%flag_values)
            write (numbers, '(i0)') item%flag_values(k)
            call add(trim(numbers))
          end do
          call add(item%flag_meanings)
        end if
      end associate
    end do
    text = buffer(1:used)

  contains

    ! Appends `piece` and a separator (NUL) to buffer(1:used), growing it as needed.
    subroutine add(piece)
      character(len=*), intent(in) :: piece
      character(len=:), allocatable :: larger

      if (used + len(piece) + 1 > len(buffer)) then
        allocate (character(len=2*(used + len(piece) + 1)) :: larger)
        larger(1:used) = buffer(1:used)
        call move_alloc(larger, buffer)
      end if
      buffer(used + 1:used + len(piece)) = piece
      buffer(used + len(piece) + 1:used + len(piece) + 1) = achar(0)
      used = used + len(piece) + 1
    end subroutine add
  end function layout

  !> Writes the buffered rows to every dataset of the table in `file`, which holds first_row rows,
  !> and empties the buffer, unless `keep` (then `forget` drops the rows once no file needs them).
  !> The first write creates the datasets: contiguous of exactly the buffered rows if `final` (no
  !> row will follow), chunked and extendible otherwise; with `held`, the file holds them already,
  !> as that write would create them (the table's `layout`), and only their values are given to
  !> it (hdf5_file's put_values, before the file is open).
  subroutine write_table(self, file, final, stat, keep, held)
    class(series_table), intent(inout) :: self
    type(hdf5_file), intent(in) :: file
    logical, intent(in) :: final
    integer, intent(out) :: stat
    logical, intent(in), optional :: keep, held
    integer(hid_t) :: dataset, file_space, memory_space
    integer(hsize_t) :: extent(2), offset(2), count(2)
    integer(hid_t) :: opened(size(self%items))   !! the new datasets, while their scales are attached
    integer :: i, rank, ignored, close_stat
    logical :: attaching, filling

    stat = 0
    filling = .false.
    if (present(held)) filling = held .and. .not. self%created
    attaching = .not. (self%created .or. filling) .and. self%scale
    opened = -1
    do i = 1, size(self%items)
      associate (item => self%items(i), first => self%items(i)%offset + 1, last => self%items(i)%offset + self%items(i)%width)
        if (filling) then
          if (self%buffered > 0) call fill(item, self%buffer(first:last, 1:self%buffered))
          if (stat /= 0) exit
          cycle
        end if
        rank = merge(2, 1, item%vector)
        if (item%vector) then
          extent = [int(item%width, hsize_t), self%first_row + self%buffered]
          offset = [0_hsize_t, self%first_row]
          count = [int(item%width, hsize_t), int(self%buffered, hsize_t)]
        else
          extent = [self%first_row + self%buffered, 0_hsize_t]
          offset = [self%first_row, 0_hsize_t]
          count = [int(self%buffered, hsize_t), 0_hsize_t]
        end if
        if (self%created) then
          call h5dopen_f(file%id, item%name, dataset, stat)
          if (stat /= 0) return
          call h5dset_extent_f(dataset, extent(1:rank), stat)
        else
          call create_dataset(file, item, rank, extent, final, self%chunk_rows, self%compression, dataset, stat)
          if (stat /= 0) then
            if (dataset >= 0) call h5dclose_f(dataset, ignored)
            exit
          end if
        end if
        if (stat == 0 .and. self%buffered > 0) then
          call h5dget_space_f(dataset, file_space, stat)
          if (stat == 0) then
            call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, offset(1:rank), count(1:rank), stat)
            if (stat == 0) call h5screate_simple_f(rank, count(1:rank), memory_space, stat)
            if (stat == 0) then
              if (item%integer_valued) then
                call h5dwrite_f(dataset, H5T_NATIVE_INTEGER, nint(self%buffer(first:last, 1:self%buffered)), &
                                count(1:rank), stat, memory_space, file_space)
              else
                call h5dwrite_f(dataset, H5T_NATIVE_DOUBLE, self%buffer(first:last, 1:self%buffered), &
                                count(1:rank), stat, memory_space, file_space)
              end if
              call h5sclose_f(memory_space, ignored)
            end if
            call h5sclose_f(file_space, ignored)
          end if
        end if
        if (attaching .and. stat == 0) then
          opened(i) = dataset               ! kept open for attach_scale
        else
          call h5dclose_f(dataset, close_stat)
          if (stat == 0) stat = close_stat
        end if
        if (stat /= 0) exit
      end associate
    end do
    if (attaching .and. stat == 0) call attach_scale(file, self%items, opened, stat)
    if (attaching) then
      do i = 1, size(opened)
        if (opened(i) >= 0) call h5dclose_f(opened(i), ignored)
      end do
    end if
    if (stat /= 0) return
    self%created = .true.
    self%written = self%first_row + self%buffered
    if (present(keep)) then
      if (keep) return
    end if
    call self%forget(self%written)

  contains

    ! The values of `item` (its columns of the buffered rows) as the bytes of its stored type:
    ! rows after rows, as HDF5 lays out a (rows, width) dataset.
    subroutine fill(item, values)
      type(series), intent(in) :: item
      real(real64), intent(in) :: values(:, :)
      character(len=merge(4, 8, item%integer_valued)*size(values)) :: bytes

      if (item%integer_valued) then
        bytes = transfer(nint(values), bytes)
      else
        bytes = transfer(values, bytes)
      end if
      call file%put_values(item%name, bytes, stat)
    end subroutine fill
  end subroutine write_table

  !> Drops the buffered rows before row `rows` (from 0): every file holds them.
  subroutine forget(self, rows)
    class(series_table), intent(inout) :: self
    integer(int64), intent(in) :: rows
    integer :: dropped

    dropped = int(min(max(rows - self%first_row, 0_int64), int(self%buffered, int64)))
    if (dropped == 0) return
    self%buffer(:, 1:self%buffered - dropped) = self%buffer(:, dropped + 1:self%buffered)
    self%buffered = self%buffered - dropped
    self%first_row = self%first_row + dropped
  end subroutine forget

  ! Makes the first dataset the dimension scale (named after it) of the other datasets' rows,
  ! and gives each vector dataset X the scale X_column of its columns' names
  ! (src/io/hdf5_scales.c: every scale attribute written once).
  subroutine attach_scale(file, items, opened, stat)
    type(hdf5_file), intent(in) :: file
    type(series), intent(in) :: items(:)
    integer(hid_t), intent(in) :: opened(:)    !! the datasets of `items`, open
    integer, intent(out) :: stat
    integer(c_int64_t) :: datasets(size(items) - 1), columns(size(items) - 1)
    integer :: i, ignored

    datasets = int(opened(2:), c_int64_t)
    columns = -1
    stat = 0
    do i = 2, size(items)
      if (stat /= 0) exit
      if (items(i)%vector) stat = int(c_column_scale(int(file%id, c_int64_t), items(i)%name//'_column'//c_null_char, &
                                                     words_as_lines(items(i)%columns)//c_null_char, columns(i - 1)))
    end do
    if (stat == 0) stat = int(c_attach_scales(int(opened(1), c_int64_t), items(1)%name//c_null_char, &
                                              int(size(items) - 1, c_int), datasets, columns))
    do i = 1, size(columns)
      if (columns(i) >= 0) call h5dclose_f(int(columns(i), hid_t), ignored)
    end do
  end subroutine attach_scale

  ! Creates one dataset of the table with its attributes: contiguous of `extent` if `final`,
  ! chunked with an unlimited row count otherwise; chunked and deflated at level `compression`
  ! (after the shuffle filter) if that is > 0 and there are rows.
  subroutine create_dataset(file, item, rank, extent, final, chunk_rows, compression, dataset, stat)
    type(hdf5_file), intent(in) :: file
    type(series), intent(in) :: item
    integer, intent(in) :: rank, chunk_rows, compression
    integer(hsize_t), intent(in) :: extent(2)
    logical, intent(in) :: final
    integer(hid_t), intent(out) :: dataset
    integer, intent(out) :: stat
    type(hdf5_file) :: fresh_object
    integer(hid_t) :: space, properties, kind
    integer(hsize_t) :: max_dims(2), chunk(2)
    integer :: ignored
    logical :: compressed

    dataset = -1
    kind = H5T_NATIVE_DOUBLE
    if (item%integer_valued) kind = H5T_NATIVE_INTEGER
    max_dims = extent
    max_dims(rank) = H5S_UNLIMITED_F
    chunk = extent
    chunk(rank) = int(chunk_rows, hsize_t)
    if (final) then
      max_dims = extent
      chunk(rank) = min(chunk(rank), extent(rank))
    end if
    compressed = compression > 0 .and. chunk(rank) > 0
    call h5screate_simple_f(rank, extent(1:rank), space, stat, max_dims(1:rank))
    if (stat /= 0) return
    call h5pcreate_f(H5P_DATASET_CREATE_F, properties, stat)
    if (stat == 0) then
      if (final .and. .not. compressed) then
        call h5pset_layout_f(properties, H5D_CONTIGUOUS_F, stat)
      else
        call h5pset_chunk_f(properties, rank, chunk(1:rank), stat)
      end if
    end if
    if (stat == 0 .and. compressed) call h5pset_shuffle_f(properties, stat)
    if (stat == 0 .and. compressed) call h5pset_deflate_f(properties, compression, stat)
    if (stat == 0) call h5dcreate_f(file%id, item%name, kind, space, dataset, stat, properties)
    call h5pclose_f(properties, ignored)
    call h5sclose_f(space, ignored)
    if (stat /= 0) return
    ! A new dataset has no attributes: no existence queries.
    fresh_object%id = file%id
    fresh_object%fresh = .true.
    stat = 0
    if (len(item%units) > 0) call fresh_object%set_text('units', item%units, stat, dataset)
    if (stat == 0) call fresh_object%set_text('description', item%description, stat, dataset)
    if (stat == 0 .and. len(item%coordinates) > 0) call fresh_object%set_text('coordinates', item%coordinates, stat, &
                                                                               dataset)
    if (stat == 0 .and. len(item%columns) > 0) call fresh_object%set_text('columns', item%columns, stat, dataset)
    if (stat == 0 .and. len(item%rows) > 0) call fresh_object%set_text('rows', item%rows, stat, dataset)
    if (stat == 0 .and. len(item%source) > 0) call fresh_object%set_text('source', item%source, stat, dataset)
    if (stat == 0 .and. allocated(item%column_units)) call fresh_object%set_texts('column_units', item%column_units, &
                                                                                 stat, dataset)
    if (stat == 0 .and. allocated(item%flag_values)) then
      call fresh_object%set_integers('flag_values', item%flag_values, stat, dataset)
      if (stat == 0) call fresh_object%set_text('flag_meanings', item%flag_meanings, stat, dataset)
    end if
  end subroutine create_dataset

  ! The blank-separated words of `text`, each ended by a newline.
  pure function words_as_lines(text) result(lines)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: lines
    integer :: i

    lines = ''
    do i = 1, len(text)
      if (text(i:i) /= ' ') then
        lines = lines//text(i:i)
      else if (i > 1) then
        if (text(i - 1:i - 1) /= ' ') lines = lines//new_line('a')
      end if
    end do
    if (len(text) > 0) then
      if (text(len(text):len(text)) /= ' ') lines = lines//new_line('a')
    end if
  end function words_as_lines

  ! items := [items, item], explicitly (gfortran 12 mishandles array constructors of types with
  ! allocatable character components).
  subroutine append_series(items, item)
    type(series), allocatable, intent(inout) :: items(:)
    type(series), intent(in) :: item
    type(series), allocatable :: longer(:)
    integer :: i

    if (.not. allocated(items)) allocate (items(0))
    allocate (longer(size(items) + 1))
    do i = 1, size(items)
      call move_alloc(items(i)%name, longer(i)%name)
      call move_alloc(items(i)%units, longer(i)%units)
      call move_alloc(items(i)%coordinates, longer(i)%coordinates)
      call move_alloc(items(i)%description, longer(i)%description)
      call move_alloc(items(i)%columns, longer(i)%columns)
      call move_alloc(items(i)%rows, longer(i)%rows)
      call move_alloc(items(i)%source, longer(i)%source)
      longer(i)%width = items(i)%width
      longer(i)%vector = items(i)%vector
      longer(i)%integer_valued = items(i)%integer_valued
      longer(i)%offset = items(i)%offset
      longer(i)%combine = items(i)%combine
      if (allocated(items(i)%column_units)) call move_alloc(items(i)%column_units, longer(i)%column_units)
      if (allocated(items(i)%flag_values)) call move_alloc(items(i)%flag_values, longer(i)%flag_values)
      if (allocated(items(i)%flag_meanings)) call move_alloc(items(i)%flag_meanings, longer(i)%flag_meanings)
    end do
    longer(size(longer)) = item
    call move_alloc(longer, items)
  end subroutine append_series

end module hdf5_series
