!> Whether a run may write its output file where the input says, checked before anything is
!> written: not over its own input file, not over a directory or a device, and not over a file
!> that is not HDF5 unless replacing was asked for (docs/faults.md, "Inputs that would destroy
!> files").
module output_path
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char
  use hdf5, only: h5fis_hdf5_f
  implicit none (type, external)
  private
  public :: check_output_path

  integer, parameter :: path_absent = 0, path_regular = 1, path_directory = 2

  interface
    function c_path_kind(path) result(kind) bind(c, name='eme_path_kind')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: kind
    end function c_path_kind
    function c_same_file(first, second) result(same) bind(c, name='eme_same_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: first(*), second(*)
      integer(c_int) :: same
    end function c_same_file
  end interface

contains

  !> stat /= 0 with a message naming the input file, &output file and what is allowed if
  !> `output_file` must not be written: it is `input_file` itself, a directory or another
  !> non-regular file, or (unless `replace_allowed`) an existing file that is not HDF5.
  subroutine check_output_path(output_file, input_file, replace_allowed, stat, message)
    character(len=*), intent(in) :: output_file, input_file
    logical, intent(in) :: replace_allowed
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    character(len=:), allocatable :: where
    logical :: is_hdf5
    integer :: hdf5_stat

    stat = 0
    message = ''
    where = input_file//': &output: file = '''//output_file//''''
    select case (c_path_kind(output_file//c_null_char))
    case (path_absent)
      return
    case (path_regular)
      if (c_same_file(output_file//c_null_char, input_file//c_null_char) /= 0) then
        stat = 1
        message = where//' is the input file itself; allowed: another path ending in .h5'
        return
      end if
      if (replace_allowed) return
      call h5fis_hdf5_f(output_file, is_hdf5, hdf5_stat)
      if (hdf5_stat == 0 .and. is_hdf5) return
      stat = 1
      message = where//' exists and is not an HDF5 file, and is kept; allowed: another path, or '// &
                '&output overwrite = .true. (or -eme_overwrite) to replace it'
    case (path_directory)
      stat = 1
      message = where//' is a directory; allowed: the path of a file ending in .h5'
    case default
      stat = 1
      message = where//' exists and is not a regular file; allowed: the path of a file ending in .h5'
    end select
  end subroutine check_output_path

end module output_path
