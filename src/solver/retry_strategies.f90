!> How a time step's nonlinear system is attacked, whatever solves it: a root is accepted only if
!> the solver converged AND the root is physical (the problem's check_root, docs/formulation.md
!> section 5), and a step that fails is retried, always for the same step:
!>   1. from the caller's predictor, improved by the finder's last linearization (a chord step);
!>   2. from the old state;
!>   3. by continuation: the problem is solved for s rising to 1 (nonlinear_system's
!>      continuation parameter; for a time step, the step of s dt), each solve starting from the
!>      previous root extrapolated in s. Only the solve at s = 1 is the step.
!> If 1-3 all fail, they are tried once more with the finder's fallback (another line search):
!> strategies 4-6. Pure Fortran over an abstract root finder, so it is tested without PETSc.
module retry_strategies
  use, intrinsic :: iso_fortran_env, only: real64
  use nonlinear_problem, only: nonlinear_system
  use dense_lu, only: lu_factors
  use number_text, only: integer_text
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: root_finder, root_search, find_root
  public :: strategy_predictor, strategy_old_state, strategy_continuation, strategies_per_round
  public :: max_continuation_solves, first_continuation_fraction, smallest_continuation_increment
  public :: chord_update_limit, newton_converged, rounding_factor, final_chord_step, chord_refinement
  public :: stagnation_update, stagnation_ratio

  integer, parameter :: strategy_predictor = 1
  integer, parameter :: strategy_old_state = 2
  integer, parameter :: strategy_continuation = 3
  integer, parameter :: strategies_per_round = 3

  integer, parameter :: max_continuation_solves = 40
  real(real64), parameter :: first_continuation_fraction = 0.25_real64
  real(real64), parameter :: smallest_continuation_increment = 1.0_real64/1024

  !> A root finder may confirm a root with the LU factors it has (a final chord step instead of a
  !> new Jacobian) once the residual is below its tolerance after an update of at most this
  !> 2-norm: the chord step's error is then ~ |update| times its own update, and its iterate is
  !> accepted only by the chord test of src/solver/modified_newton (docs/integrators.md: measured,
  !> 1e-3 let the energy drift over 2000 steps of 0.01 s grow threefold, 1e-4 does not).
  real(real64), parameter :: chord_update_limit = 1.0e-4_real64

  !> Updates and residuals within rounding_factor eps of their scales are at the rounding of a
  !> root (newton_converged). At the rounding floor the measured updates are 0.1 to 0.3 eps |z|
  !> and the residuals 0.1 to 0.3 eps |z|/h; the last quadratic step before it, 80 to 900 eps |z|.
  real(real64), parameter :: rounding_factor = 16.0_real64

  !> Newton has reached its rounding floor where a Newton update of at most stagnation_update
  !> state_scale (relative: far inside quadratic convergence, whose next residual would be ~1e-16
  !> of the last) no longer lowers the residual by stagnation_ratio, and the residual is within
  !> stagnation_residual residual_scale (newton_converged). Where the floor is set by the field's
  !> terms rather than by |z| (conduction kappa Theta ~ 9e4 W where the internal energies are ~6
  !> J: docs/integrators.md, Convergence), the rounding test cannot see it; this one does, and the
  !> step check (src/run/step_check) then judges the balances. Both scales are the old state's,
  !> never the iterate's: measured against |x|, a diverging Newton (a multiplier at 2.5e28 in a
  !> stiff scene with fixed length and temperature) passed as stagnated.
  real(real64), parameter :: stagnation_update = 1.0e-8_real64
  real(real64), parameter :: stagnation_ratio = 0.5_real64
  real(real64), parameter :: stagnation_residual = 1.0e-8_real64

  !> Something that solves a nonlinear_system from an initial guess (e.g. PETSc SNES).
  type, abstract :: root_finder
  contains
    procedure(solve_interface), deferred :: solve
    procedure(refine_interface), deferred :: refine
    procedure(fallback_interface), deferred :: use_fallback
  end type root_finder

  !> What a search for a step's root did.
  type :: root_search
    logical :: accepted = .false.
    integer :: strategy = 0               !! which strategy found the root (strategy_* + 3 in the fallback round)
    integer :: newton_iterations = 0      !! over every solve
    integer :: solves = 0
    integer :: rejected_roots = 0         !! converged roots that check_root refused
    character(len=:), allocatable :: reason           !! why the search failed (if it did)
    character(len=:), allocatable :: last_rejection   !! why the last refused root was refused
  end type root_search

  abstract interface
    !> One solve from `initial`. converged: the solver met its tolerance (root physical or not);
    !> otherwise `reason` says why not. A failure only for a library error.
    subroutine solve_interface(self, problem, initial, root, converged, reason, iterations, failure)
      import :: root_finder, nonlinear_system, real64, failure_type
      class(root_finder), intent(inout) :: self
      class(nonlinear_system), intent(inout), target :: problem
      real(real64), intent(in) :: initial(:)
      real(real64), intent(out) :: root(:)
      logical, intent(out) :: converged
      character(len=:), allocatable, intent(out) :: reason
      integer, intent(out) :: iterations
      type(failure_type), intent(out) :: failure
    end subroutine solve_interface

    !> x improved with what the finder kept of its last linearization, if anything.
    subroutine refine_interface(self, problem, x)
      import :: root_finder, nonlinear_system, real64
      class(root_finder), intent(inout) :: self
      class(nonlinear_system), intent(inout) :: problem
      real(real64), intent(inout) :: x(:)
    end subroutine refine_interface

    !> Switches the finder's fallback (the other line search) on or off.
    subroutine fallback_interface(self, on, failure)
      import :: root_finder, failure_type
      class(root_finder), intent(inout) :: self
      logical, intent(in) :: on
      type(failure_type), intent(out) :: failure
    end subroutine fallback_interface
  end interface

