!> HDF5 output made of datasets that grow by rows, written so that a full disk or a kill never
!> leaves a file that lies (src/io/hdf5_storage.c says how: files are built in memory and written
!> in one checked write; later rows are appended in short windows after their disk space is
!> reserved, to a copy that then takes the file's name (src/run/run_output.f90)).
!> A `series_table` groups datasets that gain a row together (one per time point, or one per
!> step). Rows are buffered in memory (bounded: `capacity_rows`) and written a window at a time.
!> Datasets whose final length is known when they are first written are contiguous; the others
!> are chunked and extendible, and deflated (with the shuffle filter) when a compression level is
!> set. Datasets are (rows) or (rows, width) as h5py shows them. A table's first dataset can be
!> the HDF5 dimension scale of the others' rows (src/io/hdf5_scales.c). A row of the file can
!> stand for several rows given to the table (`accumulate`, then `commit`): each dataset keeps
!> the last, the sum, the minimum, the maximum or the mean of them. Text attributes are UTF-8
!> variable-length strings (h5py reads them as str).
module hdf5_series
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_long, c_int64_t, c_null_char
  use hdf5, only: hid_t, hsize_t, h5open_f, h5eset_auto_f, h5fclose_f, h5screate_simple_f, h5screate_f, &
                  h5sclose_f, H5S_SCALAR_F, H5S_UNLIMITED_F, H5S_SELECT_SET_F, h5sselect_hyperslab_f, &
                  h5pcreate_f, h5pclose_f, h5pset_chunk_f, h5pset_layout_f, H5D_CONTIGUOUS_F, H5P_DATASET_CREATE_F, &
                  h5dcreate_f, h5dopen_f, h5dclose_f, h5dwrite_f, h5dset_extent_f, h5dget_space_f, h5pset_deflate_f, &
                  h5pset_shuffle_f, &
                  H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER, h5acreate_f, h5aclose_f, h5awrite_f, h5aexists_f, h5adelete_f, &
                  h5aopen_f, h5aread_f, h5aget_space_f, h5sget_simple_extent_npoints_f
  implicit none (type, external)
  private
  public :: hdf5_file, series_table, check_run_file, file_in_use

  integer, parameter :: file_in_use = -3   !! open_existing: a reader holds the file open

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
    procedure :: write => write_table
    procedure :: forget
  end type series_table

  !> An open HDF5 file (in memory until stored, or on disk).
  type :: hdf5_file
    integer(hid_t) :: id = -1
    logical :: fresh = .false.           !! created by this process: no attribute exists yet
  contains
    procedure :: create_in_memory
    procedure :: store
    procedure :: open_existing
    procedure :: close => close_file
    procedure :: set_text
    procedure :: set_real
    procedure :: set_reals
    procedure :: set_integer
    procedure :: set_texts
    procedure :: set_dataset_texts
    procedure :: get_text
    procedure :: get_reals
  end type hdf5_file

  ! h5open_f rebuilds HDF5's table of Fortran types on every call (~1.5 ms): call it once.
  logical, save :: library_open = .false.
  integer, save :: memory_files = 0

  interface
    function c_write_text_attribute(object, name, value, fresh) result(status) &
        bind(c, name='eme_h5_write_text_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object   ! hid_t is int64_t in HDF5 1.10
      character(kind=c_char), intent(in) :: name(*), value(*)
      integer(c_int), value :: fresh
      integer(c_int) :: status
    end function c_write_text_attribute
    function c_write_text_array_attribute(object, name, joined) result(status) &
        bind(c, name='eme_h5_write_text_array_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object
      character(kind=c_char), intent(in) :: name(*), joined(*)
      integer(c_int) :: status
    end function c_write_text_array_attribute
    function c_make_scale(scale, name) result(status) bind(c, name='eme_h5_make_scale')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: scale
      character(kind=c_char), intent(in) :: name(*)
      integer(c_int) :: status
    end function c_make_scale
    function c_column_scale(file, dataset, name, joined) result(status) bind(c, name='eme_h5_column_scale')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: file, dataset
      character(kind=c_char), intent(in) :: name(*), joined(*)
      integer(c_int) :: status
    end function c_column_scale
    function c_attach_row_scale(dataset, scale) result(status) bind(c, name='eme_h5_attach_row_scale')
      import :: c_int, c_int64_t
      integer(c_int64_t), value :: dataset, scale
      integer(c_int) :: status
    end function c_attach_row_scale
    function c_read_text_attribute(object, name, text, capacity) result(status) &
        bind(c, name='eme_h5_read_text_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object
      character(kind=c_char), intent(in) :: name(*)
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int), value :: capacity
      integer(c_int) :: status
    end function c_read_text_attribute
    function c_create_in_memory(label, file) result(status) bind(c, name='eme_h5_create_in_memory')
      import :: c_char, c_int, c_int64_t
      character(kind=c_char), intent(in) :: label(*)
      integer(c_int64_t), intent(out) :: file
      integer(c_int) :: status
    end function c_create_in_memory
    function c_store_image(file, path, sync) result(status) bind(c, name='eme_h5_store_image')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: file
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: sync
      integer(c_int) :: status
    end function c_store_image
    function c_open_file(path, writable, reserve, wait_ms, file) result(status) bind(c, name='eme_h5_open_file')
      import :: c_char, c_int, c_long, c_int64_t
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: writable, wait_ms
      integer(c_long), value :: reserve
      integer(c_int64_t), intent(out) :: file
      integer(c_int) :: status
    end function c_open_file
    function c_check_run_file(path, status_text, capacity, steps) result(status) bind(c, name='eme_h5_check_run_file')
      import :: c_char, c_int, c_long
      character(kind=c_char), intent(in) :: path(*)
      character(kind=c_char), intent(out) :: status_text(*)
      integer(c_int), value :: capacity
      integer(c_long), intent(out) :: steps
      integer(c_int) :: status
    end function c_check_run_file
  end interface

contains

  !> Creates an empty file in memory; `store` writes it to disk. stat = -1 on an HDF5 failure.
  subroutine create_in_memory(self, stat)
    class(hdf5_file), intent(inout) :: self
    integer, intent(out) :: stat
    character(len=32) :: label
    integer(c_int64_t) :: id

    call open_library(stat)
    if (stat /= 0) return
    memory_files = memory_files + 1
    write (label, '("eme_memory_file_", i0)') memory_files
    stat = int(c_create_in_memory(trim(label)//c_null_char, id))
    self%id = int(id, hid_t)
    self%fresh = .true.
  end subroutine create_in_memory

  !> Writes the in-memory file as the whole of `path` (on disk before return with `sync`); the
  !> file stays open. stat: 0, an OS error number (the partial file is removed), or -1 (HDF5).
  subroutine store(self, path, sync, stat)
    class(hdf5_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    logical, intent(in) :: sync
    integer, intent(out) :: stat

    stat = int(c_store_image(int(self%id, c_int64_t), trim(path)//c_null_char, merge(1_c_int, 0_c_int, sync)))
  end subroutine store

  !> Opens an existing file read-only, or for writing after reserving `reserve` bytes of disk for
  !> what will be added (default 64 KiB). A writer waits for readers that hold the file open:
  !> with `wait_ms` < 0 not at all (stat = file_in_use, write later), else up to wait_ms
  !> milliseconds (default 5000), then it writes without HDF5's lock. stat: 0, an OS error number
  !> from the reservation (the file is untouched), file_in_use, or -1 (HDF5 could not open it).
  subroutine open_existing(self, path, writable, stat, reserve, wait_ms)
    class(hdf5_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    logical, intent(in) :: writable
    integer, intent(out) :: stat
    integer(int64), intent(in), optional :: reserve
    integer, intent(in), optional :: wait_ms
    integer(c_int64_t) :: id
    integer(c_long) :: bytes
    integer(c_int) :: patience

    call open_library(stat)
    if (stat /= 0) return
    bytes = 65536
    if (present(reserve)) bytes = int(reserve, c_long)
    patience = 5000
    if (present(wait_ms)) patience = int(wait_ms, c_int)
    stat = int(c_open_file(trim(path)//c_null_char, merge(1_c_int, 0_c_int, writable), bytes, patience, id))
    self%id = int(id, hid_t)
    self%fresh = .false.
  end subroutine open_existing

  !> Closes the file. (The HDF5 library stays open: other files may be in use.)
  subroutine close_file(self, stat)
    class(hdf5_file), intent(inout) :: self
    integer, intent(out) :: stat

    stat = 0
    if (self%id < 0) return
    call h5fclose_f(self%id, stat)
    self%id = -1
  end subroutine close_file

  !> Text attribute on the file root, or on object `object` if given (replaces an old value).
  subroutine set_text(self, name, value, stat, object)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name, value
    integer, intent(out) :: stat
    integer(hid_t), intent(in), optional :: object
    integer(hid_t) :: target_id

    target_id = self%id
    if (present(object)) target_id = object
    stat = int(c_write_text_attribute(int(target_id, c_int64_t), name//c_null_char, value//c_null_char, &
                                      merge(1_c_int, 0_c_int, self%fresh)))
  end subroutine set_text

  !> Array of texts as one attribute on the file root (h5py: an array of str).
  subroutine set_texts(self, name, values, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name, values(:)
    integer, intent(out) :: stat

    stat = int(c_write_text_array_attribute(int(self%id, c_int64_t), name//c_null_char, joined_lines(values)//c_null_char))
  end subroutine set_texts

  !> Array of texts as one attribute of the dataset `dataset` (h5py: an array of str).
  subroutine set_dataset_texts(self, dataset, name, values, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: dataset, name, values(:)
    integer, intent(out) :: stat
    integer(hid_t) :: dataset_id
    integer :: close_stat

    call h5dopen_f(self%id, dataset, dataset_id, stat)
    if (stat /= 0) return
    stat = int(c_write_text_array_attribute(int(dataset_id, c_int64_t), name//c_null_char, &
                                            joined_lines(values)//c_null_char))
    call h5dclose_f(dataset_id, close_stat)
    if (stat == 0) stat = close_stat
  end subroutine set_dataset_texts

  !> Scalar real attribute on the file root; with `units`, a text attribute <name>_units too.
  subroutine set_real(self, name, value, stat, units)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: value
    integer, intent(out) :: stat
    character(len=*), intent(in), optional :: units

    call write_numeric_attribute(self%id, name, [value], .true., self%fresh, stat)
    if (stat == 0 .and. present(units)) call self%set_text(name//'_units', units, stat)
  end subroutine set_real

  !> Real-array attribute on the file root; with `units`, a text attribute <name>_units too.
  subroutine set_reals(self, name, values, stat, units)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: values(:)
    integer, intent(out) :: stat
    character(len=*), intent(in), optional :: units

    call write_numeric_attribute(self%id, name, values, .false., self%fresh, stat)
    if (stat == 0 .and. present(units)) call self%set_text(name//'_units', units, stat)
  end subroutine set_reals

  !> Scalar integer attribute on the file root; with `units`, a text attribute <name>_units too.
  subroutine set_integer(self, name, value, stat, units)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: value
    integer, intent(out) :: stat
    character(len=*), intent(in), optional :: units

    call write_numeric_attribute(self%id, name, [real(value, real64)], .true., self%fresh, stat, integer_valued=.true.)
    if (stat == 0 .and. present(units)) call self%set_text(name//'_units', units, stat)
  end subroutine set_integer

  !> The text attribute `name` of the file root; stat /= 0 if it is missing.
  subroutine get_text(self, name, value, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: value
    integer, intent(out) :: stat
    character(len=4096) :: buffer

    stat = int(c_read_text_attribute(int(self%id, c_int64_t), name//c_null_char, buffer, int(len(buffer), c_int)))
    value = buffer(1:max(0, index(buffer, c_null_char) - 1))
  end subroutine get_text

  !> The numeric attribute `name` of the file root (a scalar or an array, as reals); stat /= 0 if
  !> it is missing or not numeric.
  subroutine get_reals(self, name, values, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    real(real64), allocatable, intent(out) :: values(:)
    integer, intent(out) :: stat
    integer(hid_t) :: attribute, space
    integer(hsize_t) :: points, dims(1)
    integer :: ignored

    allocate (values(0))
    call h5aopen_f(self%id, name, attribute, stat)
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
  end subroutine get_reals

  !> Reads the run file at `path` back: its status and steps_completed, and whether every
  !> per-point dataset has R + 1 rows and every per-step dataset R, R being the attribute
  !> step_rows (steps_completed in files without it) (src/io/hdf5_storage.c). stat: 0 all holds,
  !> 1 unreadable, 2 no status, 3 lengths disagree.
  subroutine check_run_file(path, status, steps_completed, stat)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: status
    integer, intent(out) :: steps_completed, stat
    character(len=1024) :: buffer
    integer(c_long) :: steps

    call open_library(stat)
    if (stat == 0) stat = int(c_check_run_file(trim(path)//c_null_char, buffer, int(len(buffer), c_int), steps))
    status = buffer(1:max(0, index(buffer, c_null_char) - 1))
    steps_completed = int(steps)
  end subroutine check_run_file

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

  !> Writes the buffered rows to every dataset of the table in `file`, which holds first_row rows,
  !> and empties the buffer, unless `keep` (then `forget` drops the rows once no file needs them).
  !> The first write creates the datasets: contiguous of exactly the buffered rows if `final` (no
  !> row will follow), chunked and extendible otherwise.
  subroutine write_table(self, file, final, stat, keep)
    class(series_table), intent(inout) :: self
    type(hdf5_file), intent(in) :: file
    logical, intent(in) :: final
    integer, intent(out) :: stat
    logical, intent(in), optional :: keep
    integer(hid_t) :: dataset, file_space, memory_space
    integer(hsize_t) :: extent(2), offset(2), count(2)
    integer :: i, rank, ignored, close_stat

    stat = 0
    do i = 1, size(self%items)
      associate (item => self%items(i), first => self%items(i)%offset + 1, last => self%items(i)%offset + self%items(i)%width)
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
            return
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
        call h5dclose_f(dataset, close_stat)
        if (stat == 0) stat = close_stat
        if (stat /= 0) return
      end associate
    end do
    if (.not. self%created .and. self%scale) call attach_scale(file, self%items, stat)
    if (stat /= 0) return
    self%created = .true.
    self%written = self%first_row + self%buffered
    if (present(keep)) then
      if (keep) return
    end if
    call self%forget(self%written)
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
  ! and gives each vector dataset X the scale X_column of its columns' names.
  subroutine attach_scale(file, items, stat)
    type(hdf5_file), intent(in) :: file
    type(series), intent(in) :: items(:)
    integer, intent(out) :: stat
    integer(hid_t) :: scale, dataset
    integer :: i, ignored

    call h5dopen_f(file%id, items(1)%name, scale, stat)
    if (stat /= 0) return
    stat = int(c_make_scale(int(scale, c_int64_t), items(1)%name//c_null_char))
    do i = 2, size(items)
      if (stat /= 0) exit
      call h5dopen_f(file%id, items(i)%name, dataset, stat)
      if (stat /= 0) exit
      stat = int(c_attach_row_scale(int(dataset, c_int64_t), int(scale, c_int64_t)))
      if (stat == 0 .and. items(i)%vector) stat = int(c_column_scale(int(file%id, c_int64_t), int(dataset, c_int64_t), &
                                                      items(i)%name//'_column'//c_null_char, &
                                                      words_as_lines(items(i)%columns)//c_null_char))
      call h5dclose_f(dataset, ignored)
    end do
    call h5dclose_f(scale, ignored)
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
    if (stat == 0 .and. allocated(item%column_units)) stat = int(c_write_text_array_attribute(int(dataset, c_int64_t), &
                                                            'column_units'//c_null_char, &
                                                            joined_lines(item%column_units)//c_null_char))
    if (stat == 0 .and. allocated(item%flag_values)) then
      call write_numeric_attribute(dataset, 'flag_values', real(item%flag_values, real64), .false., .true., stat, &
                                   integer_valued=.true.)
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

  ! Opens the HDF5 library once per process, with its own error printing off.
  subroutine open_library(stat)
    integer, intent(out) :: stat

    stat = 0
    if (library_open) return
    call h5open_f(stat)
    if (stat == 0) call h5eset_auto_f(0, stat)
    library_open = stat == 0
  end subroutine open_library

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

  subroutine write_numeric_attribute(object, name, values, scalar, fresh, stat, integer_valued)
    integer(hid_t), intent(in) :: object
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: values(:)
    logical, intent(in) :: scalar, fresh
    integer, intent(out) :: stat
    logical, intent(in), optional :: integer_valued
    integer(hid_t) :: space, attribute
    integer(hsize_t) :: dims(1), points
    logical :: exists, as_integer
    integer :: ignored, close_stat

    as_integer = .false.
    if (present(integer_valued)) as_integer = integer_valued
    dims = [int(size(values), hsize_t)]
    stat = 0
    if (.not. fresh) then
      call h5aexists_f(object, name, exists, stat)
      if (stat /= 0) return
      if (exists) then
        ! In place if the stored attribute has the same number of values (no change to the object
        ! header's layout); otherwise it is replaced.
        call h5aopen_f(object, name, attribute, stat)
        if (stat /= 0) return
        call h5aget_space_f(attribute, space, stat)
        if (stat == 0) call h5sget_simple_extent_npoints_f(space, points, stat)
        if (stat == 0) call h5sclose_f(space, ignored)
        if (stat == 0 .and. points == size(values, kind=hsize_t)) then
          call write_values()
          return
        end if
        call h5aclose_f(attribute, ignored)
        call h5adelete_f(object, name, stat)
        if (stat /= 0) return
      end if
    end if
    if (scalar) then
      call h5screate_f(H5S_SCALAR_F, space, stat)
    else
      call h5screate_simple_f(1, dims, space, stat)
    end if
    if (stat /= 0) return
    if (as_integer) then
      call h5acreate_f(object, name, H5T_NATIVE_INTEGER, space, attribute, stat)
    else
      call h5acreate_f(object, name, H5T_NATIVE_DOUBLE, space, attribute, stat)
    end if
    if (stat == 0) call write_values()    ! created: write, then close whatever the write did
    call h5sclose_f(space, ignored)

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
  end subroutine write_numeric_attribute

end module hdf5_series
