!> Step-size control for integrators with a local error estimate (docs/integrators.md, Adaptive
!> steps): a PI controller on the estimate's weighted norm `err` (<= 1 accepts), and the choice of
!> the next trial step so that the run lands on t_end exactly without a sliver of a last step.
!>
!> With k the order of the estimate in h (3 for a second-order method's local error), an accepted
!> step of h proposes
!>   h_new = h * min(max_growth, max(min_ratio, safety * err**(-alpha) * err_old**beta)),
!> alpha = 0.7/k, beta = 0.4/k (Gustafsson's PI controller, as in Hairer & Wanner II, IV.2); the
!> first step, and every step right after a rejection, use the plain err**(-1/k) with no growth.
!> A step rejected by its estimate is retried with h * max(min_ratio, safety * err**(-1/k)); a step
!> that could not be solved, or left the model's domain, with h * failure_ratio.
module step_size_control
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: step_controller

  !> The controller of one run.
  type :: step_controller
    real(real64) :: order = 3.0_real64          !! k: the estimate is O(h**k)
    real(real64) :: safety = 0.9_real64
    real(real64) :: min_ratio = 0.2_real64      !! bounds of h_new/h
    real(real64) :: max_growth = 5.0_real64
    real(real64) :: failure_ratio = 0.25_real64 !! h_new/h after a step without a (physical) root
    !> A step whose remaining time to t_end is within this fraction of h is stretched to land.
    real(real64) :: landing_stretch = 0.1_real64
    real(real64) :: h = 0.0_real64              !! the next trial step
    real(real64) :: err_old = 1.0_real64        !! the last accepted step's err
    logical :: has_history = .false.            !! err_old is that of an accepted step
    logical :: rejected = .false.               !! the current step has been rejected at least once
  contains
    procedure :: restart
    procedure :: trial_step
    procedure :: accept
    procedure :: reject_error
    procedure :: reject_failure
  end type step_controller

contains

  !> A new run: h0 is the first trial step; `order` the estimate's order in h.
  pure subroutine restart(self, h0, order)
    class(step_controller), intent(inout) :: self
    real(real64), intent(in) :: h0, order

    self%h = h0
    self%order = order
    self%err_old = 1.0_real64
    self%has_history = .false.
    self%rejected = .false.
  end subroutine restart

  !> The step to try from t: the controller's h, stretched to land on t_end when it nearly
  !> reaches it, or half the remaining time when one step of h would leave less than h (two equal
  !> steps instead of a full one and a sliver). landing: the step ends exactly at t_end.
  pure subroutine trial_step(self, t, t_end, h, landing)
    class(step_controller), intent(in) :: self
    real(real64), intent(in) :: t, t_end
    real(real64), intent(out) :: h
    logical, intent(out) :: landing
    real(real64) :: remaining

    remaining = t_end - t
    h = self%h
    landing = remaining <= (1.0_real64 + self%landing_stretch)*h
    if (landing) then
      h = remaining
    else if (remaining < 2.0_real64*h) then
      h = 0.5_real64*remaining
    end if
  end subroutine trial_step

  !> Step h was accepted with estimate norm err: the next trial step.
  pure subroutine accept(self, h, err)
    class(step_controller), intent(inout) :: self
    real(real64), intent(in) :: h, err
    real(real64) :: ratio, e

    e = max(err, 1.0e-10_real64)       ! a zero estimate (a state at rest) grows at the bound
    if (self%has_history .and. .not. self%rejected) then
      ratio = self%safety*e**(-0.7_real64/self%order)*self%err_old**(0.4_real64/self%order)
    else
      ratio = self%safety*e**(-1.0_real64/self%order)
    end if
    ratio = max(self%min_ratio, min(self%max_growth, ratio))
    if (self%rejected) ratio = min(ratio, 1.0_real64)
    self%h = h*ratio
    self%err_old = e
    self%has_history = .true.
    self%rejected = .false.
  end subroutine accept

  !> Step h was rejected by its estimate norm err > 1: the next trial step is smaller.
  pure subroutine reject_error(self, h, err)
    class(step_controller), intent(inout) :: self
    real(real64), intent(in) :: h, err

    self%h = h*max(self%min_ratio, min(self%safety, self%safety*err**(-1.0_real64/self%order)))
    self%rejected = .true.
  end subroutine reject_error

  !> Step h had no acceptable root (the solver failed, or the root left the model's domain).
  pure subroutine reject_failure(self, h)
    class(step_controller), intent(inout) :: self
    real(real64), intent(in) :: h

    self%h = h*self%failure_ratio
    self%rejected = .true.
  end subroutine reject_failure

end module step_size_control
