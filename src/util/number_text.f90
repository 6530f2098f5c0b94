!> Numbers as text for messages and status lines.
module number_text
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  implicit none (type, external)
  private
  public :: integer_text, fixed_text, scientific_text, reals_text

  !> An integer (default or 64-bit) without blanks.
  interface integer_text
    module procedure default_integer_text, long_integer_text
  end interface integer_text

contains

  pure function long_integer_text(i) result(text)
    integer(int64), intent(in) :: i
    character(len=:), allocatable :: text
    character(len=24) :: buffer

    write (buffer, '(i0)') i
    text = trim(buffer)
  end function long_integer_text

  pure function default_integer_text(i) result(text)
    integer, intent(in) :: i
    character(len=:), allocatable :: text
    character(len=16) :: buffer

    write (buffer, '(i0)') i
    text = trim(buffer)
  end function default_integer_text

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

  !> Values as a user would write them, to 6 significant digits: 280.0, 0.011, -0.1, 1e-8, 5e9.
  pure function reals_text(values) result(text)
    real(real64), intent(in) :: values(:)
    character(len=:), allocatable :: text
    integer :: i

    text = ''
    do i = 1, size(values)
      if (i > 1) text = text//', '
      text = text//real_text(values(i))
    end do
  end function reals_text

  ! One value for reals_text: fixed notation from 1e-3 to 1e7, else mantissa 'e' exponent.
  pure function real_text(x) result(text)
    real(real64), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=40) :: buffer
    integer :: decimals, exponent_at, exponent

    if (ieee_is_nan(x)) then
      text = 'NaN'
    else if (abs(x) > huge(x)) then
      text = trim(merge('Inf ', '-Inf', x > 0))
    else if (abs(x) < 1.0e-3_real64 .and. abs(x) > 0.0_real64 .or. abs(x) >= 1.0e7_real64) then
      write (buffer, '(es15.5e3)') x
      exponent_at = index(buffer, 'E')
      read (buffer(exponent_at + 1:), *) exponent
      text = without_trailing_zeros(trim(adjustl(buffer(1:exponent_at - 1))))
      if (text(len(text):len(text)) == '0') text = text(1:len(text) - 2)    ! 1.0 -> 1
      write (buffer, '(i0)') exponent
      text = text//'e'//trim(buffer)
    else
      decimals = 1
      if (abs(x) > 0.0_real64) decimals = max(1, 5 - floor(log10(abs(x))))
      write (buffer, '(f40.'//integer_text(decimals)//')') x
      text = without_trailing_zeros(trim(adjustl(buffer)))
    end if
  end function real_text

  ! '12.3400' -> '12.34', '280.000' -> '280.0': trailing zeros go, one digit after '.' stays.
  pure function without_trailing_zeros(number) result(text)
    character(len=*), intent(in) :: number
    character(len=:), allocatable :: text
    integer :: last

    last = len(number)
    do while (last > 1 .and. number(last:last) == '0' .and. number(max(1, last - 1):max(1, last - 1)) /= '.')
      last = last - 1
    end do
    text = number(1:last)
  end function without_trailing_zeros

end module number_text
