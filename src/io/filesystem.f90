!> Directory creation and atomic rename (src/io/posix_files.c), with Fortran strings.
module filesystem
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_null_char
  implicit none (type, external)
  private
  public :: make_directories, make_parent_directories, rename_file

  interface
    function c_make_directories(path) result(status) bind(c, name='eme_make_directories')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: status
    end function c_make_directories
    function c_rename_file(from, to) result(status) bind(c, name='eme_rename_file')
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: from(*), to(*)
      integer(c_int) :: status
    end function c_rename_file
  end interface

contains

  !> mkdir -p path; stat = 0 on success.
  subroutine make_directories(path, stat)
    character(len=*), intent(in) :: path
    integer, intent(out) :: stat

    stat = int(c_make_directories(trim(path)//c_null_char))
  end subroutine make_directories

  !> Creates the directory that will hold `file` (nothing to do for a bare file name).
  subroutine make_parent_directories(file, stat)
    character(len=*), intent(in) :: file
    integer, intent(out) :: stat
    integer :: slash

    stat = 0
    slash = index(file, '/', back=.true.)
    if (slash > 1) call make_directories(file(1:slash - 1), stat)
  end subroutine make_parent_directories

  !> Renames `from` to `to`, replacing `to`; stat = 0 on success.
  subroutine rename_file(from, to, stat)
    character(len=*), intent(in) :: from, to
    integer, intent(out) :: stat

    stat = int(c_rename_file(trim(from)//c_null_char, trim(to)//c_null_char))
  end subroutine rename_file

end module filesystem
