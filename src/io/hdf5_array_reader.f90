!> The arrays a scene's input names in an HDF5 file (a spring chain's &initial file, with datasets
!> q, p, gamma, theta, or a run file's /snapshots): one numeric dataset read whole as real64, or
!> one row of it along its first axis (a snapshot), in the file's (C, row-major) order, with its
!> shape as h5py gives it. The file is opened read-only through hdf5_files; a
!> relative path is relative to the folder of the namelist that names it (docs/input.md, Paths).
module hdf5_array_reader
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_loc, c_ptr
  use hdf5, only: hid_t, hsize_t, size_t, h5lexists_f, h5dopen_f, h5dclose_f, h5dget_space_f, h5dget_type_f, h5sclose_f, &
                  h5tclose_f, h5tget_class_f, h5sget_simple_extent_ndims_f, h5sget_simple_extent_dims_f, h5dread_f, &
                  H5T_FLOAT_F, H5T_INTEGER_F, H5T_NATIVE_DOUBLE, h5screate_simple_f, h5sselect_hyperslab_f, &
                  H5S_SELECT_SET_F, h5gget_info_f, h5lget_name_by_idx_f, H5_INDEX_NAME_F, H5_ITER_INC_F
  use failures, only: failure_type, fail, failure_io
  use number_text, only: integer_text
  use hdf5_files, only: hdf5_file, hdf5_file_kind, not_hdf5
  use model_scene, only: array_reader
  implicit none
  private
  public :: hdf5_arrays

  !> model_scene's array_reader for HDF5 files.
  type, extends(array_reader) :: hdf5_arrays
    character(len=:), allocatable :: folder   !! of the namelist ('' or ending in '/')
  contains
    procedure :: read_array
    procedure :: member_names
  end type hdf5_arrays

