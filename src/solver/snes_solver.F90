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
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use snes_shell, only: solver_context, full_step
  use solver_options, only: step_solver_options
  use snes_description, only: describe_snes
  use solver_description, only: solver_report, add_setting, text_setting, integer_setting, set_petsc_reasons, &
                                reasons_snes
  use failures, only: failure_type, fail_on_code
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

  ! Implemented in snes_solver_setup.
  interface
    !> Makes the solver ready for `problem` (prepare_petsc); a failure if PETSc fails. With
    !> from_options = .false. (kept from the first call), the solver ignores the options database:
    !> PETSc's and this code's defaults, a full Newton to the tolerance or the rounding floor.
    module subroutine prepare(self, problem, newton_tol, max_iterations, failure, from_options)
      class(newton_solver), intent(inout), target :: self
      class(nonlinear_system), intent(in), target :: problem
      real(real64), intent(in) :: newton_tol
      integer, intent(in) :: max_iterations
      type(failure_type), intent(out) :: failure
      logical, intent(in), optional :: from_options
    end subroutine prepare

    ! Creates the SNES for n unknowns.
    module subroutine create(self, n, newton_tol, max_iterations, ierr)
      class(newton_solver), intent(inout), target :: self
      integer, intent(in) :: n
      real(real64), intent(in) :: newton_tol
      integer, intent(in) :: max_iterations
      PetscErrorCode, intent(out) :: ierr
    end subroutine create

    !> Frees the PETSc objects.
    module subroutine destroy_petsc(self, ierr)
      class(newton_solver), intent(inout) :: self
      PetscErrorCode, intent(out) :: ierr
    end subroutine destroy_petsc
  end interface

contains

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
