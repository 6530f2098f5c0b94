!> PETSc SNES solver for one time step of a step_problem (src/scheme/step_residual).
!> One SNES, vector pair and dense matrix are created per run and reused for every step;
!> the linear solves are LU (KSPPREONLY + PCLU). SNESSetFromOptions comes last, so
!> -snes_monitor, -snes_converged_reason, -snes_test_jacobian, ... work from the command line.
!>
!> A step is accepted only if SNES converged AND the root is physical (FORMULATION section 5):
!> positive temperatures at z' and positive scheme temperatures. Newton at large dt is hard,
!> so a step that fails is retried, always for the same dt:
!>   1. from the caller's predictor,  2. from the old state,
!>   3. by continuation in the step size: the step equation is solved for dt_s = s dt with
!>      s increasing to 1, each solve starting from the previous root extrapolated in s.
!>      Only the final solve, at s = 1, is the step; the others only provide initial guesses.
!> Newton takes full steps (line search 'basic') by default: the residual's rows carry
!> different units, and backtracking on its 2-norm can stall where full steps converge. If
!> 1-3 all fail, they are tried once more with backtracking ('bt'), or with full steps if the
!> command line chose 'bt': strategies 4-6.
module step_solver
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use, intrinsic :: iso_fortran_env, only: real64
  use step_residual, only: step_problem
  use time_stepper, only: stepper, step_report
  use lapack_lu, only: dgetf2, dgetrs
  use number_text, only: integer_text
  implicit none
  private
  public :: snes_solver

  integer, parameter :: strategy_predictor = 1
  integer, parameter :: strategy_old_state = 2
  integer, parameter :: strategy_continuation = 3
  integer, parameter :: strategies_per_line_search = 3


  !> LU factors of the step's Jacobian for the shell preconditioner. PETSc's dense LU calls
  !> LAPACK's blocked dgetrf, whose recursion costs twice the unblocked dgetf2 on 15 x 15 (the
  !> benchmark, README); the shell factors with dgetf2 and solves with dgetrs.
  type :: dense_lu
    real(real64), allocatable :: factors(:, :)
    integer, allocatable :: pivots(:)
    logical :: ready = .false.     !! factors of some earlier Jacobian are available
  end type dense_lu

  ! PETSc needs these interfaces to pass a Fortran derived type as a shell's context.
  interface
    subroutine PCShellSetContext(pc, context, ierr)
      import :: tPC, dense_lu
      PC, intent(in) :: pc
      type(dense_lu), intent(in) :: context
      PetscErrorCode, intent(out) :: ierr
    end subroutine PCShellSetContext
    subroutine PCShellGetContext(pc, context, ierr)
      import :: tPC, dense_lu
      PC, intent(in) :: pc
      type(dense_lu), pointer, intent(out) :: context
      PetscErrorCode, intent(out) :: ierr
    end subroutine PCShellGetContext
  end interface

  !> The PETSc objects of one run and the problem their callbacks see. Do not copy it after
  !> `create`: PETSc holds the address of `problem`.
  type, extends(stepper) :: snes_solver
    type(step_problem) :: problem
    type(dense_lu) :: lu
    SNES :: snes
    Vec :: x
    Vec :: r
    Mat :: jacobian
    integer :: n = 0
    real(real64) :: newton_tol = 0.0_real64
    integer :: max_iterations = 0
    logical :: created = .false.
    character(len=16) :: line_search = ''           !! the primary line search type
    character(len=16) :: fallback_line_search = ''  !! tried when every strategy failed with it
    logical :: chord_predictor = .true.             !! -eme_chord_predictor false switches it off
  contains
    procedure :: create
    procedure :: prepare
    procedure :: destroy
    procedure :: solve_step
    procedure :: advance
  end type snes_solver

  integer, parameter :: max_continuation_solves = 40
  real(real64), parameter :: first_continuation_fraction = 0.25_real64
  real(real64), parameter :: smallest_continuation_increment = 1.0_real64/1024

