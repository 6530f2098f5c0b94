!> The 2-norm of the Newton loops' vectors (residuals, updates, iterates; 9 to 17 numbers, a dozen
!> norms a step): the plain sum of squares wherever it neither overflows nor loses accuracy to
!> underflow, else the sum of squares of x scaled by its largest entry. (gfortran's norm2 divides
!> every entry by a running scale, which costs more, and it starts that scale at 1, so that its
!> norm of a vector of entries below 1e-154 loses digits, and below 1e-162 is 0.)
module euclidean_norm
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: two_norm

  !> Below this sum of squares an entry's square may have underflowed by more than the sum's
  !> rounding: tiny/epsilon.
  real(real64), parameter :: smallest_exact_sum = tiny(1.0_real64)/epsilon(1.0_real64)

contains

  !> |x|_2: sqrt(x.x) if smallest_exact_sum <= x.x <= huge (no square overflowed, and an
  !> underflowed one weighs less than the sum's rounding), else m sqrt((x/m).(x/m)) with m the
  !> largest |x_i| (0 for x = 0, infinite or NaN as x's entries are).
  pure real(real64) function two_norm(x)
    real(real64), intent(in) :: x(:)
    real(real64) :: sum_of_squares, largest
    integer :: i

    sum_of_squares = 0.0_real64
    do i = 1, size(x)
      sum_of_squares = sum_of_squares + x(i)*x(i)
    end do
    if (sum_of_squares >= smallest_exact_sum .and. sum_of_squares <= huge(1.0_real64)) then
      two_norm = sqrt(sum_of_squares)
      return
    end if
    largest = maxval(abs(x))
    if (largest > 0.0_real64 .and. largest <= huge(1.0_real64)) then
      two_norm = largest*sqrt(sum((x/largest)**2))
    else
      two_norm = largest + sum_of_squares    ! x = 0: 0; an infinite entry: +Inf; a NaN (which the sum keeps): NaN
    end if
  end function two_norm

end module euclidean_norm
