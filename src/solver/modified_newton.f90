!> The modified Newton of the lean step solver (docs/integrators.md, "Convergence"): within a
!> solve, the LU factors are kept across Newton iterations while their observed contraction would
!> bring the iterate to the acceptance level within chord_iterations more iterations; they are
!> made anew when it would not (the contraction got worse than that threshold), and at a solve's
!> first iteration (the previous solve's factors serve only the predictor's chord step: on the
!> next step's system they contract too slowly to certify a root at round-off, measured in
!> docs/performance.md). An iteration with kept factors (a chord iteration) converges linearly,
!> so its iterate is accepted only where the error its contraction leaves, rate/(1 - rate)
!> |update|, is below chord_error_limit: eps |z|/64 times the step length in seconds, which
!> bounds what chord iterates add over a run of T seconds to T/(64 s) ulps of |z|; a Newton
!> update (new factors) is accepted by retry_strategies' newton_converged, as without the
!> modified Newton, whose final chord step (retry_strategies' final_chord_step) is a chord
!> iterate too and is accepted by the same test.
!>
!> The contraction that decides is the last update's residual ratio r_k/r_(k-1): for kept factors
!> it is theirs; for the Newton update that made them, it is the chord rate of the new factors
!> (Newton's error falls from e to c e^2, and chord steps with factors made at e contract by c e).
!> The acceptance uses the ratio of two updates of the solve with the same factors (the error bound
!> is in the unknowns' norm). Pure Fortran, shared by the SNES shell (src/solver/snes_shell) and
!> the hand-written loop (src/solver/hand_newton), so that both take the same iterations.
module modified_newton
  use, intrinsic :: iso_fortran_env, only: real64
  use retry_strategies, only: newton_converged, rounding_factor
  implicit none (type, external)
  private
  public :: factor_record, chord_converged, chord_error_limit, default_chord_iterations, largest_rate

  !> Chord iterations the kept factors may need to reach the acceptance level (measured, docs/performance.md).
  integer, parameter :: default_chord_iterations = 2
  !> A contraction above this is never kept nor trusted: rate/(1 - rate) would exceed 1.
  real(real64), parameter :: largest_rate = 0.5_real64
  !> The error a chord iterate may leave, in ulps of |z| per second of the step length (measured,
  !> docs/performance.md: 1/16 let J_z drift 25 times further on the stiff scene in the internal
  !> energy, whose |z| the internal energies dominate).
  real(real64), parameter :: chord_error_rate = 1.0_real64/64

  !> What is known, within a solve, of the LU factors in use: whether they were made for the
  !> update just taken and how they contract.
  type :: factor_record
    logical :: enabled = .false.                  !! the modified Newton (else a Jacobian every iteration)
    integer :: chord_iterations = default_chord_iterations
    !> the last update used factors kept from an earlier iterate of the solve (a chord update: the
    !> modified Newton's, or without it the final chord step), not made at its start point;
    !> .false. where no caller says (PETSc's own preconditioner set-up)
    logical :: chord = .false.
    real(real64) :: last_update = 0.0_real64      !! 2-norm of the last update with these factors (0: none yet)
    real(real64) :: start_residual = 0.0_real64   !! the residual's 2-norm where it started
    real(real64) :: update_rate = 0.0_real64      !! their last two updates' ratio, if `measured`
    logical :: measured = .false.
  contains
    procedure :: begin_solve
    procedure :: must_factor
    procedure :: factored
    procedure :: kept
    procedure :: updated
    procedure :: converged
  end type factor_record

contains

  !> The error a chord iterate may leave in a step of `step_length` seconds whose unknowns have
  !> the rounding scale `state_scale` (nonlinear_system's rounding_scales).
  pure real(real64) function chord_error_limit(state_scale, step_length)
    real(real64), intent(in) :: state_scale, step_length

    chord_error_limit = chord_error_rate*epsilon(1.0_real64)*state_scale*step_length
  end function chord_error_limit

  !> A solve starts: no update has been made with the factors at hand in it.
  pure subroutine begin_solve(self)
    class(factor_record), intent(inout) :: self

    self%chord = .false.
    self%last_update = 0.0_real64
    self%start_residual = 0.0_real64
    self%measured = .false.
  end subroutine begin_solve

  !> Whether the next iteration, at a residual of 2-norm `residual_norm`, must make new factors for
  !> a step of `step_length` whose unknowns have the rounding scale `state_scale`: there are none,
  !> no update of this solve was made with them, or their contraction rate (the last update's
  !> residual ratio) is above largest_rate or would not bring the error, about rate/(1 - rate)
  !> times the last update, below chord_error_limit within chord_iterations more iterations, or
  !> not at all: rate times the updates' rounding above the limit (at small steps, where only
  !> Newton's quadratic convergence reaches it, a chord iteration would be spent for nothing).
  pure logical function must_factor(self, ready, residual_norm, state_scale, step_length)
    class(factor_record), intent(in) :: self
    logical, intent(in) :: ready
    real(real64), intent(in) :: residual_norm, state_scale, step_length
    real(real64) :: rate

    must_factor = .not. (ready .and. self%last_update > 0.0_real64 .and. self%start_residual > 0.0_real64)
    if (must_factor) return
    rate = residual_norm/self%start_residual
    must_factor = .not. (rate <= largest_rate)
    if (must_factor) return
    ! The updates cannot fall below their rounding, about eps |z|/8 (0.1 to 0.3 eps |z| measured).
    must_factor = .not. (rate/(1.0_real64 - rate)*max(self%last_update*rate**self%chord_iterations, &
                                                      epsilon(1.0_real64)*state_scale/8) <= &
                         chord_error_limit(state_scale, step_length))
  end function must_factor

  !> New factors were made at the current iterate.
  pure subroutine factored(self)
    class(factor_record), intent(inout) :: self

    self%chord = .false.
    self%last_update = 0.0_real64
    self%measured = .false.
  end subroutine factored

  !> The next update is taken with the factors at hand.
  pure subroutine kept(self)
    class(factor_record), intent(inout) :: self

    self%chord = .true.
  end subroutine kept

  !> An update of 2-norm `update_norm` was taken from an iterate whose residual had 2-norm
  !> `start_residual`: with the update before it from the same factors, it measures their
  !> contraction for the convergence test.
  pure subroutine updated(self, update_norm, start_residual)
    class(factor_record), intent(inout) :: self
    real(real64), intent(in) :: update_norm, start_residual

    self%measured = self%last_update > 0.0_real64
    if (self%measured) self%update_rate = update_norm/self%last_update
    self%last_update = update_norm
    self%start_residual = start_residual
  end subroutine updated

  !> The convergence test of the iterate the last update reached, in a step of `step_length`:
  !> retry_strategies' newton_converged after a Newton update (new factors) and at iteration 0;
  !> chord_converged after a chord update, also the final chord step without the modified Newton
  !> (accepted by Newton's test, its iterate kept an error of |update| times the Newton update
  !> before it: min dS = -4.97e-14, 56 ulps of S, on the gas containers without friction at
  !> dt = 0.5, docs/integrators.md). The other arguments as newton_converged's.
  pure logical function converged(self, iteration, residual_norm, update_norm, x_norm, tolerance, update_tolerance, &
                                  state_scale, residual_scale, step_length, previous_residual)
    class(factor_record), intent(in) :: self
    integer, intent(in) :: iteration
    real(real64), intent(in) :: residual_norm, update_norm, x_norm, tolerance, update_tolerance
    real(real64), intent(in) :: state_scale, residual_scale, step_length
    real(real64), intent(in), optional :: previous_residual   !! the residual before the update (stagnation)

    if (.not. self%chord .or. iteration == 0) then
      converged = newton_converged(iteration, residual_norm, update_norm, x_norm, tolerance, update_tolerance, &
                                   state_scale, residual_scale, previous_residual)
    else if (.not. self%measured) then
      converged = .false.
    else
      converged = chord_converged(residual_norm, update_norm, self%update_rate, x_norm, tolerance, update_tolerance, &
                                  chord_error_limit(state_scale, step_length), residual_scale)
    end if
  end function converged

  !> A chord iterate (the update made with kept factors whose updates contract by `rate`) has
  !> converged when the error it leaves, at most rate/(1 - rate) times the update for a linear
  !> contraction, is below `error_limit`, its residual is below the tolerance or at its rounding
  !> (rounding_factor eps residual_scale), and the update meets update_tolerance |x| if that is
  !> positive (-snes_stol). A rate above largest_rate is never trusted (nor a NaN).
  pure logical function chord_converged(residual_norm, update_norm, rate, x_norm, tolerance, update_tolerance, &
                                        error_limit, residual_scale)
    real(real64), intent(in) :: residual_norm, update_norm, rate, x_norm, tolerance, update_tolerance
    real(real64), intent(in) :: error_limit, residual_scale

    chord_converged = rate <= largest_rate
    if (.not. chord_converged) return
    chord_converged = rate/(1.0_real64 - rate)*update_norm <= error_limit .and. &
                      (residual_norm <= tolerance .or. residual_norm <= rounding_factor*epsilon(1.0_real64)*residual_scale) &
                      .and. (update_tolerance <= 0.0_real64 .or. update_norm <= update_tolerance*x_norm)
  end function chord_converged

end module modified_newton
