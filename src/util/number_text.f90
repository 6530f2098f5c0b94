!> Numbers as text for messages and status lines.
module number_text
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  implicit none (type, external)
  private
  public :: integer_text, fixed_text, scientific_text, reals_text

  !> fixed_text's largest magnitude in fixed notation: above it, fixed notation shows digits that
  !> a double (15 to 17 significant digits) does not hold.
  real(real64), parameter :: fixed_limit = 1.0e15_real64

  !> An integer (default or 64-bit) without blanks.
  interface integer_text
    module procedure default_integer_text, long_integer_text
  end interface integer_text

contains

  ! Digit by digit, not by an internal write: a chain of 10^5 springs names 4 x 10^5 columns, and
  ! the write took about 30,000 instructions a number (a third of a 15,000-spring run's start).
  pure function long_integer_text(i) result(text)
    integer(int64), intent(in) :: i
    character(len=:), allocatable :: text
    character(len=20) :: digits
    integer(int64) :: rest
    integer :: at

    at = len(digits) + 1
    rest = i
    do
      at = at - 1
      digits(at:at) = achar(iachar('0') + abs(int(mod(rest, 10_int64))))
      rest = rest/10
      if (rest == 0) exit
    end do
    if (i < 0) then
      at = at - 1
      digits(at:at) = '-'
    end if
    text = digits(at:)
  end function long_integer_text

  pure function default_integer_text(i) result(text)
    integer, intent(in) :: i
    character(len=:), allocatable :: text

    text = long_integer_text(int(i, int64))
  end function default_integer_text

  !> A real in fixed notation with `decimals` digits after the point, without blanks (right-aligned
  !> in `width` characters if given and the text is shorter). Where fixed notation would not say
  !> the number, it is written as scientific_text writes it with `decimals` digits after the point
  !> (at least one): from 1e15 up, where it would show more digits than a double holds (1e300
  !> filled a field of 40 with stars), and below half a unit of its last decimal, where it would
  !> read 0 (1e-20 with 3 decimals); NaN and Inf as such.
  pure function fixed_text(x, decimals, width) result(text)
    real(real64), intent(in) :: x
    integer, intent(in) :: decimals
    integer, intent(in), optional :: width
    character(len=:), allocatable :: text
    character(len=40) :: buffer

    if (.not. abs(x) < fixed_limit .or. (abs(x) > 0.0_real64 .and. abs(x) < 0.5_real64*10.0_real64**(-decimals))) then
      text = scientific_text(x, max(1, decimals))
    else
      write (buffer, '(f40.'//integer_text(decimals)//')') x
      text = trim(adjustl(buffer))
    end if
    if (present(width)) text = right_aligned(text, width)
  end function fixed_text

  !> A real in scientific notation, d.ddddE+xx with `decimals` digits after the point (4 unless
  !> given) and an exponent of at least two digits (all of its digits, 1.0000E-300), without
  !> blanks (right-aligned in `width` characters if given and the text is shorter); NaN, Inf and
  !> -Inf as such.
  pure function scientific_text(x, decimals, width) result(text)
    real(real64), intent(in) :: x
    integer, intent(in), optional :: decimals, width
    character(len=:), allocatable :: text
    character(len=48) :: buffer
    integer :: digits, exponent_at, exponent

    digits = 4
    if (present(decimals)) digits = decimals
    if (ieee_is_nan(x)) then
      text = 'NaN'
    else if (abs(x) > huge(x)) then
      text = trim(merge('Inf ', '-Inf', x > 0))
    else
      ! The exponent's field of 3 digits holds every double's; it is written again without padding.
      write (buffer, '(es48.'//integer_text(digits)//'e3)') x
      exponent_at = index(buffer, 'E')
      read (buffer(exponent_at + 1:), *) exponent
      write (buffer(exponent_at + 1:), '(sp, i0.2)') exponent
      text = trim(adjustl(buffer))
    end if
    if (present(width)) text = right_aligned(text, width)
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

  ! The text right-aligned in `width` characters; a longer text is kept whole.
  pure function right_aligned(text, width) result(aligned)
    character(len=*), intent(in) :: text
    integer, intent(in) :: width
    character(len=:), allocatable :: aligned

    aligned = repeat(' ', max(0, width - len(text)))//text
  end function right_aligned

end module number_text