contains

  !> Creates the SNES for `problem` (copied into the solver) with absolute tolerance newton_tol
  !> on the 2-norm of the residual and at most max_iterations Newton iterations per solve.
  subroutine create(self, problem, newton_tol, max_iterations, ierr)
    class(snes_solver), intent(inout), target :: self
    type(step_problem), intent(in) :: problem
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    KSP :: ksp
    PC :: pc
    SNESLineSearch :: line_search
    PetscInt :: n, max_evaluations
    PetscBool :: found

    self%problem = problem
    self%n = problem%unknowns()
    self%newton_tol = newton_tol
    self%max_iterations = max_iterations
    self%created = .true.
    n = self%n
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, n, self%x, ierr))
    PetscCall(VecDuplicate(self%x, self%r, ierr))
    PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, n, n, PETSC_NULL_SCALAR, self%jacobian, ierr))
    PetscCall(SNESCreate(PETSC_COMM_SELF, self%snes, ierr))
    PetscCall(SNESSetFunction(self%snes, self%r, form_residual, self%problem, ierr))
    PetscCall(SNESSetJacobian(self%snes, self%jacobian, self%jacobian, form_jacobian, self%problem, ierr))
    PetscCall(SNESGetKSP(self%snes, ksp, ierr))
    PetscCall(KSPSetType(ksp, KSPPREONLY, ierr))
    PetscCall(KSPGetPC(ksp, pc, ierr))
    allocate (self%lu%factors(n, n), self%lu%pivots(n))
    self%lu%ready = .false.
    PetscCall(PCSetType(pc, PCSHELL, ierr))
    PetscCall(PCShellSetContext(pc, self%lu, ierr))
    PetscCall(PCShellSetSetUp(pc, factor_jacobian, ierr))
    PetscCall(PCShellSetApply(pc, solve_factored, ierr))
    PetscCall(PCShellSetName(pc, 'dense LU by LAPACK dgetf2 and dgetrs', ierr))
    max_evaluations = 10000
    PetscCall(SNESSetTolerances(self%snes, newton_tol, 0.0_real64, 0.0_real64, int(max_iterations, kind(n)), max_evaluations, ierr))
    PetscCall(SNESSetConvergenceTest(self%snes, converged_on_update, 0, PETSC_NULL_FUNCTION, ierr))
    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    PetscCall(SNESLineSearchSetType(line_search, SNESLINESEARCHBASIC, ierr))
    PetscCall(SNESSetFromOptions(self%snes, ierr))
    PetscCall(SNESLineSearchGetType(line_search, self%line_search, ierr))
    self%chord_predictor = .true.
    PetscCall(PetscOptionsGetBool(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-eme_chord_predictor', self%chord_predictor, found, ierr))
    if (self%line_search == SNESLINESEARCHBT) then
      self%fallback_line_search = SNESLINESEARCHBASIC
    else
      self%fallback_line_search = SNESLINESEARCHBT
    end if
  end subroutine create

  !> Makes the solver ready for `problem`: reuses the PETSc objects of an earlier run when the
  !> number of unknowns is the same (an ensemble rank runs many cases), and creates them
  !> otherwise. Changed tolerances are applied; options from the command line are kept.
  subroutine prepare(self, problem, newton_tol, max_iterations, ierr)
    class(snes_solver), intent(inout), target :: self
    type(step_problem), intent(in) :: problem
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: iterations

    ierr = 0
    if (self%created .and. self%n == problem%unknowns()) then
      self%problem = problem
      self%lu%ready = .false.    ! the chord predictor must not use another problem's Jacobian
      if (abs(newton_tol - self%newton_tol) > 0.0_real64 .or. max_iterations /= self%max_iterations) then
        iterations = max_iterations
        PetscCall(SNESSetTolerances(self%snes, newton_tol, PETSC_DEFAULT_REAL, PETSC_DEFAULT_REAL, iterations, PETSC_DEFAULT_INTEGER, ierr))
        self%newton_tol = newton_tol
        self%max_iterations = max_iterations
      end if
      return
    end if
    if (self%created) then
      PetscCall(self%destroy(ierr))
    end if
    PetscCall(self%create(problem, newton_tol, max_iterations, ierr))
  end subroutine prepare

  !> Frees the PETSc objects.
  subroutine destroy(self, ierr)
    class(snes_solver), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    self%created = .false.
    self%lu%ready = .false.
    if (allocated(self%lu%factors)) deallocate (self%lu%factors, self%lu%pivots)
    PetscCall(SNESDestroy(self%snes, ierr))
    PetscCall(MatDestroy(self%jacobian, ierr))
    PetscCall(VecDestroy(self%r, ierr))
    PetscCall(VecDestroy(self%x, ierr))
  end subroutine destroy

  !> Solves the step from z_old with step size dt. `guess` is the caller's predictor; on
  !> acceptance x_new holds the root (state and any multipliers).
  subroutine solve_step(self, z_old, dt, guess, x_new, report, ierr)
    class(snes_solver), intent(inout) :: self
    real(real64), intent(in) :: z_old(:), dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    PetscErrorCode, intent(out) :: ierr
    real(real64) :: start(self%n)
    character(len=:), allocatable :: why
    SNESLineSearch :: line_search
    integer :: offset

    ierr = 0
    self%problem%z_old = z_old
    report%reason = ''
    report%last_rejection = ''
    start = guess
    start(1:size(z_old)) = z_old
    offset = 0
    call strategies()
    if (report%accepted .or. ierr /= 0) return
    ! Every strategy failed with the primary line search: once more with the other one.
    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    PetscCall(SNESLineSearchSetType(line_search, self%fallback_line_search, ierr))
    offset = strategies_per_line_search
    call strategies()
    PetscCall(SNESLineSearchSetType(line_search, self%line_search, ierr))
    self%problem%dt = dt

  contains

    ! Predictor, old state, continuation in dt; report%strategy is offset + which one worked.
    subroutine strategies()
      call attempt(refined(guess), 1.0_real64, offset + strategy_predictor)
      if (report%accepted .or. ierr /= 0) return
      if (maxval(abs(start - guess)) > 0.0_real64) then
        call attempt(start, 1.0_real64, offset + strategy_old_state)
        if (report%accepted .or. ierr /= 0) return
      end if
      call continuation(start)
      self%problem%dt = dt
    end subroutine strategies

    ! The predictor improved by one chord step with the last Jacobian's LU factors (from the
    ! previous step): x - J_old^-1 R(x). It costs a residual and a back-substitution, not a
    ! SNES iteration, and saves about one of those per step (README, per-step cost).
    function refined(x) result(better)
      real(real64), intent(in) :: x(:)
      real(real64) :: better(size(x)), residual(size(x))
      integer :: stat, info

      better = x
      if (.not. (self%lu%ready .and. self%chord_predictor)) return
      self%problem%dt = dt
      call self%problem%evaluate(x, residual, stat=stat)
      if (stat /= 0) return
      call dgetrs('N', self%n, 1, self%lu%factors, self%n, self%lu%pivots, residual, self%n, info)
      if (info == 0) better = x - residual
    end function refined

    ! One SNES solve of the step with step size fraction*dt from `initial`.
    subroutine attempt(initial, fraction, strategy)
      real(real64), intent(in) :: initial(:), fraction
      integer, intent(in) :: strategy
      logical :: ok

      call solve_once(self, initial, fraction*dt, x_new, report, ok, why, ierr)
      if (ierr /= 0) return
      if (ok) then
        report%accepted = .true.
        report%strategy = strategy
        report%reason = ''
      else
        report%reason = why
      end if
    end subroutine attempt

    ! Continuation in s from 0 to 1 with adaptive increments.
    subroutine continuation(initial)
      real(real64), intent(in) :: initial(:)
      real(real64) :: s_done, s_try, increment, root(self%n), trial(self%n)
      character(len=:), allocatable :: last_failure
      logical :: ok
      integer :: stage

      s_done = 0.0_real64
      increment = first_continuation_fraction
      root = initial
      last_failure = 'more than '//integer_text(max_continuation_solves)//' continuation solves needed'
      do stage = 1, max_continuation_solves
        s_try = min(1.0_real64, s_done + increment)
        ! Linear extrapolation in s along the path of roots, which starts at the old state (s = 0).
        if (s_done > 0.0_real64) then
          trial = root + (s_try - s_done)/s_done*(root - initial)
        else
          trial = root
        end if
        call solve_once(self, trial, s_try*dt, x_new, report, ok, why, ierr)
        if (ierr /= 0) return
        if (ok) then
          if (s_try >= 1.0_real64) then
            report%accepted = .true.
            report%strategy = offset + strategy_continuation
            report%reason = ''
            return
          end if
          s_done = s_try
          root = x_new
          increment = 2*increment
        else
          last_failure = why
          increment = increment/2
          if (increment < smallest_continuation_increment) exit
        end if
      end do
      report%reason = 'no root from the predictor, from the old state, or by continuation in dt (last: ' &
                      //last_failure//')'
    end subroutine continuation
  end subroutine solve_step

  !> The stepper interface: one step of the scheme, then the temperatures its K0 used.
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, ierr)
    class(snes_solver), intent(inout) :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    integer, intent(out) :: ierr
    integer :: stat

    call self%solve_step(x_old(1:size(self%problem%z_old)), dt, guess, x_new, report, ierr)
    if (ierr /= 0 .or. .not. report%accepted) return
    call self%problem%scheme_temperatures(x_new, report%scheme_temperature, stat)
    if (stat /= 0) then    ! check_root has accepted the root, so this does not happen
      report%accepted = .false.
      report%reason = 'the scheme temperatures of the root are undefined'
    end if
  end subroutine advance

  ! One SNESSolve for step size dt from `initial`; ok = converged to a physical root.
  subroutine solve_once(self, initial, dt, root, report, ok, why, ierr)
    class(snes_solver), intent(inout) :: self
    real(real64), intent(in) :: initial(:), dt
    real(real64), intent(out) :: root(:)
    type(step_report), intent(inout) :: report
    logical, intent(out) :: ok
    character(len=:), allocatable, intent(out) :: why
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: values(:)
    SNESConvergedReason :: converged
    PetscInt :: iterations
    character(len=80) :: reason_text
    character(len=:), allocatable :: physics

    ok = .false.
    why = ''
    self%problem%dt = dt
    PetscCall(VecGetArrayF90(self%x, values, ierr))
    values = initial
    PetscCall(VecRestoreArrayF90(self%x, values, ierr))
    PetscCall(SNESSolve(self%snes, PETSC_NULL_VEC, self%x, ierr))
    PetscCall(SNESGetConvergedReason(self%snes, converged, ierr))
    PetscCall(SNESGetIterationNumber(self%snes, iterations, ierr))
    report%newton_iterations = report%newton_iterations + iterations
    report%solves = report%solves + 1
    PetscCall(VecGetArrayReadF90(self%x, values, ierr))
    root = values
    PetscCall(VecRestoreArrayReadF90(self%x, values, ierr))
    if (converged <= 0) then
      if (.not. at_rounding_floor()) then
        PetscCall(SNESGetConvergedReasonString(self%snes, reason_text, ierr))
        why = 'Newton did not converge: '//trim(reason_text)
        return
      end if
    end if
    call self%problem%check_root(root, physics)
    if (len(physics) > 0) then
      report%rejected_roots = report%rejected_roots + 1
      why = 'root rejected: '//physics
      report%last_rejection = why
      return
    end if
    ok = .true.

  contains

    ! The line search failed on a residual already below the tolerance: the residual sits at
    ! its rounding floor and cannot decrease further, so the iterate is a root to round-off.
    logical function at_rounding_floor()
      PetscReal :: residual_norm, atol, rtol, stol
      PetscInt :: max_iterations, max_evaluations
      PetscErrorCode :: ierr

      at_rounding_floor = .false.
      if (converged /= SNES_DIVERGED_LINE_SEARCH) return
      PetscCall(SNESGetFunctionNorm(self%snes, residual_norm, ierr))
      PetscCall(SNESGetTolerances(self%snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
      at_rounding_floor = residual_norm <= atol
    end function at_rounding_floor
  end subroutine solve_once

  ! SNES convergence test. Converged when the residual is below the absolute tolerance and so
  ! was the Newton update that produced it (or the initial guess already solves the step).
  ! Newton's quadratic convergence then leaves a residual ~ tolerance^2, so the discrete
  ! conservation laws, which hold exactly at a root, hold to round-off rather than to the
  ! tolerance. -snes_atol changes the tolerance; -snes_stol > 0 adds PETSc's relative update test.
  subroutine converged_on_update(snes, iteration, x_norm, update_norm, residual_norm, reason, context, ierr)
    SNES, intent(in) :: snes
    PetscInt, intent(in) :: iteration
    PetscReal, intent(in) :: x_norm, update_norm, residual_norm
    SNESConvergedReason, intent(out) :: reason
    PetscInt, intent(in) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscReal :: atol, rtol, stol
    PetscInt :: max_iterations, max_evaluations

    PetscCall(SNESGetTolerances(snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
    if (.not. (residual_norm <= huge(residual_norm))) then
      reason = SNES_DIVERGED_FNORM_NAN
    else if (residual_norm <= atol .and. (iteration == 0 .or. update_norm <= max(atol, stol*x_norm))) then
      reason = SNES_CONVERGED_FNORM_ABS
    else
      reason = SNES_CONVERGED_ITERATING
    end if
  end subroutine converged_on_update

  ! Shell preconditioner set-up: factor the new Jacobian. A zero pivot fails the linear solve,
  ! which fails the Newton solve, which the step's strategies handle.
  subroutine factor_jacobian(pc, ierr)
    PC, intent(in) :: pc
    PetscErrorCode, intent(out) :: ierr
    type(dense_lu), pointer :: lu
    Mat :: operator, preconditioner
    PetscScalar, pointer :: entries(:, :)
    integer :: info

    PetscCall(PCShellGetContext(pc, lu, ierr))
    PetscCall(PCGetOperators(pc, operator, preconditioner, ierr))
    PetscCall(MatDenseGetArrayF90(preconditioner, entries, ierr))
    lu%factors = entries
    PetscCall(MatDenseRestoreArrayF90(preconditioner, entries, ierr))
    call dgetf2(size(lu%pivots), size(lu%pivots), lu%factors, size(lu%pivots), lu%pivots, info)
    lu%ready = info == 0
    ! PETSc keeps a failure reason until told otherwise: clear it after a good factorization.
    if (info /= 0) then
      PetscCall(PCSetFailedReason(pc, PC_FACTOR_NUMERIC_ZEROPIVOT, ierr))
    else
      PetscCall(PCSetFailedReason(pc, PC_NOERROR, ierr))
    end if
  end subroutine factor_jacobian

  ! Shell preconditioner application: y = J^-1 x from the factors.
  subroutine solve_factored(pc, x, y, ierr)
    PC, intent(in) :: pc
    Vec, intent(in) :: x
    Vec, intent(in) :: y
    PetscErrorCode, intent(out) :: ierr
    type(dense_lu), pointer :: lu
    PetscScalar, pointer :: x_values(:), y_values(:)
    integer :: info, n

    PetscCall(PCShellGetContext(pc, lu, ierr))
    n = size(lu%pivots)
    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(VecGetArrayF90(y, y_values, ierr))
    y_values = x_values
    call dgetrs('N', n, 1, lu%factors, n, lu%pivots, y_values, n, info)
    PetscCall(VecRestoreArrayF90(y, y_values, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    if (info /= 0) then
      PetscCall(PCSetFailedReason(pc, PC_SUBPC_ERROR, ierr))
    end if
  end subroutine solve_factored

  ! SNES callback: the step residual; a state outside the model's domain is a domain error,
  ! which makes the line search shorten the step.
  subroutine form_residual(snes, x, f, problem, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Vec, intent(in) :: f
    type(step_problem), intent(in) :: problem
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), f_values(:)
    integer :: stat

    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(VecGetArrayF90(f, f_values, ierr))
    call problem%evaluate(x_values, f_values, stat=stat)
    if (stat /= 0) f_values = huge(1.0_real64)
    PetscCall(VecRestoreArrayF90(f, f_values, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    if (stat /= 0) then
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine form_residual

  ! SNES callback: the analytic Jacobian, written straight into the dense matrix.
  subroutine form_jacobian(snes, x, jacobian, preconditioner, problem, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian
    Mat, intent(in) :: preconditioner
    type(step_problem), intent(in) :: problem
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), entries(:, :)
    real(real64) :: residual(problem%unknowns())
    integer :: stat

    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(MatDenseGetArrayF90(preconditioner, entries, ierr))
    call problem%evaluate(x_values, residual, entries, stat)
    PetscCall(MatDenseRestoreArrayF90(preconditioner, entries, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    PetscCall(MatAssemblyBegin(preconditioner, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatAssemblyEnd(preconditioner, MAT_FINAL_ASSEMBLY, ierr))
    if (jacobian /= preconditioner) then
      PetscCall(MatAssemblyBegin(jacobian, MAT_FINAL_ASSEMBLY, ierr))
      PetscCall(MatAssemblyEnd(jacobian, MAT_FINAL_ASSEMBLY, ierr))
    end if
    if (stat /= 0) then
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine form_jacobian

end module step_solver
