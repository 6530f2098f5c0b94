!> The root search of the relaxation of a Runge-Kutta step (docs/integrators.md, "Relaxation"),
!> shared by the dense relaxed steps (src/integrator/relaxation) and the chain's split ones
!> (src/model/spring_chain/spring_chain_relaxed_run), which differ only in how they evaluate
!> r(gamma) = E(P(z + gamma d)) - E(z) [- thetabar (S(...) - S(z) - gamma e_S)]: from the whole
!> state, or as sums of the ranks' per-part differences. r(0) = 0, so the secant runs on
!> q(gamma) = r(gamma)/gamma, whose root is the nontrivial one. `floor` is r's rounding floor
!> (what rounding z_new to doubles alone moves E by): a gamma whose |r| is within it is a root.
module relaxation_root
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  implicit none (type, external)
  private
  public :: relaxation_function, find_relaxation_root, gamma_min, gamma_max, max_halvings, gamma_band, &
            gamma_warning_deviation

  !> The gamma a step may take (docs/integrators.md); outside, the step is rejected.
  real(real64), parameter :: gamma_min = 0.2_real64, gamma_max = 2.0_real64
  !> Depth of the halving of a rejected relaxed step: 2^12 substeps at most.
  integer, parameter :: max_halvings = 12
  !> The largest |gamma - 1| of an accepted (sub)step that passes without a warning.
  real(real64), parameter :: gamma_warning_deviation = 0.1_real64
  integer, parameter :: max_secant_steps = 30
  real(real64), parameter :: settled = 1.0e-13_real64   !! a secant step this small ends the iteration

  !> What the search asks of a step: the relaxed state at a gamma, and q(gamma) there.
  type, abstract :: relaxation_function
  contains
    procedure(move_interface), deferred :: move
    procedure(residual_interface), deferred :: scaled_residual
  end type relaxation_function

  abstract interface
    !> Makes z_new = P(z + gamma d) the step's relaxed state; stat: a domain code.
    subroutine move_interface(self, gamma, stat)
      import :: relaxation_function, real64
      class(relaxation_function), intent(inout) :: self
      real(real64), intent(in) :: gamma
      integer, intent(out) :: stat
    end subroutine move_interface

    !> q = r(gamma)/gamma at z_new = P(z + gamma d) (which it makes the relaxed state); stat: a
    !> domain code, or one for a non-finite q.
    subroutine residual_interface(self, gamma, q, stat)
      import :: relaxation_function, real64
      class(relaxation_function), intent(inout) :: self
      real(real64), intent(in) :: gamma
      real(real64), intent(out) :: q
      integer, intent(out) :: stat
    end subroutine residual_interface
  end interface

contains

  !> The largest |gamma - 1| a step of an order-p tableau may take at `tolerance`:
  !> 10 tol^((p-1)/(p+1)) (src/integrator/relaxed_stepper's header says why).
  pure real(real64) function gamma_band(tolerance, order)
    real(real64), intent(in) :: tolerance
    integer, intent(in) :: order

    gamma_band = 10.0_real64*tolerance**(real(order - 1, real64)/real(order + 1, real64))
  end function gamma_band

  !> gamma with r(gamma) = 0 to the rounding floor `floor`, its relaxed state made (`move`);
  !> found = .false. when no root lies in [gamma_min, gamma_max] or an evaluation leaves the
  !> domain. `evaluations` counts the residuals taken; `resolution` is how far rounding alone
  !> moves the root: 2 floor / |dq/dgamma| at the root. A short step's r(gamma) is flat (its
  !> slope ~ |d|^2), so this grows like (|z|/|d|)^2 eps.
  subroutine find_relaxation_root(problem, floor, gamma, found, evaluations, resolution)
    class(relaxation_function), intent(inout) :: problem
    real(real64), intent(in) :: floor
    real(real64), intent(out) :: gamma
    logical, intent(out) :: found
    integer, intent(out) :: evaluations
    real(real64), intent(out), optional :: resolution
    real(real64) :: g_a, g_b, q_a, q_b, g_next, best, best_r
    integer :: k, stat
    logical :: stalled

    found = .false.
    evaluations = 0
    gamma = 1.0_real64
    if (present(resolution)) resolution = huge(1.0_real64)
    ! From gamma = 1 (an order-p step has r(1) = O(h^(p+1))) and 1 - 1e-3. It always takes a
    ! secant step: r(1) is the method's own energy error, which may lie below the floor and yet
    ! accumulate over many steps if accepted; the secant's root has only rounding left in r.
    g_a = 1.0_real64
    call evaluate(g_a, q_a)
    if (stat /= failure_none) return
    g_b = 1.0_real64 - 1.0e-3_real64
    call evaluate(g_b, q_b)
    if (stat /= failure_none) return
    best = 1.0_real64
    best_r = abs(q_a)
    ! Secant steps (q is nearly linear near the root, so they converge fast) until |r| is an
    ! eighth of the floor or a step moves gamma by less than `settled` (then only rounding is
    ! left to change). The best gamma is a root if its |r| is within the floor.
    do k = 1, max_secant_steps
      if (.not. (abs(q_b - q_a) > 0.0_real64)) exit
      g_next = g_b - q_b*(g_b - g_a)/(q_b - q_a)
      if (.not. (g_next >= 0.5_real64*gamma_min .and. g_next <= 2.0_real64*gamma_max)) exit
      stalled = abs(g_next - g_b) <= settled
      g_a = g_b
      q_a = q_b
      g_b = g_next
      call evaluate(g_b, q_b)
      if (stat /= failure_none) return
      if (abs(q_b*g_b) < best_r) then
        best = g_b
        best_r = abs(q_b*g_b)
      end if
      if (stalled .or. best_r <= 0.125_real64*floor) exit
    end do
    gamma = best
    if (present(resolution)) then
      if (abs(g_b - g_a) > 0.0_real64 .and. abs(q_b - q_a) > 0.0_real64) &
        resolution = 2.0_real64*floor/abs((q_b - q_a)/(g_b - g_a))
    end if
    found = best_r <= floor .and. gamma >= gamma_min .and. gamma <= gamma_max
    if (found) call problem%move(gamma, stat)
    found = found .and. stat == failure_none

  contains

    subroutine evaluate(g, q)
      real(real64), intent(in) :: g
      real(real64), intent(out) :: q

      call problem%scaled_residual(g, q, stat)
      evaluations = evaluations + 1
    end subroutine evaluate
  end subroutine find_relaxation_root

end module relaxation_root