contains

  !> Dataset `name` of the HDF5 file `path` (model_scene's read_array); a failure's message starts
  !> with the path as resolved.
  subroutine read_array(self, path, name, values, shape, found, failure, row)
    class(hdf5_arrays), intent(in) :: self
    character(len=*), intent(in) :: path, name
    real(real64), allocatable, intent(out) :: values(:)
    integer, allocatable, intent(out) :: shape(:)
    logical, intent(out) :: found
    type(failure_type), intent(out) :: failure
    integer, intent(in), optional :: row
    type(hdf5_file) :: file
    type(failure_type) :: closing
    character(len=:), allocatable :: where

    found = .false.
    allocate (values(0), shape(0))
    call open_file(self, path, file, where, failure)
    if (failure%failed()) return
    call read_dataset(file%id, where, name, values, shape, found, failure, row)
    call file%close(closing)
    if (.not. failure%failed() .and. closing%failed()) failure = closing
  end subroutine read_array

  !> The names of the root group's members of the HDF5 file `path` (model_scene's member_names),
  !> in name order; a failure's message starts with the path as resolved.
  subroutine member_names(self, path, names, failure)
    class(hdf5_arrays), intent(in) :: self
    character(len=*), intent(in) :: path
    character(len=256), allocatable, intent(out) :: names(:)
    type(failure_type), intent(out) :: failure
    type(hdf5_file) :: file
    type(failure_type) :: closing
    character(len=:), allocatable :: where
    integer(size_t) :: length
    integer :: stat, storage, count, last_order, k

    allocate (names(0))
    call open_file(self, path, file, where, failure)
    if (failure%failed()) return
    call h5gget_info_f(file%id, storage, count, last_order, stat)
    if (stat == 0) then
      deallocate (names)
      allocate (names(count))
      do k = 1, count
        call h5lget_name_by_idx_f(file%id, '.', H5_INDEX_NAME_F, H5_ITER_INC_F, int(k - 1, hsize_t), names(k), stat, &
                                  length)
        if (stat /= 0) exit
      end do
    end if
    if (stat /= 0) call fail(failure, failure_io, where//': its root group cannot be listed (a damaged file)', where)
    call file%close(closing)
    if (.not. failure%failed() .and. closing%failed()) failure = closing
  end subroutine member_names

  ! Opens the file at `path` (relative to the namelist's folder unless absolute) read-only as
  ! `file`; `where` is the path as resolved; a failure names a missing or non-HDF5 file.
  subroutine open_file(self, path, file, where, failure)
    class(hdf5_arrays), intent(in) :: self
    character(len=*), intent(in) :: path
    type(hdf5_file), intent(out) :: file
    character(len=:), allocatable, intent(out) :: where
    type(failure_type), intent(out) :: failure
    logical :: exists

    where = path
    if (path(1:1) /= '/' .and. allocated(self%folder)) where = self%folder//path
    inquire (file=where, exist=exists)
    if (.not. exists) then
      call fail(failure, failure_io, where//': no such file', where)
      return
    else if (hdf5_file_kind(where) == not_hdf5) then
      call fail(failure, failure_io, where//': not an HDF5 file', where)
      return
    end if
    call file%open_existing(where, .false., failure)
    if (failure%failed()) failure%message = where//': '//failure%message
  end subroutine open_file

  ! Dataset `name` of the open file `file_id`, if it exists, read whole as real64, or its row `row`
  ! (from 0) along the first axis.
  subroutine read_dataset(file_id, where, name, values, shape, found, failure, row)
    integer(hid_t), intent(in) :: file_id
    character(len=*), intent(in) :: where, name
    real(real64), allocatable, target, intent(inout) :: values(:)
    integer, allocatable, intent(inout) :: shape(:)
    logical, intent(out) :: found
    type(failure_type), intent(out) :: failure
    integer, intent(in), optional :: row
    integer(hid_t) :: dataset, space, stored, memory
    integer(hsize_t), allocatable :: dims(:), most(:), start(:), count(:)
    type(c_ptr) :: buffer
    integer :: stat, rank, class, k, closed

    call h5lexists_f(file_id, name, found, stat)
    found = found .and. stat == 0
    if (.not. found) return
    call h5dopen_f(file_id, name, dataset, stat)
    if (stat /= 0) then
      call fail(failure, failure_io, where//': dataset '''//name//''' cannot be opened', name)
      return
    end if
    call h5dget_space_f(dataset, space, stat)
    call h5sget_simple_extent_ndims_f(space, rank, stat)
    allocate (dims(max(rank, 0)), most(max(rank, 0)))
    if (rank > 0) call h5sget_simple_extent_dims_f(space, dims, most, stat)
    call h5dget_type_f(dataset, stored, stat)
    call h5tget_class_f(stored, class, stat)
    if (class /= H5T_FLOAT_F .and. class /= H5T_INTEGER_F) then
      call fail(failure, failure_io, where//': dataset '''//name//''' holds no numbers', name)
    else if (.not. present(row)) then
      shape = int(dims(size(dims):1:-1))    ! HDF5's Fortran interface gives the dimensions reversed
      deallocate (values)
      allocate (values(product(shape)))
      if (size(values) > 0) then
        buffer = c_loc(values(1))
        call h5dread_f(dataset, H5T_NATIVE_DOUBLE, buffer, stat)
        if (stat /= 0) call fail(failure, failure_io, where//': dataset '''//name//''' cannot be read (a damaged file)', &
                                 name)
      end if
    else if (rank < 1) then
      call fail(failure, failure_io, where//': dataset '''//name//''' has no rows', name)
    else if (row < 0 .or. row >= int(dims(rank))) then
      call fail(failure, failure_io, where//': dataset '''//name//''' has no row '//integer_text(row)// &
                ' (it has '//integer_text(int(dims(rank)))//')', name)
    else
      ! The row: the last of HDF5's reversed dimensions is h5py's first.
      shape = int(dims(size(dims) - 1:1:-1))
      start = [(0_hsize_t, k=1, rank - 1), int(row, hsize_t)]
      count = [dims(1:rank - 1), 1_hsize_t]
      deallocate (values)
      allocate (values(max(1, product(shape))))
      call h5sselect_hyperslab_f(space, H5S_SELECT_SET_F, start, count, stat)
      if (stat == 0) call h5screate_simple_f(rank, count, memory, stat)
      if (stat == 0) then
        buffer = c_loc(values(1))
        call h5dread_f(dataset, H5T_NATIVE_DOUBLE, buffer, stat, memory, space)
        call h5sclose_f(memory, closed)
      end if
      if (stat /= 0) call fail(failure, failure_io, where//': dataset '''//name//''' cannot be read (a damaged file)', &
                               name)
    end if
    call h5tclose_f(stored, stat)
    call h5sclose_f(space, stat)
    call h5dclose_f(dataset, stat)
  end subroutine read_dataset

end module hdf5_array_reader
