!> Numbers as text for messages and status lines.
module number_text
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: integer_text, fixed_text, scientific_text

contains

  !> An integer without blanks.
  pure function integer_text(i) result(text)
    integer, intent(in) :: i
    character(len=:), allocatable :: text
    character(len=16) :: buffer

    write (buffer, '(i0)') i
    text = trim(buffer)
  end function integer_text

  !> A real in fixed notation with `decimals` digits after the point, without blanks.
  pure function fixed_text(x, decimals) result(text)
    real(real64), intent(in) :: x
    integer, intent(in) :: decimals
    character(len=:), allocatable :: text
    character(len=40) :: buffer

    write (buffer, '(f40.'//integer_text(decimals)//')') x
    text = trim(adjustl(buffer))
  end function fixed_text

  !> A real in scientific notation with 4 digits after the point, without blanks.
  pure function scientific_text(x) result(text)
    real(real64), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=16) :: buffer

    write (buffer, '(es16.4)') x
    text = trim(adjustl(buffer))
  end function scientific_text

end module number_text
