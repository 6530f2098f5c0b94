!> Whether a run may write its output file where the input says, checked before anything is
!> written: not over its own input file, not over a directory or a device, and not over a file
!> that is not HDF5 unless replacing was asked for (docs/faults.md, "Inputs that would destroy
!> files").
module output_path
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char
  use hdf5, only: h5fis_hdf5_f
  use failures, only: failure_type, fail, failure_input
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

  !> A failure (failure_input) with a message naming the input file, &output file and what is
  !> allowed if `output_file` must not be written: it is `input_file` itself, a directory or
  !> another non-regular file, or (unless `replace_allowed`) an existing file that is not HDF5.
  subroutine check_output_path(output_file, input_file, replace_allowed, failure)
    character(len=*), intent(in) :: output_file, input_file
    logical, intent(in) :: replace_allowed
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: where
    logical :: is_hdf5
    integer :: hdf5_stat

    where = input_file//': &output: file = '''//output_file//''''
    select case (c_path_kind(output_file//c_null_char))
    case (path_absent)
      return
    case (path_regular)
      if (c_same_file(output_file//c_null_char, input_file//c_null_char) /= 0) then
        call fail(failure, failure_input, where//' is the input file itself; allowed: another path ending in .h5', &
                  input_file)
        return
      end if
      if (replace_allowed) return
      call h5fis_hdf5_f(output_file, is_hdf5, hdf5_stat)
      if (hdf5_stat == 0 .and. is_hdf5) return
      call fail(failure, failure_input, where//' exists and is not an HDF5 file, and is kept; allowed: another '// &
                'path, or &output overwrite = .true. (or -eme_overwrite) to replace it', input_file)
    case (path_directory)
      call fail(failure, failure_input, where//' is a directory; allowed: the path of a file ending in .h5', input_file)
    case default
      call fail(failure, failure_input, where//' exists and is not a regular file; allowed: the path of a file '// &
                'ending in .h5', input_file)
    end select
  end subroutine check_output_path

end module output_path
