!> DOP853's error norm and step-size controller (Hairer, Norsett and Wanner, "Solving Ordinary
!> Differential Equations I", section II.10, and their code DOP853), shared by relaxed_dp853 on
!> the dense path (src/integrator/relaxed_step_control) and on the chain split over ranks
!> (src/model/spring_chain/spring_chain_relaxed_control), which differ only in how they sum:
!>  - the error norm of a step of h from the embedded estimates of orders 5 and 3,
!>    err = |h| err5/sqrt(n (err5 + 0.01 err3)), with err5 = sum_j (sum_i e5_i k_ij / sk_j)^2,
!>    err3 likewise with e3 and sk_j = tolerance (1 + max(|z_j|, |z_new,j|)) (`error_squares`
!>    gives one part's sums; the whole state's are their sum);
!>  - the next step h_new = h min(6, max(1/3, 0.9 err^(-1/8))) after an accepted step, with no
!>    growth right after a rejection, and h max(1/3, 0.9 err^(-1/8)) after a rejected one.
module dop853_control
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: error_squares, dop853_error_norm, accepted_step_factor, rejected_step_factor
  public :: max_error_rejections, landing_slack

  ! DOP853's step-size controller: safety factor and the bounds of h_new/h.
  real(real64), parameter :: safety = 0.9_real64, shrink_limit = 0.333_real64, grow_limit = 6.0_real64
  !> Trial steps one accepted step may reject before the run stops.
  integer, parameter :: max_error_rejections = 100
  !> A step that would leave less than landing_slack h to its landing time lands there instead: a
  !> last step of round-off size would carry no information for relaxation to work with.
  real(real64), parameter :: landing_slack = 0.01_real64

contains

  !> One part's [err5, err3] (module header) from its rows: the combinations sum_i e5_i k_ij and
  !> sum_i e3_i k_ij, and z, z_new.
  pure function error_squares(tolerance, estimate5, estimate3, z, z_new) result(squares)
    real(real64), intent(in) :: tolerance, estimate5(:), estimate3(:), z(:), z_new(:)
    real(real64) :: squares(2)
    real(real64) :: scale
    integer :: j

    squares = 0.0_real64
    do j = 1, size(z)
      scale = tolerance*(1.0_real64 + max(abs(z(j)), abs(z_new(j))))
      squares = squares + [(estimate5(j)/scale)**2, (estimate3(j)/scale)**2]
    end do
  end function error_squares

  !> The error norm of a step of h over n unknowns from the whole state's [err5, err3].
  pure real(real64) function dop853_error_norm(h, squares, n) result(error_norm)
    real(real64), intent(in) :: h, squares(2)
    integer, intent(in) :: n
    real(real64) :: denominator

    denominator = squares(1) + 0.01_real64*squares(2)
    if (denominator <= 0.0_real64) denominator = 1.0_real64
    error_norm = abs(h)*squares(1)/sqrt(n*denominator)
  end function dop853_error_norm

  !> h_new/h after a step accepted with `error_norm` (<= 1); not above 1 after a rejection.
  pure real(real64) function accepted_step_factor(error_norm, after_rejection) result(factor)
    real(real64), intent(in) :: error_norm
    logical, intent(in) :: after_rejection

    factor = grow_limit
    if (error_norm > 0.0_real64) factor = min(grow_limit, max(shrink_limit, safety*error_norm**(-0.125_real64)))
    if (after_rejection) factor = min(factor, 1.0_real64)
  end function accepted_step_factor

  !> h_new/h after a step rejected with `error_norm` (> 1).
  pure real(real64) function rejected_step_factor(error_norm) result(factor)
    real(real64), intent(in) :: error_norm

    factor = max(shrink_limit, safety*error_norm**(-0.125_real64))
  end function rejected_step_factor

end module dop853_control
