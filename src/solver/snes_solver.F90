!> PETSc SNES on a nonlinear_system of any size (src/solver/nonlinear_problem), as the root
!> finder of the retry strategies (src/solver/retry_strategies). One SNES, vector pair and dense
!> matrix live as long as the solver and are reused for every solve (and, in an ensemble, for
!> every case of the same size). The linear solves are exact: LU in a shell preconditioner
!> (src/solver/lu_preconditioner) whose factors also serve the chord predictor. SNESSetFromOptions
!> comes last, so -snes_monitor, -snes_converged_reason, -snes_test_jacobian, -pc_type lu, ...
!> work from the command line. Newton takes full steps (line search 'basic') by default: the
!> residual's rows carry different units, and backtracking on its 2-norm can stall where full
!> steps converge; the fallback is 'bt' (or 'basic' if the command line chose 'bt').
module snes_solver
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use, intrinsic :: iso_fortran_env, only: real64
  use nonlinear_problem, only: nonlinear_system
  use retry_strategies, only: root_finder
  use dense_lu, only: lu_factors
  use lu_preconditioner, only: use_lu_shell
  use dense_assembly, only: assemble_jacobian
  implicit none
  private
  public :: newton_solver

  !> The problem the callbacks see (PETSc holds this context's address).
  type :: problem_context
    class(nonlinear_system), pointer :: problem => null()
  end type problem_context

  !> The PETSc objects of a solver. Do not copy it after `prepare`: PETSc holds the addresses of
  !> `context` and `lu`.
  type, extends(root_finder) :: newton_solver
    type(problem_context) :: context
    type(lu_factors) :: lu
    SNES :: snes
    Vec :: x
    Vec :: r
    Mat :: jacobian
    integer :: n = 0
    real(real64) :: newton_tol = 0.0_real64
    integer :: max_iterations = 0
    logical :: created = .false.
    character(len=16) :: line_search = ''           !! the primary line search type
    character(len=16) :: fallback_line_search = ''  !! the retry strategies' fallback
    logical :: chord_predictor = .true.             !! -eme_chord_predictor false switches it off
  contains
    procedure :: prepare
    procedure :: destroy
    procedure :: solve
    procedure :: refine
    procedure :: use_fallback
    procedure, private :: create
  end type newton_solver

contains

  !> Makes the solver ready for `problem` (which must stay at its address while in use), with
  !> absolute tolerance newton_tol on the 2-norm of the residual and at most max_iterations
  !> Newton iterations per solve. Reuses the PETSc objects when the size is the same, forgetting
  !> the old problem's LU factors; changed tolerances are applied, command-line options kept.
  subroutine prepare(self, problem, newton_tol, max_iterations, ierr)
    class(newton_solver), intent(inout), target :: self
    class(nonlinear_system), intent(in), target :: problem
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: iterations

    ierr = 0
    self%context%problem => problem
    if (self%created .and. self%n == problem%unknowns()) then
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
    PetscCall(self%create(problem%unknowns(), newton_tol, max_iterations, ierr))
  end subroutine prepare

  ! Creates the SNES for n unknowns.
  subroutine create(self, n, newton_tol, max_iterations, ierr)
    class(newton_solver), intent(inout), target :: self
    integer, intent(in) :: n
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    KSP :: ksp
    PC :: pc
    SNESLineSearch :: line_search
    PetscInt :: size, max_evaluations
    PetscBool :: found

    self%n = n
    self%newton_tol = newton_tol
    self%max_iterations = max_iterations
    self%created = .true.
    size = n
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, size, self%x, ierr))
    PetscCall(VecDuplicate(self%x, self%r, ierr))
    PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, size, size, PETSC_NULL_SCALAR, self%jacobian, ierr))
    PetscCall(SNESCreate(PETSC_COMM_SELF, self%snes, ierr))
    PetscCall(SNESSetFunction(self%snes, self%r, form_residual, self%context, ierr))
    PetscCall(SNESSetJacobian(self%snes, self%jacobian, self%jacobian, form_jacobian, self%context, ierr))
    PetscCall(SNESGetKSP(self%snes, ksp, ierr))
    PetscCall(KSPSetType(ksp, KSPPREONLY, ierr))
    PetscCall(KSPGetPC(ksp, pc, ierr))
    call self%lu%reset(n)
    PetscCall(use_lu_shell(pc, self%lu, ierr))
    max_evaluations = 10000
    PetscCall(SNESSetTolerances(self%snes, newton_tol, 0.0_real64, 0.0_real64, int(max_iterations, kind(size)), max_evaluations, ierr))
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

  !> Frees the PETSc objects.
  subroutine destroy(self, ierr)
    class(newton_solver), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    self%created = .false.
    self%lu%ready = .false.
    PetscCall(SNESDestroy(self%snes, ierr))
    PetscCall(MatDestroy(self%jacobian, ierr))
    PetscCall(VecDestroy(self%r, ierr))
    PetscCall(VecDestroy(self%x, ierr))
  end subroutine destroy

  !> One SNESSolve of `problem` (of the size the solver was prepared for; it must stay at its
  !> address during the solve) from `initial`. A line search that fails on a residual already below the
  !> tolerance counts as converged: the residual sits at its rounding floor there.
  subroutine solve(self, problem, initial, root, converged, reason, iterations, ierr)
    class(newton_solver), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations, ierr
    PetscScalar, pointer :: values(:)
    SNESConvergedReason :: snes_reason
    PetscInt :: its
    character(len=80) :: reason_text

    converged = .false.
    reason = ''
    iterations = 0
    self%context%problem => problem
    PetscCall(VecGetArrayF90(self%x, values, ierr))
    values = initial
    PetscCall(VecRestoreArrayF90(self%x, values, ierr))
    PetscCall(SNESSolve(self%snes, PETSC_NULL_VEC, self%x, ierr))
    PetscCall(SNESGetConvergedReason(self%snes, snes_reason, ierr))
    PetscCall(SNESGetIterationNumber(self%snes, its, ierr))
    iterations = int(its)
    PetscCall(VecGetArrayReadF90(self%x, values, ierr))
    root = values
    PetscCall(VecRestoreArrayReadF90(self%x, values, ierr))
    converged = snes_reason > 0
    if (.not. converged) converged = at_rounding_floor()
    if (.not. converged) then
      PetscCall(SNESGetConvergedReasonString(self%snes, reason_text, ierr))
      reason = 'Newton did not converge: '//trim(reason_text)
    end if

  contains

    logical function at_rounding_floor()
      PetscReal :: residual_norm, atol, rtol, stol
      PetscInt :: max_iterations, max_evaluations
      PetscErrorCode :: ierr

      at_rounding_floor = .false.
      if (snes_reason /= SNES_DIVERGED_LINE_SEARCH) return
      PetscCall(SNESGetFunctionNorm(self%snes, residual_norm, ierr))
      PetscCall(SNESGetTolerances(self%snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
      at_rounding_floor = residual_norm <= atol
    end function at_rounding_floor
  end subroutine solve

  !> The chord step x - J_old^-1 R(x) with the last Jacobian's LU factors (from the last
  !> solve): a residual and a back-substitution instead of a Newton iteration, which saves about
  !> one iteration per step (README, per-step cost). Nothing happens without factors.
  subroutine refine(self, problem, x)
    class(newton_solver), intent(inout) :: self
    class(nonlinear_system), intent(in) :: problem
    real(real64), intent(inout) :: x(:)
    real(real64) :: residual(size(x))
    integer :: stat, info

    if (.not. (self%lu%ready .and. self%chord_predictor)) return
    call problem%evaluate(x, residual, stat=stat)
    if (stat /= 0) return
    call self%lu%solve(residual, info)
    if (info == 0) x = x - residual
  end subroutine refine

  !> Switches to the fallback line search, or back to the primary one.
  subroutine use_fallback(self, on, ierr)
    class(newton_solver), intent(inout) :: self
    logical, intent(in) :: on
    integer, intent(out) :: ierr
    SNESLineSearch :: line_search

    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    if (on) then
      PetscCall(SNESLineSearchSetType(line_search, self%fallback_line_search, ierr))
    else
      PetscCall(SNESLineSearchSetType(line_search, self%line_search, ierr))
    end if
  end subroutine use_fallback

  ! SNES convergence test. Converged when the residual is below the absolute tolerance and so
  ! was the Newton update that produced it (or the initial guess already solves the system).
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

  ! SNES callback: the residual; a point outside the problem's domain is a domain error, which
  ! makes the line search shorten the step.
  subroutine form_residual(snes, x, f, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Vec, intent(in) :: f
    type(problem_context), intent(in) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), f_values(:)
    integer :: stat

    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(VecGetArrayF90(f, f_values, ierr))
    call context%problem%evaluate(x_values, f_values, stat=stat)
    if (stat /= 0) f_values = huge(1.0_real64)
    PetscCall(VecRestoreArrayF90(f, f_values, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    if (stat /= 0) then
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine form_residual

  ! SNES callback: the analytic Jacobian, written straight into the dense matrix.
  subroutine form_jacobian(snes, x, jacobian, preconditioner, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian
    Mat, intent(in) :: preconditioner
    type(problem_context), intent(in) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), entries(:, :)
    real(real64) :: residual(context%problem%unknowns())
    integer :: stat

    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(MatDenseGetArrayF90(preconditioner, entries, ierr))
    call context%problem%evaluate(x_values, residual, entries, stat)
    PetscCall(MatDenseRestoreArrayF90(preconditioner, entries, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    PetscCall(assemble_jacobian(jacobian, preconditioner, ierr))
    if (stat /= 0) then
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine form_jacobian

end module snes_solver
