!> Newton's method by hand on a nonlinear_system, with the small dense LU (src/solver/dense_lu) and no
!> PETSc: the same iteration as the lean SNES path (src/solver/snes_solver) -- full steps, the
!> modified Newton's choice between kept and new factors (src/solver/modified_newton; or, without
!> it, a new Jacobian and LU per iteration except the final chord step), the same convergence
!> test. newton_iterate is that iteration on LU factors the caller owns: the SNES solver runs its
!> solves through it where nothing needs SNESSolve (snes_solver's direct way), and newton_loop, a
!> root finder of its own with its own factors, serves the benchmark's floor (drivers/eme_bench)
!> and the tests that check that SNES adds nothing to the iteration.
module hand_newton
  use, intrinsic :: iso_fortran_env, only: real64
  use nonlinear_problem, only: nonlinear_system
  use retry_strategies, only: root_finder, final_chord_step, chord_refinement
  use dense_lu, only: lu_factors
  use euclidean_norm, only: two_norm
  use modified_newton, only: factor_record
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: newton_loop, newton_settings, newton_outcome, newton_iterate
  public :: ending_converged, ending_iterations, ending_step_domain, ending_other

  !> How newton_iterate ended: converged; at the iteration limit; a full step (a Newton step, or a
  !> chord step taken again as one) whose residual lies outside the domain, which the lean SNES's
  !> shell line search reports as its failure; anything else (the start outside the domain, a
  !> Jacobian outside it or a zero pivot at an iteration's start, a residual norm not finite).
  integer, parameter :: ending_converged = 0, ending_iterations = 1, ending_step_domain = 2, ending_other = 3

  !> What one run of the iteration is told: the convergence test's tolerances (retry_strategies'
  !> newton_converged: update_tolerance > 0 adds |dx| <= update_tolerance |x|), the iteration
  !> limit, and the switches of the factors' reuse.
  type :: newton_settings
    real(real64) :: tolerance = 1.0e-8_real64
    real(real64) :: update_tolerance = 0.0_real64
    integer :: max_iterations = 50
    logical :: modified_newton = .true.     !! keep the factors while they contract (modified_newton)
    logical :: final_chord = .true.         !! without it: confirm a root with the factors at hand
  end type newton_settings

  !> What one run of the iteration did.
  type :: newton_outcome
    logical :: converged = .false.
    integer :: ending = ending_other
    integer :: iterations = 0                          !! begun (with a failed step: the completed ones + 1)
    integer :: factorizations = 0
    real(real64) :: residual_norm = huge(1.0_real64)   !! at the last iterate accepted (as SNES's function norm)
  end type newton_outcome

  !> The loop's tolerance, iteration limit, switches and LU factors with their record.
  type, extends(root_finder) :: newton_loop
    type(lu_factors) :: lu
    type(factor_record) :: reuse
    real(real64) :: tolerance = 1.0e-8_real64
    integer :: max_iterations = 50
    logical :: chord_predictor = .true.
    logical :: final_chord = .true.
    logical :: modified_newton = .true.     !! as the SNES solver's -eme_modified_newton
    logical :: fallback = .false.           !! the retry strategies' second round (SNES: another line search)
  contains
    procedure :: prepare
    procedure :: solve
    procedure :: refine
    procedure :: use_fallback
  end type newton_loop

contains

  !> Room for n unknowns, tolerance on the residual's 2-norm, at most max_iterations per solve.
  subroutine prepare(self, n, tolerance, max_iterations)
    class(newton_loop), intent(inout) :: self
    integer, intent(in) :: n
    real(real64), intent(in) :: tolerance
    integer, intent(in) :: max_iterations

    call self%lu%reset(n)
    self%tolerance = tolerance
    self%max_iterations = max_iterations
  end subroutine prepare

  !> Newton from `initial` until the convergence test says so (newton_iterate).
  subroutine solve(self, problem, initial, root, converged, reason, iterations, failure)
    class(newton_loop), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations
    type(failure_type), intent(out) :: failure
    type(newton_outcome) :: outcome

    call newton_iterate(problem, initial, newton_settings(tolerance=self%tolerance, max_iterations=self%max_iterations, &
                                                          modified_newton=self%modified_newton .and. .not. self%fallback, &
                                                          final_chord=self%final_chord), &
                        self%lu, self%reuse, root, outcome)
    converged = outcome%converged
    iterations = outcome%iterations
    reason = 'Newton did not converge'
    if (converged) reason = ''
  end subroutine solve

  !> Newton's iteration on `problem` from `initial`, with the LU factors `lu` and their record
  !> `reuse` (both the caller's: on return they hold the last factors, as the lean SNES's shell
  !> leaves them), exactly as the lean SNES way takes it (src/solver/snes_shell: the residual at
  !> the start, then per iteration new factors or the kept ones, the full step, its residual and
  !> the modified Newton's convergence test), until the test accepts an iterate or the
  !> iteration fails: max_iterations reached, a residual or Jacobian outside the domain (a chord
  !> step outside it is taken again as a Newton step from the same iterate), a zero pivot or a
  !> residual norm that is not finite. Unconverged, `root` is the last iterate.
  subroutine newton_iterate(problem, initial, settings, lu, reuse, root, outcome)
    class(nonlinear_system), intent(inout) :: problem
    real(real64), intent(in) :: initial(:)
    type(newton_settings), intent(in) :: settings
    type(lu_factors), intent(inout) :: lu
    type(factor_record), intent(inout) :: reuse
    real(real64), intent(out) :: root(:)
    type(newton_outcome), intent(out) :: outcome
    real(real64) :: residual(size(initial)), update(size(initial)), trial(size(initial)), trial_residual(size(initial))
    real(real64) :: residual_norm, previous_residual, update_norm, state_scale, residual_scale, step_length
    integer :: info, stat
    logical :: chord_taken, refactor, retrying

    root = initial
    chord_taken = .false.
    update_norm = huge(1.0_real64)
    call problem%evaluate_residual(root, residual, stat)
    if (stat /= 0) return
    residual_norm = two_norm(residual)
    outcome%residual_norm = residual_norm
    if (.not. (residual_norm <= huge(1.0_real64))) return
    call problem%rounding_scales(state_scale, residual_scale)
    step_length = problem%step_length()
    reuse%enabled = settings%modified_newton .and. state_scale > 0.0_real64 .and. step_length > 0.0_real64
    call reuse%begin_solve()
    outcome%converged = reuse%converged(0, residual_norm, update_norm, two_norm(root), settings%tolerance, &
                                        settings%update_tolerance, state_scale, residual_scale, step_length)
    do while (.not. outcome%converged .and. outcome%iterations < settings%max_iterations)
      outcome%iterations = outcome%iterations + 1
      if (reuse%enabled) then
        refactor = reuse%must_factor(lu%ready, residual_norm, state_scale, step_length)
      else
        chord_taken = final_chord_step(settings%final_chord, lu%ready, chord_taken, residual_norm, settings%tolerance, &
                                       update_norm)
        refactor = .not. chord_taken
      end if
      retrying = .false.
      do
        if (refactor) then
          call problem%evaluate_jacobian(root, lu%factors, stat)
          lu%ready = .false.
          info = 0
          if (stat == 0) then
            call lu%factor_in_place(info)
            outcome%factorizations = outcome%factorizations + 1
          end if
          if (stat /= 0 .or. info /= 0) then
            ! In the shell: the retried step's line search fails; at the iteration's start the PC.
            if (retrying) outcome%ending = ending_step_domain
            return
          end if
          call reuse%factored()
        else
          call reuse%kept()
        end if
        update = residual
        call lu%solve(update, info)
        if (info /= 0 .and. .not. retrying) return
        trial = root - update
        call problem%evaluate_residual(trial, trial_residual, stat)
        if (stat == 0) exit
        ! A chord step outside the domain is taken again as a Newton step from the same iterate.
        if (refactor .or. .not. reuse%enabled) then
          outcome%ending = ending_step_domain
          return
        end if
        refactor = .true.
        retrying = .true.
      end do
      root = trial
      residual = trial_residual
      update_norm = two_norm(update)
      call reuse%updated(update_norm, residual_norm)
      previous_residual = residual_norm
      residual_norm = two_norm(residual)
      outcome%residual_norm = residual_norm
      if (.not. (residual_norm <= huge(1.0_real64))) return
      outcome%converged = reuse%converged(outcome%iterations, residual_norm, update_norm, two_norm(root), &
                                          settings%tolerance, settings%update_tolerance, state_scale, residual_scale, &
                                          step_length, previous_residual)
    end do
    outcome%ending = merge(ending_converged, ending_iterations, outcome%converged)
  end subroutine newton_iterate

  !> The chord refinement of a predictor with the last factors, as the SNES solver's.
  subroutine refine(self, problem, x)
    class(newton_loop), intent(inout) :: self
    class(nonlinear_system), intent(inout) :: problem
    real(real64), intent(inout) :: x(:)

    if (self%chord_predictor) call chord_refinement(self%lu, problem, x)
  end subroutine refine

  !> The loop has no other line search: the fallback round repeats the first, with a new Jacobian
  !> every iteration as the SNES solver's (whose fallback line search is PETSc's).
  subroutine use_fallback(self, on, failure)
    class(newton_loop), intent(inout) :: self
    logical, intent(in) :: on
    type(failure_type), intent(out) :: failure

    self%fallback = on
  end subroutine use_fallback

end module hand_newton
