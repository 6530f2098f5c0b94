!> Newton's method by hand on a nonlinear_system, with the small dense LU (src/solver/dense_lu) and no
!> PETSc: the same iteration as the lean SNES path (src/solver/snes_solver) -- full steps, the
!> modified Newton's choice between kept and new factors (src/solver/modified_newton; or, without
!> it, a new Jacobian and LU per iteration except the final chord step), the same convergence
!> test -- for the benchmark's floor (drivers/eme_bench) and the tests that check that SNES adds
!> nothing to the iteration.
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
  public :: newton_loop

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

  !> Newton from `initial` until the convergence test says so (modified_newton's, which is
  !> retry_strategies' newton_converged after every Newton update).
  subroutine solve(self, problem, initial, root, converged, reason, iterations, failure)
    class(newton_loop), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations
    type(failure_type), intent(out) :: failure
    real(real64) :: residual(size(initial)), update(size(initial)), trial(size(initial)), trial_residual(size(initial))
    real(real64) :: residual_norm, previous_residual, update_norm, state_scale, residual_scale, step_length
    integer :: info, stat
    logical :: chord_taken, refactor

    iterations = 0
    reason = 'Newton did not converge'
    root = initial
    converged = .false.
    chord_taken = .false.
    update_norm = huge(1.0_real64)
    call problem%evaluate_residual(root, residual, stat)
    if (stat /= 0) return
    residual_norm = two_norm(residual)
    call problem%rounding_scales(state_scale, residual_scale)
    step_length = problem%step_length()
    self%reuse%enabled = self%modified_newton .and. .not. self%fallback .and. state_scale > 0.0_real64 .and. &
                         step_length > 0.0_real64
    call self%reuse%begin_solve()
    converged = self%reuse%converged(0, residual_norm, update_norm, two_norm(root), self%tolerance, 0.0_real64, &
                                     state_scale, residual_scale, step_length)
    do while (.not. converged .and. iterations < self%max_iterations)
      iterations = iterations + 1
      if (self%reuse%enabled) then
        refactor = self%reuse%must_factor(self%lu%ready, residual_norm, state_scale, step_length)
      else
        chord_taken = final_chord_step(self%final_chord, self%lu%ready, chord_taken, residual_norm, self%tolerance, &
                                       update_norm)
        refactor = .not. chord_taken
      end if
      do
        if (refactor) then
          call problem%evaluate_jacobian(root, self%lu%factors, stat)
          self%lu%ready = .false.
          if (stat /= 0) return
          call self%lu%factor_in_place(info)
          if (info /= 0) return
          call self%reuse%factored()
        else
          call self%reuse%kept()
        end if
        update = residual
        call self%lu%solve(update, info)
        trial = root - update
        call problem%evaluate_residual(trial, trial_residual, stat)
        if (stat == 0) exit
        ! A chord step outside the domain is taken again as a Newton step from the same iterate.
        if (refactor .or. .not. self%reuse%enabled) return
        refactor = .true.
      end do
      root = trial
      residual = trial_residual
      update_norm = two_norm(update)
      call self%reuse%updated(update_norm, residual_norm)
      previous_residual = residual_norm
      residual_norm = two_norm(residual)
      converged = self%reuse%converged(iterations, residual_norm, update_norm, two_norm(root), self%tolerance, &
                                       0.0_real64, state_scale, residual_scale, step_length, previous_residual)
    end do
    if (converged) reason = ''
  end subroutine solve

  !> The chord refinement of a predictor with the last factors, as the SNES solver's.
  subroutine refine(self, problem, x)
    class(newton_loop), intent(inout) :: self
    class(nonlinear_system), intent(in) :: problem
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
