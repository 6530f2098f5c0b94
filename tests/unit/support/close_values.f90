!> Closeness of computed and expected values within an absolute and a relative tolerance,
!> elementwise: |got - expected| <= atol + rtol |expected| (pFUnit's assertEqual takes an absolute
!> tolerance only). `closeness` says where the worst entry is, for an assertion's message.
module close_values
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  implicit none
  private
  public :: is_close, closeness

contains

  !> Whether every entry is within atol + rtol |expected| (false for a size mismatch or NaN).
  pure logical function is_close(got, expected, rtol, atol)
    real(real64), intent(in) :: got(:), expected(:)
    real(real64), intent(in), optional :: rtol, atol

    is_close = size(got) == size(expected)
    if (is_close) is_close = all(excess(got, expected, rtol, atol) <= 0.0_real64)
  end function is_close

  !> The worst entry: its index, got, expected and the tolerances.
  function closeness(got, expected, rtol, atol) result(text)
    real(real64), intent(in) :: got(:), expected(:)
    real(real64), intent(in), optional :: rtol, atol
    character(len=:), allocatable :: text
    character(len=200) :: buffer
    real(real64) :: over(size(got))
    integer :: worst

    if (size(got) /= size(expected)) then
      write (buffer, '(a, i0, a, i0)') 'size ', size(got), ' /= expected size ', size(expected)
    else
      over = excess(got, expected, rtol, atol)
      worst = maxloc(over, dim=1)
      write (buffer, '(a, i0, a, es23.15, a, es23.15, a, es9.2)') 'entry ', worst, ': got ', got(worst), &
        ', expected ', expected(worst), ', excess over the tolerance ', over(worst)
    end if
    text = trim(buffer)
  end function closeness

  pure function excess(got, expected, rtol, atol) result(over)
    real(real64), intent(in) :: got(:), expected(:)
    real(real64), intent(in), optional :: rtol, atol
    real(real64) :: over(size(got)), r, t

    r = 0.0_real64
    t = 0.0_real64
    if (present(rtol)) r = rtol
    if (present(atol)) t = atol
    over = abs(got - expected) - (t + r*abs(expected))
    where (ieee_is_nan(over)) over = huge(1.0_real64)     ! NaN fails
  end function excess

end module close_values
