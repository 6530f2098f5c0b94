!> How newton_solver is set up (src/solver/snes_solver): the options it refuses, the SNES, its shell
!> preconditioner, line search and tolerances created for a problem's size, or reused for the next
!> problem of that size, and its PETSc objects destroyed. A submodule because it works on the
!> solver's PETSc objects.
#include <petsc/finclude/petscsnes.h>
submodule (snes_solver) snes_solver_setup
  use dense_assembly, only: assemble_jacobian
  use snes_shell, only: PCSetApplicationContext, converged_on_update, form_residual, form_jacobian, &
                        factor_operator, apply_lu
  use solver_options, only: read_solver_options, option_given, option_value
  use failures, only: fail, failure_input
  implicit none

contains

  module procedure prepare
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
  end procedure prepare

  module procedure create
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
  end procedure create

  module procedure destroy_petsc

    self%created = .false.
    self%context%lu%ready = .false.
    PetscCall(SNESDestroy(self%snes, ierr))
    PetscCall(MatDestroy(self%jacobian, ierr))
    PetscCall(VecDestroy(self%r, ierr))
    PetscCall(VecDestroy(self%x, ierr))
  end procedure destroy_petsc

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

end submodule snes_solver_setup
