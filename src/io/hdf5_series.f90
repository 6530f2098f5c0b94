!> HDF5 output made of extendible datasets that grow by one row at a time.
!> A `series_table` groups datasets that gain a row together (one per time point, or one per
!> step); rows are buffered and written a chunk at a time, after which the file is flushed, so
!> memory stays bounded and a killed run leaves a readable file with every flushed row.
!> Datasets are (rows) or (rows, width) as h5py shows them. Text attributes are UTF-8
!> variable-length strings (h5py reads them as str), written by src/io/hdf5_text.c.
module hdf5_series
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_int64_t, c_null_char
  use hdf5, only: hid_t, hsize_t, h5open_f, h5eset_auto_f, h5fcreate_f, h5fopen_f, h5fclose_f, &
                  h5fflush_f, H5F_ACC_TRUNC_F, H5F_ACC_RDWR_F, H5F_ACC_RDONLY_F, H5F_SCOPE_GLOBAL_F, &
                  h5screate_simple_f, h5screate_f, &
                  h5sclose_f, H5S_SCALAR_F, H5S_UNLIMITED_F, H5S_SELECT_SET_F, h5sselect_hyperslab_f, &
                  h5pcreate_f, h5pclose_f, h5pset_chunk_f, H5P_DATASET_CREATE_F, h5dcreate_f, h5dclose_f, &
                  h5dwrite_f, h5dset_extent_f, h5dget_space_f, H5T_NATIVE_DOUBLE, H5T_NATIVE_INTEGER, &
                  h5acreate_f, h5aclose_f, h5awrite_f, h5aexists_f, h5adelete_f
  implicit none (type, external)
  private
  public :: hdf5_file, series_table

  !> One dataset fed from columns offset+1 .. offset+width of its table's rows.
  type :: series
    character(len=:), allocatable :: name
    integer :: width = 1
    logical :: vector = .false.          !! (rows, width) if true, (rows) if false
    logical :: integer_valued = .false.
    integer :: offset = 0
    integer(hid_t) :: dataset = -1
  end type series

  !> Datasets that gain a row together, with the row buffer.
  type :: series_table
    type(series), allocatable :: items(:)
    integer :: row_width = 0
    integer :: chunk_rows = 256
    real(real64), allocatable :: buffer(:, :)
    integer :: buffered = 0
    integer(hsize_t) :: written = 0
  contains
    procedure :: define
    procedure :: append
    procedure :: flush => flush_table
    procedure :: close => close_table
  end type series_table

  !> An open output file.
  type :: hdf5_file
    integer(hid_t) :: id = -1
  contains
    procedure :: create
    procedure :: open_existing
    procedure :: close => close_file
    procedure :: flush => flush_file
    procedure :: set_text
    procedure :: set_real
    procedure :: set_reals
    procedure :: set_integer
  end type hdf5_file

  ! h5open_f rebuilds HDF5's table of Fortran types on every call (~1.5 ms): call it once.
  logical, save :: library_open = .false.

  interface
    function c_write_text_attribute(object, name, value) result(status) &
        bind(c, name='eme_h5_write_text_attribute')
      import :: c_char, c_int, c_int64_t
      integer(c_int64_t), value :: object   ! hid_t is int64_t in HDF5 1.10
      character(kind=c_char), intent(in) :: name(*), value(*)
      integer(c_int) :: status
    end function c_write_text_attribute
  end interface