contains

  !> Newton's convergence test, scale-aware (docs/integrators.md): converged when the residual is below
  !> the tolerance and so was the update that produced it (or the initial guess already solves the
  !> system: iteration 0), or when both are at their rounding: the update below rounding_factor eps
  !> state_scale and the residual below rounding_factor eps residual_scale, the scales of the
  !> problem's sane reference point (nonlinear_system's rounding_scales: a time step's old state,
  !> |z| and |z|/h). Quadratic convergence then leaves a residual ~ tolerance^2 or at its rounding
  !> floor, so the discrete conservation laws, exact at a root, hold to round-off. The residual of a
  !> step scales like 1/dt: the second condition lets a tight tolerance or a small dt end where
  !> rounding ends the iteration instead of failing the step. update_tolerance > 0 (PETSc's
  !> -snes_stol; 0 by default) is one more condition on the update, |dx| <= update_tolerance |x|:
  !> an option can make the test stricter, never looser. With `previous_residual` (the residual
  !> before this update), a Newton that has stagnated at its rounding floor (stagnation_update,
  !> stagnation_ratio) has converged as far as arithmetic allows, whatever the tolerance.
  pure logical function newton_converged(iteration, residual_norm, update_norm, x_norm, tolerance, update_tolerance, &
                                         state_scale, residual_scale, previous_residual)
    integer, intent(in) :: iteration
    real(real64), intent(in) :: residual_norm, update_norm, x_norm, tolerance, update_tolerance
    real(real64), intent(in) :: state_scale, residual_scale
    real(real64), intent(in), optional :: previous_residual

    if (iteration == 0) then
      ! An initial guess is accepted only if it solves the system exactly: below the tolerance
      ! alone it leaves an error ~ tolerance in the step that no Newton update has squared, which
      ! shows in the invariants (J_z drifted 5.7e-12 J s over 2e5 steps of 3e-4 s at newton_tol =
      ! 1e-12 with 30 % of the steps accepted at their predictor; 1e-13 with an update each).
      newton_converged = residual_norm <= 0.0_real64      ! a norm: exactly 0
      return
    end if
    newton_converged = residual_norm <= tolerance .and. update_norm <= tolerance .and. &
                       (update_tolerance <= 0.0_real64 .or. update_norm <= update_tolerance*x_norm)
    newton_converged = newton_converged .or. &
                       (update_norm <= rounding_factor*epsilon(1.0_real64)*state_scale .and. &
                        residual_norm <= rounding_factor*epsilon(1.0_real64)*residual_scale)
    if (newton_converged .or. .not. present(previous_residual)) return
    newton_converged = iteration >= 2 .and. update_norm <= stagnation_update*state_scale .and. &
                       residual_norm >= stagnation_ratio*previous_residual .and. &
                       residual_norm <= stagnation_residual*residual_scale
  end function newton_converged

  !> Whether a Newton iteration may confirm the root with the factors at hand instead of a new
  !> Jacobian (the final chord step): the residual is below the tolerance after an update of at
  !> most chord_update_limit, and the last iteration was not already such a step.
  pure logical function final_chord_step(enabled, factors_ready, chord_taken, residual_norm, tolerance, update_norm)
    logical, intent(in) :: enabled, factors_ready, chord_taken
    real(real64), intent(in) :: residual_norm, tolerance, update_norm

    final_chord_step = enabled .and. factors_ready .and. .not. chord_taken .and. residual_norm <= tolerance .and. &
                       update_norm <= chord_update_limit
  end function final_chord_step

  !> The chord step x - J_old^-1 R(x) with the last Jacobian's LU factors (from the last solve):
  !> a residual and a back-substitution instead of a Newton iteration, which saves about one
  !> iteration per step (docs/performance.md). Both Newton loops (src/solver/snes_solver and
  !> src/solver/hand_newton) refine their predictor with it; nothing happens without factors.
  subroutine chord_refinement(lu, problem, x)
    type(lu_factors), intent(in) :: lu
    class(nonlinear_system), intent(inout) :: problem
    real(real64), intent(inout) :: x(:)
    real(real64) :: residual(size(x))
    integer :: stat, info

    if (.not. lu%ready) return
    ! The residual as the solver's callbacks evaluate it: a kernel that keeps its last pass
    ! (pendulum_step_kernel) then evaluates it in that pass's storage instead of in a new,
    ! default-initialized one.
    call problem%evaluate_residual(x, residual, stat)
    if (stat /= 0) return
    call lu%solve(residual, info)
    if (info == 0) x = x - residual
  end subroutine chord_refinement

  !> Searches the root of `problem` (at s = 1) by the strategies above. `predictor` is the
  !> caller's guess; `start` is the old state (a root at s -> 0), both of the problem's size.
  !> A failure only for a library error; a search that fails is reported in `search`.
  subroutine find_root(finder, problem, start, predictor, root, search, failure, continue_in_s)
    class(root_finder), intent(inout) :: finder
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: start(:), predictor(:)
    real(real64), intent(out) :: root(:)
    type(root_search), intent(out) :: search
    type(failure_type), intent(out) :: failure
    logical, intent(in), optional :: continue_in_s    !! .false.: no continuation (strategies 3, 6)
    type(failure_type) :: fallback_failure
    integer :: offset
    logical :: continuing

    continuing = .true.
    if (present(continue_in_s)) continuing = continue_in_s

    ! The reason comes from the first attempt (attempt moves its solve's reason in).
    search%last_rejection = ''
    offset = 0
    call strategies()
    if (search%accepted .or. failure%failed()) return
    call finder%use_fallback(.true., failure)
    if (failure%failed()) return
    offset = strategies_per_round
    call strategies()
    call finder%use_fallback(.false., fallback_failure)
    if (.not. failure%failed()) failure = fallback_failure
    call problem%set_continuation(1.0_real64)

  contains

    ! Predictor, old state, continuation; search%strategy is offset + the one that worked.
    subroutine strategies()
      real(real64) :: guess(size(predictor))

      guess = predictor
      call problem%set_continuation(1.0_real64)
      call finder%refine(problem, guess)
      call attempt(guess, 1.0_real64, offset + strategy_predictor)
      if (search%accepted .or. failure%failed()) return
      if (maxval(abs(start - predictor)) > 0.0_real64) then
        call attempt(start, 1.0_real64, offset + strategy_old_state)
        if (search%accepted .or. failure%failed()) return
      end if
      if (continuing) then
        call continuation()
      else
        search%reason = 'no root from the predictor or from the old state (last: '//search%reason//')'
      end if
      call problem%set_continuation(1.0_real64)
    end subroutine strategies

    ! One solve at s = fraction from `initial`; accepted if it converged to a physical root.
    subroutine attempt(initial, fraction, strategy)
      real(real64), intent(in) :: initial(:), fraction
      integer, intent(in) :: strategy
      logical :: ok
      character(len=:), allocatable :: why

      call solve_once(initial, fraction, ok, why)
      if (failure%failed()) then
        if (.not. allocated(search%reason)) search%reason = ''
        return
      end if
      ! Moved, not copied (why is '' when ok): no allocation more than the solve's.
      call move_alloc(why, search%reason)
      if (.not. allocated(search%reason)) search%reason = ''
      if (ok) then
        search%accepted = .true.
        search%strategy = strategy
      end if
    end subroutine attempt

    ! Continuation in s from 0 to 1 with adaptive increments.
    subroutine continuation()
      real(real64) :: s_done, s_try, increment, path_root(size(start)), trial(size(start))
      character(len=:), allocatable :: last_failure, why
      logical :: ok
      integer :: stage

      s_done = 0.0_real64
      increment = first_continuation_fraction
      path_root = start
      last_failure = 'more than '//integer_text(max_continuation_solves)//' continuation solves needed'
      do stage = 1, max_continuation_solves
        s_try = min(1.0_real64, s_done + increment)
        ! Linear extrapolation in s along the path of roots, which starts at the old state (s = 0).
        if (s_done > 0.0_real64) then
          trial = path_root + (s_try - s_done)/s_done*(path_root - start)
        else
          trial = path_root
        end if
        call solve_once(trial, s_try, ok, why)
        if (failure%failed()) return
        if (ok) then
          if (s_try >= 1.0_real64) then
            search%accepted = .true.
            search%strategy = offset + strategy_continuation
            search%reason = ''
            return
          end if
          s_done = s_try
          path_root = root
          increment = 2*increment
        else
          last_failure = why
          increment = increment/2
          if (increment < smallest_continuation_increment) exit
        end if
      end do
      search%reason = 'no root from the predictor, from the old state, or by continuation in dt (last: ' &
                      //last_failure//')'
    end subroutine continuation

    ! One solve at s from `initial`, counted; ok = converged to a physical root.
    subroutine solve_once(initial, s, ok, why)
      real(real64), intent(in) :: initial(:), s
      logical, intent(out) :: ok
      character(len=:), allocatable, intent(out) :: why
      character(len=:), allocatable :: physics
      logical :: converged
      integer :: iterations

      ok = .false.
      call problem%set_continuation(s)
      call finder%solve(problem, initial, root, converged, why, iterations, failure)
      if (failure%failed()) return
      search%newton_iterations = search%newton_iterations + iterations
      search%solves = search%solves + 1
      if (.not. converged) return
      call problem%check_root(root, physics)
      if (len(physics) > 0) then
        search%rejected_roots = search%rejected_roots + 1
        why = 'root rejected: '//physics
        search%last_rejection = why
        return
      end if
      why = ''
      ok = .true.
    end subroutine solve_once
  end subroutine find_root

end module retry_strategies
