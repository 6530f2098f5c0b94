!> The versions of the code and of every library it links, asked of the libraries at run time
!> (src/io/version_queries.c), for --version and for the provenance an output file stores.
module library_versions
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char
  use, intrinsic :: iso_fortran_env, only: compiler_version
  use build_info, only: code_version
  implicit none (type, external)
  private
  public :: library_names, library_version, print_versions

  !> The names library_version answers for, in the order --version prints them.
  character(len=*), parameter :: library_names(7) = [character(len=8) :: 'eme', 'PETSc', 'HDF5', 'MPI', 'SUNDIALS', &
                                                      'LAPACK', 'compiler']

  interface
    function c_library_version(which, text, size) result(status) bind(c, name='eme_library_version')
      import :: c_char, c_int
      integer(c_int), value :: which, size
      character(kind=c_char), intent(out) :: text(*)
      integer(c_int) :: status
    end function c_library_version
    ! LAPACK's own version (LAPACK >= 3.2).
    subroutine ilaver(major, minor, patch)
      integer, intent(out) :: major, minor, patch
    end subroutine ilaver
  end interface

contains

  !> The version of `name` (one of library_names): the code's release and git description, the library's
  !> version as it reports it, or 'unknown' if it does not answer.
  function library_version(name) result(version)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: version
    character(kind=c_char, len=1024) :: buffer
    character(len=48) :: numbers
    integer :: which, major, minor, patch

    select case (name)
    case ('eme')
      version = code_version
      return
    case ('LAPACK')
      call ilaver(major, minor, patch)
      write (numbers, '(i0, ".", i0, ".", i0)') major, minor, patch
      version = trim(numbers)
      return
    case ('compiler')
      version = compiler_version()
      return
    end select
    which = findloc(library_names(2:5), name, dim=1)
    version = 'unknown'
    buffer = ''
    if (which == 0) return
    if (c_library_version(int(which, c_int), buffer, len(buffer, kind=c_int)) /= 0) return
    version = buffer(1:index(buffer, c_null_char) - 1)
  end function library_version

  !> 'name: version' for the code and each library, one per line (--version).
  subroutine print_versions(unit, program_name)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: program_name
    integer :: i

    write (unit, '(a)') program_name//' (eme) '//library_version('eme')
    do i = 2, size(library_names)
      write (unit, '(a)') trim(library_names(i))//': '//library_version(trim(library_names(i)))
    end do
  end subroutine print_versions

end module library_versions