contains

  !> Creates (truncates) the file at `path`. HDF5's own error printing is switched off:
  !> failures come back as stat /= 0 with a message.
  subroutine create(self, path, stat, message)
    class(hdf5_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message

    message = ''
    call open_library(stat)
    if (stat == 0) call h5fcreate_f(path, H5F_ACC_TRUNC_F, self%id, stat)
    if (stat /= 0) message = 'cannot create HDF5 file '''//trim(path)//''''
  end subroutine create

  !> Opens an existing file, read-only or for writing.
  subroutine open_existing(self, path, writable, stat)
    class(hdf5_file), intent(inout) :: self
    character(len=*), intent(in) :: path
    logical, intent(in) :: writable
    integer, intent(out) :: stat

    call open_library(stat)
    if (stat /= 0) return
    if (writable) then
      call h5fopen_f(path, H5F_ACC_RDWR_F, self%id, stat)
    else
      call h5fopen_f(path, H5F_ACC_RDONLY_F, self%id, stat)
    end if
  end subroutine open_existing

  !> Closes the file. (The HDF5 library stays open: other files may be in use.)
  subroutine close_file(self, stat)
    class(hdf5_file), intent(inout) :: self
    integer, intent(out) :: stat

    call h5fclose_f(self%id, stat)
    self%id = -1
  end subroutine close_file

  !> Pushes everything written so far to disk.
  subroutine flush_file(self, stat)
    class(hdf5_file), intent(in) :: self
    integer, intent(out) :: stat

    call h5fflush_f(self%id, H5F_SCOPE_GLOBAL_F, stat)
  end subroutine flush_file

  !> Text attribute on the file root, or on object `object` if given (replaces an old value).
  subroutine set_text(self, name, value, stat, object)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name, value
    integer, intent(out) :: stat
    integer(hid_t), intent(in), optional :: object
    integer(hid_t) :: target_id

    target_id = self%id
    if (present(object)) target_id = object
    stat = int(c_write_text_attribute(int(target_id, c_int64_t), name//c_null_char, value//c_null_char))
  end subroutine set_text

  !> Scalar real attribute on the file root.
  subroutine set_real(self, name, value, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: value
    integer, intent(out) :: stat

    call write_numeric_attribute(self%id, name, [value], .true., stat)
  end subroutine set_real

  !> Real-array attribute on the file root.
  subroutine set_reals(self, name, values, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: values(:)
    integer, intent(out) :: stat

    call write_numeric_attribute(self%id, name, values, .false., stat)
  end subroutine set_reals

  !> Scalar integer attribute on the file root.
  subroutine set_integer(self, name, value, stat)
    class(hdf5_file), intent(in) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: value
    integer, intent(out) :: stat

    call write_numeric_attribute(self%id, name, [real(value, real64)], .true., stat, integer_valued=.true.)
  end subroutine set_integer

  !> Adds a dataset of `width` values per row (a (rows, width) dataset if vector, else (rows))
  !> with `units` and `description` attributes, `columns` (names separated by blanks) for a
  !> vector, `rows` (what a row is) and `source` (who defines it); it is created empty in `file` at once.
  subroutine define(self, file, name, width, vector, units, description, stat, integer_valued, columns, rows, source)
    class(series_table), intent(inout) :: self
    type(hdf5_file), intent(in) :: file
    character(len=*), intent(in) :: name, units, description
    integer, intent(in) :: width
    logical, intent(in) :: vector
    integer, intent(out) :: stat
    logical, intent(in), optional :: integer_valued
    character(len=*), intent(in), optional :: columns, rows, source
    type(series) :: item
    integer(hid_t) :: space, properties, kind
    integer(hsize_t) :: dims(2), max_dims(2), chunk(2)
    integer :: rank, ignored

    item%name = name
    item%width = width
    item%vector = vector
    if (present(integer_valued)) item%integer_valued = integer_valued
    item%offset = self%row_width
    if (vector) then
      rank = 2
      dims = [int(width, hsize_t), 0_hsize_t]
      max_dims = [int(width, hsize_t), H5S_UNLIMITED_F]
      chunk = [int(width, hsize_t), int(self%chunk_rows, hsize_t)]
    else
      rank = 1
      dims = [0_hsize_t, 0_hsize_t]
      max_dims = [H5S_UNLIMITED_F, 0_hsize_t]
      chunk = [int(self%chunk_rows, hsize_t), 0_hsize_t]
    end if
    kind = H5T_NATIVE_DOUBLE
    if (item%integer_valued) kind = H5T_NATIVE_INTEGER
    call h5screate_simple_f(rank, dims(1:rank), space, stat, max_dims(1:rank))
    if (stat /= 0) return
    call h5pcreate_f(H5P_DATASET_CREATE_F, properties, stat)
    if (stat == 0) call h5pset_chunk_f(properties, rank, chunk(1:rank), stat)
    if (stat == 0) call h5dcreate_f(file%id, name, kind, space, item%dataset, stat, properties)
    call h5pclose_f(properties, ignored)
    call h5sclose_f(space, ignored)
    if (stat /= 0) return
    call file%set_text('units', units, stat, item%dataset)
    if (stat == 0) call file%set_text('description', description, stat, item%dataset)
    if (stat == 0 .and. present(columns)) call file%set_text('columns', columns, stat, item%dataset)
    if (stat == 0 .and. present(rows)) call file%set_text('rows', rows, stat, item%dataset)
    if (stat == 0 .and. present(source)) call file%set_text('source', source, stat, item%dataset)
    if (stat /= 0) return

    self%row_width = self%row_width + width
    call append_series(self%items, item)
    if (allocated(self%buffer)) deallocate (self%buffer)
    allocate (self%buffer(self%row_width, self%chunk_rows))
  end subroutine define

  !> Appends one row (all datasets of the table at once); writes a chunk when the buffer fills.
  subroutine append(self, file, row, stat)
    class(series_table), intent(inout) :: self
    type(hdf5_file), intent(in) :: file
    real(real64), intent(in) :: row(:)
    integer, intent(out) :: stat

    stat = 0
    self%buffered = self%buffered + 1
    self%buffer(:, self%buffered) = row
    if (self%buffered == self%chunk_rows) call self%flush(file, stat)
  end subroutine append

  !> Writes the buffered rows to every dataset of the table and flushes the file.
  subroutine flush_table(self, file, stat)
    class(series_table), intent(inout) :: self
    type(hdf5_file), intent(in) :: file
    integer, intent(out) :: stat
    integer(hid_t) :: file_space, memory_space
    integer(hsize_t) :: extent(2), offset(2), count(2)
    integer :: i, rank, ignored

    stat = 0
    if (self%buffered == 0) return
    do i = 1, size(self%items)
      associate (item => self%items(i), first => self%items(i)%offset + 1, last => self%items(i)%offset + self%items(i)%width)
        if (item%vector) then
          rank = 2
          extent = [int(item%width, hsize_t), self%written + self%buffered]
          offset = [0_hsize_t, self%written]
          count = [int(item%width, hsize_t), int(self%buffered, hsize_t)]
        else
          rank = 1
          extent = [self%written + self%buffered, 0_hsize_t]
          offset = [self%written, 0_hsize_t]
          count = [int(self%buffered, hsize_t), 0_hsize_t]
        end if
        call h5dset_extent_f(item%dataset, extent(1:rank), stat)
        if (stat /= 0) return
        call h5dget_space_f(item%dataset, file_space, stat)
        if (stat /= 0) return
        call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, offset(1:rank), count(1:rank), stat)
        if (stat == 0) call h5screate_simple_f(rank, count(1:rank), memory_space, stat)
        if (stat == 0) then
          if (item%integer_valued) then
            call h5dwrite_f(item%dataset, H5T_NATIVE_INTEGER, nint(self%buffer(first:last, 1:self%buffered)), &
                            count(1:rank), stat, memory_space, file_space)
          else
            call h5dwrite_f(item%dataset, H5T_NATIVE_DOUBLE, self%buffer(first:last, 1:self%buffered), &
                            count(1:rank), stat, memory_space, file_space)
          end if
          call h5sclose_f(memory_space, ignored)
        end if
        call h5sclose_f(file_space, ignored)
        if (stat /= 0) return
      end associate
    end do
    self%written = self%written + self%buffered
    self%buffered = 0
    call file%flush(stat)
  end subroutine flush_table

  !> Writes what is buffered and closes the table's datasets.
  subroutine close_table(self, file, stat)
    class(series_table), intent(inout) :: self
    type(hdf5_file), intent(in) :: file
    integer, intent(out) :: stat
    integer :: i, ignored

    call self%flush(file, stat)
    if (.not. allocated(self%items)) return
    do i = 1, size(self%items)
      call h5dclose_f(self%items(i)%dataset, ignored)
    end do
  end subroutine close_table

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
      longer(i)%width = items(i)%width
      longer(i)%vector = items(i)%vector
      longer(i)%integer_valued = items(i)%integer_valued
      longer(i)%offset = items(i)%offset
      longer(i)%dataset = items(i)%dataset
    end do
    longer(size(longer)) = item
    call move_alloc(longer, items)
  end subroutine append_series

  subroutine write_numeric_attribute(object, name, values, scalar, stat, integer_valued)
    integer(hid_t), intent(in) :: object
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: values(:)
    logical, intent(in) :: scalar
    integer, intent(out) :: stat
    logical, intent(in), optional :: integer_valued
    integer(hid_t) :: space, attribute
    integer(hsize_t) :: dims(1)
    logical :: exists, as_integer
    integer :: ignored

    as_integer = .false.
    if (present(integer_valued)) as_integer = integer_valued
    dims = [int(size(values), hsize_t)]
    call h5aexists_f(object, name, exists, stat)
    if (stat == 0 .and. exists) call h5adelete_f(object, name, stat)
    if (stat /= 0) return
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
    if (stat == 0) then    ! created: write, then close whatever the write did
      if (as_integer) then
        call h5awrite_f(attribute, H5T_NATIVE_INTEGER, nint(values), dims, stat)
      else
        call h5awrite_f(attribute, H5T_NATIVE_DOUBLE, values, dims, stat)
      end if
      call h5aclose_f(attribute, ignored)
    end if
    call h5sclose_f(space, ignored)
  end subroutine write_numeric_attribute

end module hdf5_series
