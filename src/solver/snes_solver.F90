!> PETSc SNES on a nonlinear_system of any size (src/solver/nonlinear_problem), as the root
!> finder of the retry strategies (src/solver/retry_strategies). One SNES, vector pair and dense
!> matrix live as long as the solver and are reused for every solve (and, in an ensemble, for
!> every case of the same size). The linear solves are exact: LU with partial pivoting (src/solver/dense_lu)
!> in a shell preconditioner, whose factors also serve the chord predictor. SNESSetFromOptions
!> comes last, so -snes_monitor, -snes_converged_reason, -snes_test_jacobian, -pc_type lu, ...
!> work from the command line. Newton takes full steps by default: the residual's rows carry
!> different units, and backtracking on its 2-norm can stall where full steps converge; the
!> fallback is 'bt' (or 'basic' if the command line chose 'bt').
!>
!> Two ways to drive SNES (docs/performance.md), and one without it:
!>  - lean (the default): SNES never computes a Jacobian (SNESSetLagJacobian -1). The shell
!>    preconditioner evaluates it at SNES's current iterate and factors it when it is applied,
!>    whenever the modified Newton (src/solver/modified_newton) finds the factors it has no
!>    longer contracting: factors are kept across the iterations of a solve.
!>    With -eme_modified_newton false, once per Newton iteration, or it confirms a root with the
!>    factors it has (the final chord step: the residual is below the tolerance after an update
!>    below chord_update_limit). A shell line search takes the full step and hands SNES the norms
!>    it computed; the modified Newton needs it (PETSc's line searches select a new Jacobian every
!>    iteration). SNES's viewer lookups are switched off around SNESSolve when no option asks for a
!>    viewer.
!>  - direct (opt-in, -eme_direct_newton true, where the lean way is taken with its full-step shell
!>    and no option asks anything of SNES, KSP or PC: none whose name holds -snes_, -ksp_, -pc_,
!>    -info or -log_; by default SNES solves each step, as the project's design has it): the lean way's iteration run by hand_newton's
!>    newton_iterate on the same LU factors, without SNESSolve, whose machinery around a dense
!>    system of 9 unknowns cost as much as the residuals (docs/performance.md, Issue 42). The
!>    iterates, tests, factors and counts are the lean way's, bit for bit (the residual norms are
!>    the shell's two_norm in both; SNES's own VecNorm of the first residual enters no test that
!>    can fire at iteration 1). A solve that fails the direct way ends as SNES's would: at the
!>    iteration limit DIVERGED_MAX_IT; on a full step outside the domain after at least one
!>    iteration DIVERGED_LOCAL_MIN (the shell line search fails, and NEWTONLS's check of J^T F
!>    reads the lean way's operator, which stays zero); any other failure (the start or a
!>    Jacobian outside the domain, a zero pivot, a step at the first iteration, whose residual
!>    SNES measured with its own norm) is solved again by SNESSolve from the same start.
!>  - standard: SNESComputeJacobian calls form_jacobian, PCSetUp factors the matrix (read without
!>    changing its state, so once per iteration), the line search is PETSc's. Taken when an
!>    option needs SNES's own Jacobian (-snes_test_jacobian, -snes_compare_*, -snes_mf*,
!>    -snes_fd*, -snes_lag_jacobian, -pc_type, -ksp_type, another -snes_type) or -eme_lean_snes
!>    false; the line search is PETSc's whenever -snes_linesearch_type is given.
!>
!> Errors: each public procedure returns a failure_type; its PETSc calls sit in a private twin
!> (`*_petsc`) with PETSc's own ierr, whose PetscCall returns early, and the public procedure
!> turns that code into a failure (failures' fail_on_code).
module snes_solver
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use, intrinsic :: iso_fortran_env, only: real64
  use nonlinear_problem, only: nonlinear_system
  use retry_strategies, only: root_finder, chord_refinement, rounding_factor
  use hand_newton, only: newton_iterate, newton_settings, newton_outcome, ending_iterations, ending_step_domain
  use euclidean_norm, only: two_norm
  use dense_assembly, only: assemble_jacobian
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use snes_shell, only: solver_context, PCSetApplicationContext, converged_on_update, form_residual, form_jacobian, &
                        factor_operator, apply_lu, full_step
  use solver_options, only: step_solver_options, read_solver_options, option_given, option_value
  use snes_description, only: describe_snes
  use solver_description, only: solver_report, add_setting, text_setting, number_setting, integer_setting, set_petsc_reasons, &
                                reasons_snes
  use failures, only: failure_type, fail_on_code, fail, failure_input
  implicit none
  private
  public :: newton_solver

  !> The PETSc objects of a solver. Do not copy it after `prepare`: PETSc holds the address of
  !> `context`.
  type, extends(root_finder) :: newton_solver
    type(solver_context) :: context
    SNES :: snes
    Vec :: x
    Vec :: r
    Mat :: jacobian
    integer :: n = 0
    real(real64) :: newton_tol = 0.0_real64
    integer :: max_iterations = 0
    logical :: created = .false.
    type(step_solver_options) :: options
    !> Set up from the options database (the command line, PETSC_OPTIONS); .false.: the defaults
    !> alone, whatever the options say (the step check's re-solve, src/run/step_check).
    logical :: from_options = .true.
    logical :: shell_line_search = .false.          !! the full-step shell instead of 'basic'
    logical :: shell_in_use = .false.               !! the line search now is the shell
    logical :: quiet = .false.                      !! no option asks for a viewer
    logical :: direct = .false.                     !! the direct way (module header) where the shell is in use
    character(len=16) :: line_search = ''           !! the primary line search type
    character(len=16) :: fallback_line_search = ''  !! the retry strategies' fallback
    real(real64) :: last_residual_norm = 0.0_real64   !! of the last solve, as SNES's convergence test saw it
    integer :: last_reason = 0                      !! SNESConvergedReason of the last solve
  contains
    procedure :: prepare
    procedure :: destroy
    procedure :: solve
    procedure :: refine
    procedure :: use_fallback
    procedure :: lean
    procedure :: direct_way
    procedure :: keeps_factors
    procedure :: factorizations
    procedure :: describe
    procedure, private :: create
    procedure, private :: set_line_search
  end type newton_solver

contains

  !> Makes the solver ready for `problem` (prepare_petsc); a failure if PETSc fails. With
  !> from_options = .false. (kept from the first call), the solver ignores the options database:
  !> PETSc's and this code's defaults, a full Newton to the tolerance or the rounding floor.
  subroutine prepare(self, problem, newton_tol, max_iterations, failure, from_options)
    class(newton_solver), intent(inout), target :: self
    class(nonlinear_system), intent(in), target :: problem
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    type(failure_type), intent(out) :: failure
    logical, intent(in), optional :: from_options
    PetscErrorCode :: ierr
    character(len=:), allocatable :: refusal

    if (present(from_options) .and. .not. self%created) self%from_options = from_options
    if (self%from_options) then
      ! Before SNES reads them: -snes_type vinewtonrsls crashes PETSc 3.18 in SNESSetFromOptions.
      call refused_options(refusal, ierr)
      call fail_on_code(failure, ierr, 'newton_solver%prepare', 'PETSc could not read its options')
      if (.not. failure%failed() .and. len(refusal) > 0) &
        call fail(failure, failure_input, refusal, 'the command line or PETSC_OPTIONS')
      if (failure%failed()) return
    end if
    call prepare_petsc(self, problem, newton_tol, max_iterations, ierr)
    call fail_on_code(failure, ierr, 'newton_solver%prepare', 'PETSc could not set up SNES')
  end subroutine prepare

  !> Frees the PETSc objects; a failure if PETSc fails.
  subroutine destroy(self, failure)
    class(newton_solver), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call destroy_petsc(self, ierr)
    call fail_on_code(failure, ierr, 'newton_solver%destroy', 'PETSc could not free SNES')
  end subroutine destroy

  !> The SNES's settings and PETSc's names of its converged reasons (describe_petsc).
  subroutine describe(self, report, failure)
    class(newton_solver), intent(in) :: self
    type(solver_report), intent(inout) :: report
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call describe_petsc(self, report, ierr)
    call fail_on_code(failure, ierr, 'newton_solver%describe', 'PETSc could not describe SNES')
    if (.not. failure%failed()) call set_petsc_reasons(report, reasons_snes, failure)
  end subroutine describe

  !> One SNESSolve of `problem` from `initial` (solve_petsc); a failure only for a PETSc error.
  subroutine solve(self, problem, initial, root, converged, reason, iterations, failure)
    class(newton_solver), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr
    logical :: decided

    if (self%direct_way()) then
      call solve_direct(self, problem, initial, root, converged, reason, iterations, decided)
      if (decided) return
    end if
    call solve_petsc(self, problem, initial, root, converged, reason, iterations, ierr)
    call fail_on_code(failure, ierr, 'newton_solver%solve', 'PETSc failed in SNESSolve')
  end subroutine solve

  ! One solve the direct way (module header): newton_iterate on the shell's LU factors and record,
  ! with the lean SNES's settings; `decided` when it ended as SNES would report it (converged:
  ! CONVERGED_FNORM_ABS; DIVERGED_MAX_IT; DIVERGED_LOCAL_MIN), with SNES's reason, residual norm,
  ! iteration count and factorizations; otherwise SNESSolve must solve it again.
  subroutine solve_direct(self, problem, initial, root, converged, reason, iterations, decided)
    class(newton_solver), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations
    logical, intent(out) :: decided
    type(newton_outcome) :: outcome

    self%context%problem => problem
    call newton_iterate(problem, initial, newton_settings(tolerance=self%context%tolerance, &
                                                          update_tolerance=self%context%update_tolerance, &
                                                          max_iterations=self%max_iterations, &
                                                          modified_newton=self%keeps_factors(), &
                                                          final_chord=self%context%final_chord), &
                        self%context%lu, self%context%reuse, root, outcome)
    self%context%factorizations = self%context%factorizations + outcome%factorizations
    converged = outcome%converged
    iterations = outcome%iterations
    reason = ''
    decided = .true.
    self%last_residual_norm = outcome%residual_norm
    if (converged) then
      self%last_reason = int(SNES_CONVERGED_FNORM_ABS)
    else if (outcome%ending == ending_iterations) then
      self%last_reason = int(SNES_DIVERGED_MAX_IT)
      reason = 'Newton did not converge: DIVERGED_MAX_IT'
    else if (outcome%ending == ending_step_domain .and. outcome%iterations >= 2) then
      self%last_reason = int(SNES_DIVERGED_LOCAL_MIN)
      reason = 'Newton did not converge: DIVERGED_LOCAL_MIN'
      iterations = outcome%iterations - 1      ! SNES counts the iterations completed
    else
      decided = .false.
    end if
  end subroutine solve_direct

  !> Switches to the fallback line search, or back to the primary one; a failure if PETSc fails.
  subroutine use_fallback(self, on, failure)
    class(newton_solver), intent(inout) :: self
    logical, intent(in) :: on
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call use_fallback_petsc(self, on, ierr)
    call fail_on_code(failure, ierr, 'newton_solver%use_fallback', 'PETSc could not change the line search')
  end subroutine use_fallback

  ! Makes the solver ready for `problem` (which must stay at its address while in use), with
  !> absolute tolerance newton_tol on the 2-norm of the residual and at most max_iterations
  !> Newton iterations per solve. Reuses the PETSc objects when the size is the same, forgetting
  !> the old problem's LU factors; changed tolerances are applied, command-line options kept.
  subroutine prepare_petsc(self, problem, newton_tol, max_iterations, ierr)
    class(newton_solver), intent(inout), target :: self
    class(nonlinear_system), intent(in), target :: problem
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: iterations

    ierr = 0
    self%context%problem => problem
    if (self%created .and. self%n == problem%unknowns()) then
      self%context%lu%ready = .false.    ! the chord steps must not use another problem's Jacobian
      if (abs(newton_tol - self%newton_tol) > 0.0_real64 .or. max_iterations /= self%max_iterations) then
        iterations = max_iterations
        PetscCall(SNESSetTolerances(self%snes, newton_tol, PETSC_DEFAULT_REAL, PETSC_DEFAULT_REAL, iterations, PETSC_DEFAULT_INTEGER, ierr))
        self%newton_tol = newton_tol
        self%max_iterations = max_iterations
        PetscCall(keep_tolerances(self, ierr))
      end if
      return
    end if
    if (self%created) then
      PetscCall(destroy_petsc(self, ierr))
    end if
    PetscCall(self%create(problem%unknowns(), newton_tol, max_iterations, ierr))
  end subroutine prepare_petsc

  ! What the options database asks of this solver that it cannot do (a dense system, its own LU
  ! in a shell preconditioner, no DM, no bounds), as the refusal's text ('' if nothing): the SNES
  ! types that need a DM, an AIJ matrix, sub-solvers or callbacks it does not have, or that solve
  ! variational inequalities (vinewtonrsls crashed in PETSc 3.18); a matrix-free preconditioning
  ! matrix (-snes_mf: the shell reads the dense matrix) and coloring (-snes_fd_color: AIJ only);
  ! a factorization package other than PETSc's own (none takes a dense matrix); no iteration.
  subroutine refused_options(refusal, ierr)
    character(len=:), allocatable, intent(out) :: refusal
    PetscErrorCode, intent(out) :: ierr
    character(len=*), parameter :: refused_types(*) = [character(len=16) :: 'composite', 'ngs', 'nasm', 'aspin', &
                                                        'shell', 'patch', 'vinewtonrsls', 'vinewtonssls', 'python']
    character(len=*), parameter :: why = ' (the dense step of this model: no DM, its own LU in a shell '// &
                                         'preconditioner, docs/running.md); '
    character(len=64) :: snes_type, value
    integer :: max_iterations, status
    logical :: set

    refusal = ''
    PetscCall(option_value('-snes_type', snes_type, set, ierr))
    if (set .and. any(refused_types == snes_type)) then
      refusal = '-snes_type '//trim(snes_type)//' cannot solve this model''s steps'//why// &
                'allowed: newtonls (the default), newtontr, newtontrdc, nrichardson, ncg, ngmres, anderson, qn, ms, '// &
                'fas, ksponly'
      return
    end if
    PetscCall(option_value('-snes_mf', value, set, ierr))
    if (set) then
      refusal = '-snes_mf cannot serve this model''s steps'//why//'allowed: -snes_mf_operator, -snes_fd'
      return
    end if
    PetscCall(option_value('-snes_fd_color', value, set, ierr))
    if (set) then
      refusal = '-snes_fd_color cannot serve this model''s steps (coloring needs an AIJ matrix)'//why// &
                'allowed: -snes_fd, -snes_mf_operator'
      return
    end if
    PetscCall(option_value('-pc_factor_mat_solver_type', value, set, ierr))
    if (set .and. value /= 'petsc') then
      refusal = '-pc_factor_mat_solver_type '//trim(value)//' does not factor a dense matrix'//why// &
                'allowed: petsc'
      return
    end if
    PetscCall(option_value('-snes_max_it', value, set, ierr))
    if (.not. set) return
    read (value, *, iostat=status) max_iterations
    if (status == 0 .and. max_iterations < 1) then
      refusal = '-snes_max_it must allow at least one Newton iteration'//why//'allowed: an integer >= 1'
      return
    end if
  end subroutine refused_options

  ! Creates the SNES for n unknowns.
  subroutine create(self, n, newton_tol, max_iterations, ierr)
    class(newton_solver), intent(inout), target :: self
    integer, intent(in) :: n
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    type(failure_type) :: options_failure
    KSP :: ksp
    PC :: pc
    SNESLineSearch :: line_search
    PetscInt :: rows, max_evaluations, lag
    character(len=32) :: snes_type, ksp_type, pc_type
    logical :: needs_snes_jacobian, given
    integer :: k
    character(len=*), parameter :: jacobian_options(*) = [character(len=20) :: '-snes_test_jacobian', &
      '-snes_compare', '-snes_mf', '-snes_fd', '-snes_lag_jacobian', '-pc_type', '-ksp_type']
    character(len=*), parameter :: viewer_options(*) = [character(len=8) :: 'view', 'reason', 'monitor', 'draw']
    character(len=*), parameter :: solver_options_seen(*) = [character(len=6) :: '-snes_', '-ksp_', '-pc_', '-info', &
                                                             '-log_']

    self%n = n
    self%newton_tol = newton_tol
    self%max_iterations = max_iterations
    self%created = .true.
    rows = n
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, rows, self%x, ierr))
    PetscCall(VecDuplicate(self%x, self%r, ierr))
    PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, rows, rows, PETSC_NULL_SCALAR, self%jacobian, ierr))
    ! Assembled once, so that the lean preconditioner's operator (never changed) is valid.
    PetscCall(assemble_jacobian(self%jacobian, self%jacobian, ierr))
    PetscCall(SNESCreate(PETSC_COMM_SELF, self%snes, ierr))
    self%context%snes = self%snes
    PetscCall(SNESSetFunction(self%snes, self%r, form_residual, self%context, ierr))
    PetscCall(SNESSetJacobian(self%snes, self%jacobian, self%jacobian, form_jacobian, self%context, ierr))
    PetscCall(SNESGetKSP(self%snes, ksp, ierr))
    PetscCall(KSPSetType(ksp, KSPPREONLY, ierr))
    PetscCall(KSPGetPC(ksp, pc, ierr))
    call self%context%lu%reset(n)
    PetscCall(PCSetType(pc, PCSHELL, ierr))
    PetscCall(PCSetApplicationContext(pc, self%context, ierr))
    PetscCall(PCShellSetSetUp(pc, factor_operator, ierr))
    PetscCall(PCShellSetApply(pc, apply_lu, ierr))
    PetscCall(PCShellSetName(pc, 'dense LU with partial pivoting (src/solver/dense_lu)', ierr))
    max_evaluations = 10000
    PetscCall(SNESSetTolerances(self%snes, newton_tol, 0.0_real64, 0.0_real64, int(max_iterations, kind(rows)), max_evaluations, ierr))
    PetscCall(SNESSetConvergenceTest(self%snes, converged_on_update, self%context, PETSC_NULL_FUNCTION, ierr))
    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    PetscCall(SNESLineSearchSetType(line_search, SNESLINESEARCHBASIC, ierr))
    if (self%from_options) then
      PetscCall(SNESSetFromOptions(self%snes, ierr))
      call read_solver_options(self%options, options_failure)
      if (options_failure%failed()) then
        ierr = options_failure%code     ! nonzero: create's callers see a failed PETSc call
        return
      end if
    end if
    PetscCall(keep_tolerances(self, ierr))
    PetscCall(SNESLineSearchGetType(line_search, self%line_search, ierr))

    ! Lean only where SNES would not look at its Jacobian: Newton line search, LU in our shell.
    PetscCall(SNESGetType(self%snes, snes_type, ierr))
    PetscCall(KSPGetType(ksp, ksp_type, ierr))
    PetscCall(PCGetType(pc, pc_type, ierr))
    PetscCall(SNESGetLagJacobian(self%snes, lag, ierr))
    needs_snes_jacobian = snes_type /= SNESNEWTONLS .or. ksp_type /= KSPPREONLY .or. pc_type /= PCSHELL .or. lag /= 1
    do k = 1, size(jacobian_options)
      if (.not. self%from_options) exit
      PetscCall(option_given(trim(jacobian_options(k)), given, ierr))
      needs_snes_jacobian = needs_snes_jacobian .or. given
    end do
    self%context%lean = self%options%lean_snes .and. .not. needs_snes_jacobian
    self%context%final_chord = self%options%final_chord
    self%context%reuse%chord_iterations = self%options%chord_iterations
    if (self%context%lean) then
      lag = -1
      PetscCall(SNESSetLagJacobian(self%snes, lag, ierr))
      ! The preconditioner's operator never changes: PCSetUp (twice an iteration) returns at once.
      PetscCall(PCSetReusePreconditioner(pc, PETSC_TRUE, ierr))
    end if
    given = .false.
    if (self%from_options) then
      PetscCall(option_given('-snes_linesearch_type', given, ierr))
    end if
    self%shell_line_search = self%context%lean .and. .not. given
    if (self%line_search == SNESLINESEARCHBT) then
      self%fallback_line_search = SNESLINESEARCHBASIC
    else
      self%fallback_line_search = SNESLINESEARCHBT
    end if
    PetscCall(self%set_line_search(self%line_search, ierr))
    ! Viewers: -snes_view, -snes_converged_reason, -ksp_view_*, -mat_view, ..., monitors and draws.
    self%quiet = .true.
    do k = 1, size(viewer_options)
      if (.not. self%from_options) exit
      PetscCall(option_given(trim(viewer_options(k)), given, ierr))
      self%quiet = self%quiet .and. .not. given
    end do
    ! The direct way only where SNES, KSP and PC would do nothing that the lean way does not.
    self%direct = self%options%direct_newton .and. self%context%lean .and. self%shell_line_search .and. self%quiet
    do k = 1, size(solver_options_seen)
      if (.not. (self%from_options .and. self%direct)) exit
      PetscCall(option_given(trim(solver_options_seen(k)), given, ierr))
      self%direct = .not. given
    end do
  end subroutine create

  ! The line search `kind`: the full-step shell stands in for 'basic' when the solver is lean and
  ! the command line chose no line search.
  subroutine set_line_search(self, kind, ierr)
    class(newton_solver), intent(inout), target :: self
    character(len=*), intent(in) :: kind
    PetscErrorCode, intent(out) :: ierr
    SNESLineSearch :: line_search

    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    self%shell_in_use = self%shell_line_search .and. kind == SNESLINESEARCHBASIC
    if (self%shell_in_use) then
      PetscCall(SNESLineSearchSetType(line_search, SNESLINESEARCHSHELL, ierr))
      PetscCall(SNESLineSearchShellSetUserFunc(line_search, full_step, self%context, ierr))
    else
      PetscCall(SNESLineSearchSetType(line_search, kind, ierr))
    end if
  end subroutine set_line_search

  !> Frees the PETSc objects.
  subroutine destroy_petsc(self, ierr)
    class(newton_solver), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    self%created = .false.
    self%context%lu%ready = .false.
    PetscCall(SNESDestroy(self%snes, ierr))
    PetscCall(MatDestroy(self%jacobian, ierr))
    PetscCall(VecDestroy(self%r, ierr))
    PetscCall(VecDestroy(self%x, ierr))
  end subroutine destroy_petsc

  !> Whether the solver drives SNES the lean way (module header).
  logical function lean(self)
    class(newton_solver), intent(in) :: self

    lean = self%context%lean
  end function lean

  !> Whether the next solve is taken the direct way (module header): chosen at set-up, and the
  !> lean way's full-step shell is in use (not the retry strategies' fallback line search).
  logical function direct_way(self)
    class(newton_solver), intent(in) :: self

    direct_way = self%direct .and. self%shell_in_use
  end function direct_way

  !> Whether the lean way keeps its LU factors while they contract (module header), where its
  !> full-step line search is in use.
  logical function keeps_factors(self)
    class(newton_solver), intent(in) :: self

    keeps_factors = self%options%modified_newton .and. self%context%lean .and. self%shell_line_search
  end function keeps_factors

  !> The SNES as the options database left it (after SNESSetFromOptions): type, tolerances, line
  !> searches, linear solver, the lean way's choices, and PETSc's names of its converged reasons.
  subroutine describe_petsc(self, report, ierr)
    class(newton_solver), intent(in) :: self
    type(solver_report), intent(inout) :: report
    PetscErrorCode, intent(out) :: ierr
    PetscReal :: atol, rtol, stol
    PetscInt :: max_iterations, max_evaluations

    call add_setting(report, text_setting('name', 'PETSc SNES'))
    PetscCall(describe_snes(self%snes, report, ierr, line_search=self%line_search))
    PetscCall(SNESGetTolerances(self%snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
    call add_setting(report, integer_setting('snes_max_funcs', max_evaluations))
    call add_setting(report, text_setting('snes_convergence_test', 'retry_strategies newton_converged: |F| <= '// &
                                          'snes_atol after an update <= max(snes_atol, snes_stol |x|), or both at '// &
                                          'their rounding'))
    call add_setting(report, text_setting('fallback_linesearch_type', self%fallback_line_search))
    call add_setting(report, text_setting('eme_lean_snes', merge('true ', 'false', self%context%lean)))
    call add_setting(report, text_setting('eme_final_chord', merge('true ', 'false', self%context%final_chord)))
    call add_setting(report, text_setting('eme_modified_newton', merge('true ', 'false', self%keeps_factors())))
    call add_setting(report, text_setting('eme_direct_newton', merge('true ', 'false', self%direct)))
    call add_setting(report, integer_setting('eme_chord_iterations', self%context%reuse%chord_iterations))
    call add_setting(report, text_setting('eme_chord_predictor', merge('true ', 'false', self%options%chord_predictor)))
  end subroutine describe_petsc

  !> LU factorizations since the solver was made.
  integer function factorizations(self)
    class(newton_solver), intent(in) :: self

    factorizations = self%context%factorizations
  end function factorizations

  !> One SNESSolve of `problem` (of the size the solver was prepared for; it must stay at its
  !> address during the solve) from `initial`. A line search that fails on a residual already below the
  !> tolerance counts as converged: the residual sits at its rounding floor there.
  subroutine solve_petsc(self, problem, initial, root, converged, reason, iterations, ierr)
    class(newton_solver), intent(inout) :: self
    class(nonlinear_system), intent(inout), target :: problem
    real(real64), intent(in) :: initial(:)
    real(real64), intent(out) :: root(:)
    logical, intent(out) :: converged
    character(len=:), allocatable, intent(out) :: reason
    integer, intent(out) :: iterations
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: values(:)
    SNESConvergedReason :: snes_reason
    PetscInt :: its
    character(len=80) :: reason_text

    converged = .false.
    reason = ''
    iterations = 0
    self%context%problem => problem
    self%context%residual_norm = huge(1.0_real64)
    self%context%update_norm = huge(1.0_real64)
    self%context%previous_residual = huge(1.0_real64)
    self%context%chord_taken = .false.
    call problem%rounding_scales(self%context%state_scale, self%context%residual_scale)
    self%context%step_length = problem%step_length()
    ! Chord iterations stop at an error limit from the problem's rounding scale and step length.
    self%context%reuse%enabled = self%keeps_factors() .and. self%shell_in_use .and. self%context%state_scale > 0.0_real64 &
                                 .and. self%context%step_length > 0.0_real64
    call self%context%reuse%begin_solve()
    self%context%accepted_at = -1
    PetscCall(borrow(self%x, self%n, values, ierr))
    values = initial
    PetscCall(give_back(self%x, values, ierr))
    if (self%quiet) then
      PetscCall(PetscOptionsPushGetViewerOff(PETSC_TRUE, ierr))
    end if
    PetscCall(SNESSolve(self%snes, PETSC_NULL_VEC, self%x, ierr))
    if (self%quiet) then
      PetscCall(PetscOptionsPopGetViewerOff(ierr))
    end if
    PetscCall(SNESGetConvergedReason(self%snes, snes_reason, ierr))
    PetscCall(SNESGetIterationNumber(self%snes, its, ierr))
    PetscCall(SNESGetFunctionNorm(self%snes, self%last_residual_norm, ierr))
    self%last_reason = int(snes_reason)
    iterations = int(its)
    PetscCall(borrow_read(self%x, self%n, values, ierr))
    root = values
    PetscCall(give_back_read(self%x, values, ierr))
    converged = snes_reason > 0
    ! SNES stopped by a test other than ours (an option replaced it, or -snes_type ksponly): the
    ! root is accepted only if our test accepts its residual.
    if (converged .and. self%context%accepted_at /= int(its)) then
      converged = root_confirmed()
      if (.not. converged) then
        PetscCall(SNESGetConvergedReasonString(self%snes, reason_text, ierr))
        reason = 'Newton did not converge: SNES stopped ('//trim(reason_text)//') by a test other than the '// &
                 'project''s, at a residual above newton_tol'
        return
      end if
    end if
    if (.not. converged) converged = at_rounding_floor()
    if (.not. converged) then
      PetscCall(SNESGetConvergedReasonString(self%snes, reason_text, ierr))
      reason = 'Newton did not converge: '//trim(reason_text)
    end if

  contains

    logical function at_rounding_floor()
      PetscReal :: residual_norm
      PetscErrorCode :: ierr

      at_rounding_floor = .false.
      if (snes_reason /= SNES_DIVERGED_LINE_SEARCH) return
      PetscCall(SNESGetFunctionNorm(self%snes, residual_norm, ierr))
      at_rounding_floor = residual_norm <= self%context%tolerance
    end function at_rounding_floor

    ! The residual at the root SNES returned, against the tolerance or its rounding floor.
    logical function root_confirmed()
      real(real64) :: residual(size(root)), norm
      integer :: stat

      root_confirmed = .false.
      call problem%evaluate_residual(root, residual, stat)
      if (stat /= 0) return
      norm = two_norm(residual)
      root_confirmed = norm <= self%context%tolerance .or. &
                       norm <= rounding_factor*epsilon(1.0_real64)*self%context%residual_scale
    end function root_confirmed
  end subroutine solve_petsc

  ! The convergence test's tolerances, read from SNES once each time they are set (create and
  ! prepare) instead of in every test: the absolute one is the input's newton_tol, or SNES's where
  ! -snes_atol made it smaller (an option never loosens it); the relative update tolerance is
  ! -snes_stol's.
  subroutine keep_tolerances(self, ierr)
    class(newton_solver), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr
    PetscReal :: snes_atol, rtol, stol
    PetscInt :: max_iterations, max_evaluations

    PetscCall(SNESGetTolerances(self%snes, snes_atol, rtol, stol, max_iterations, max_evaluations, ierr))
    self%context%tolerance = min(snes_atol, self%newton_tol)
    self%context%update_tolerance = stol
  end subroutine keep_tolerances

  !> The predictor's chord refinement with the last solve's LU factors (retry_strategies'
  !> chord_refinement), unless -eme_chord_predictor false.
  subroutine refine(self, problem, x)
    class(newton_solver), intent(inout) :: self
    class(nonlinear_system), intent(inout) :: problem
    real(real64), intent(inout) :: x(:)

    if (self%options%chord_predictor) call chord_refinement(self%context%lu, problem, x)
  end subroutine refine

  !> Switches to the fallback line search, or back to the primary one.
  subroutine use_fallback_petsc(self, on, ierr)
    class(newton_solver), intent(inout) :: self
    logical, intent(in) :: on
    PetscErrorCode, intent(out) :: ierr

    if (on) then
      PetscCall(self%set_line_search(self%fallback_line_search, ierr))
    else
      PetscCall(self%set_line_search(self%line_search, ierr))
    end if
  end subroutine use_fallback_petsc

end module snes_solver
