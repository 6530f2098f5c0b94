!> PETSc TS on the chain split over ranks (docs/formulation.md section 10, "Sparse and
!> distributed"; docs/performance.md, "Two paths"): the chain's GENERIC field z' = f(z) = (L + K)
!> of the exact partials and its sparse Jacobian df/dz, each rank assembling the rows it owns on
!> spring_chain_dmda's DMDA (field_at, jacobian_at: the blocks of the EME step at partials_exact),
!> offered to TS as its RHS function and RHS Jacobian. The input's TS integrator (the dense path's
!> names, src/integrator/ts_stepper: ts_midpoint, ts_bdf2, ts_rk4, ts_rk5dp) sets the TS's type;
!> -ts_type and every other -ts_* option override it (TSSetFromOptions comes last), so any TS type
!> runs on the chain. As on the dense path, one `step(dt)` advances the TS by dt exactly: the
!> fixed-step methods take one step of dt (no adaptivity, no rejected steps), ts_rk5dp (or options
!> that choose an adaptor) chooses its own steps at &integrator tolerance and lands on t + dt; the
!> TS keeps its state, and BDF its history, from one step to the next. The implicit methods' Newton
!> is the TS's SNES at &integrator newton_tol (absolute) or the rounding floor of the state (an
!> update below 16 eps |z|, -snes_stol), with the chain's default linear solver (spring_chain_dmda). A stage outside a spring's domain: the field is NaN there and an implicit
!> method's SNES is told, so the step fails; an explicit method's step that went through such a
!> stage ends non-finite, and is reported as not converged. A TS run keeps no balance exactly: its
!> registry entry guarantees none, and the time loop checks none (src/run/step_check).
module spring_chain_ts_run
#include <petsc/finclude/petscts.h>
  use petscts
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use failures, only: failure_type, fail_on_code, failure_none
  use number_text, only: integer_text
  use model_interface, only: generic_model
  use solver_description, only: solver_report, add_setting, text_setting, set_petsc_reasons, reasons_ts
  use ts_description, only: describe_ts
  use ts_type_check, only: refuse_other_problem_forms
  use distributed_model, only: distributed_settings, distributed_step, distributed_part
  use spring_chain_dmda, only: distributed_chain, set_default_linear_solver
  use spring_chain_linear_solver, only: settings_in_code
  use spring_chain_sparse_run, only: sparse_chain_run
  implicit none
  private
  public :: ts_chain_run

  !> TS's types that solve no equations with an RHS alone (ARKIMEX treats an RHS explicitly).
  character(len=*), parameter :: explicit_types(5) = [character(len=8) :: 'euler', 'rk', 'ssp', 'arkimex', 'mprk']

  !> What the TS's callbacks see (PETSc holds its address): the chain they evaluate, and how many
  !> evaluations since the step began found a spring outside its domain.
  type :: ts_context
    type(distributed_chain), pointer :: chain => null()
    integer :: domain_errors = 0
  end type ts_context

  !> The chain stepped by PETSc TS. Do not copy it after `start`: PETSc holds the addresses of its
  !> context and its chain.
  type, extends(sparse_chain_run) :: ts_chain_run
    type(ts_context) :: context
    TS :: ts
    Vec :: old                                  !! the state a step starts from (kept if TS fails)
    logical :: ts_created = .false.
    logical :: adaptive = .false.               !! the TS chooses its steps inside one (ts_rk5dp)
    real(real64) :: time = 0.0_real64           !! the time the state held is at
    PetscInt :: snes_iterations = 0, ts_steps = 0, rejections = 0   !! the TS's totals so far
  contains
    procedure :: start
    procedure :: step
    procedure :: restore
    procedure :: restore_state
    procedure :: finish
    procedure :: describe_solver
  end type ts_chain_run

contains

  !> Sets up the chain from z0 on `comm` (sparse_chain_run's set_up: the DMDA, the state, E_0,
  !> S_0) and its TS for `settings`' integrator.
  subroutine start(self, settings, model, z0, comm, failure)
    class(ts_chain_run), intent(inout), target :: self
    type(distributed_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call self%set_up(settings, model, z0, comm, failure)
    if (failure%failed()) return
    call start_petsc(self, settings, ierr)
    call fail_on_code(failure, ierr, 'setting up the chain''s PETSc TS')
    if (.not. failure%failed()) call refuse_other_problem_forms(self%ts, failure)
  end subroutine start

  subroutine start_petsc(self, settings, ierr)
    class(ts_chain_run), intent(inout), target :: self
    type(distributed_settings), intent(in) :: settings
    PetscErrorCode, intent(out) :: ierr
    MPI_Comm :: comm
    SNES :: snes
    KSP :: ksp
    TSAdapt :: adapt
    PetscInt :: max_iterations, max_evaluations, max_steps

    self%context%chain => self%chain
    self%time = 0.0_real64
    PetscCall(PetscObjectGetComm(self%chain%context%da, comm, ierr))
    PetscCall(TSCreate(comm, self%ts, ierr))
    self%ts_created = .true.
    PetscCall(VecDuplicate(self%chain%x, self%old, ierr))
    PetscCall(TSSetProblemType(self%ts, TS_NONLINEAR, ierr))
    PetscCall(TSSetSolution(self%ts, self%chain%x, ierr))
    PetscCall(TSSetRHSFunction(self%ts, PETSC_NULL_VEC, chain_field, self%context, ierr))
    ! The Jacobian for every type: an implicit -ts_type may replace an explicit integrator.
    PetscCall(TSSetRHSJacobian(self%ts, self%chain%jacobian, self%chain%jacobian, chain_field_jacobian, self%context, ierr))
    select case (settings%scheme)
    case ('ts_midpoint')
      PetscCall(TSSetType(self%ts, TSTHETA, ierr))
      PetscCall(TSThetaSetTheta(self%ts, 0.5_real64, ierr))
    case ('ts_bdf2')
      PetscCall(TSSetType(self%ts, 'bdf', ierr))   ! PETSc 3.18's Fortran headers lack TSBDF
      PetscCall(TSBDFSetOrder(self%ts, 2, ierr))
    case ('ts_rk4')
      PetscCall(TSSetType(self%ts, TSRK, ierr))
      PetscCall(TSRKSetType(self%ts, TSRK4, ierr))
    case default   ! ts_rk5dp (chain_problem_of refused the others)
      PetscCall(TSSetType(self%ts, TSRK, ierr))
      PetscCall(TSRKSetType(self%ts, TSRK5DP, ierr))
    end select
    PetscCall(TSGetSNES(self%ts, snes, ierr))
    max_iterations = settings%newton_max_iterations
    max_evaluations = 10000
    ! Newton to newton_tol, or to the rounding floor of the state (an update below 16 eps |z|, as
    ! the split EME steps): a long chain's TS residual, shift z - f(z), rounds far above 1e-9.
    PetscCall(SNESSetTolerances(snes, settings%newton_tol, 0.0_real64, 16.0_real64*epsilon(1.0_real64), max_iterations, max_evaluations, ierr))
    PetscCall(SNESGetKSP(snes, ksp, ierr))
    PetscCall(set_default_linear_solver(ksp, comm, ierr))
    PetscCall(TSSetTime(self%ts, 0.0_real64, ierr))
    PetscCall(TSSetTimeStep(self%ts, settings%dt, ierr))
    max_steps = 1000000000
    PetscCall(TSSetMaxSteps(self%ts, max_steps, ierr))
    PetscCall(TSSetExactFinalTime(self%ts, TS_EXACTFINALTIME_MATCHSTEP, ierr))
    ! A step that fails ends TSSolve with a negative converged reason, not a PETSc error.
    PetscCall(TSSetErrorIfStepFails(self%ts, PETSC_FALSE, ierr))
    PetscCall(TSGetAdapt(self%ts, adapt, ierr))
    if (settings%scheme == 'ts_rk5dp') then
      PetscCall(TSSetTolerances(self%ts, settings%tolerance, PETSC_NULL_VEC, settings%tolerance, PETSC_NULL_VEC, ierr))
    else
      ! Fixed steps, as on the dense path: a failed step ends the run instead of halving the step.
      PetscCall(TSAdaptSetType(adapt, TSADAPTNONE, ierr))
      PetscCall(TSSetMaxStepRejections(self%ts, 0, ierr))
    end if
    PetscCall(TSSetFromOptions(self%ts, ierr))
    self%adaptive = .not. is_type(adapt, TSADAPTNONE)
  end subroutine start_petsc

  ! Whether the adaptor is of type `name`.
  logical function is_type(adapt, name)
    TSAdapt, intent(in) :: adapt
    character(len=*), intent(in) :: name
    character(len=32) :: adapt_type
    PetscErrorCode :: ierr

    call TSAdaptGetType(adapt, adapt_type, ierr)
    is_type = ierr == 0 .and. adapt_type == name
  end function is_type

  !> Advances the TS by dt from the state held (distributed_system); on a step TS could not take
  !> the state is kept (outcome%converged false, outcome%failure says why).
  subroutine step(self, dt, outcome, failure)
    class(ts_chain_run), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call step_petsc(self, dt, outcome, ierr)
    call fail_on_code(failure, ierr, 'advancing the chain''s PETSc TS')
  end subroutine step

  subroutine step_petsc(self, dt, outcome, ierr)
    class(ts_chain_run), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    PetscErrorCode, intent(out) :: ierr
    TSConvergedReason :: converged
    SNES :: snes
    PetscInt :: snes_iterations, ts_steps, rejections
    PetscReal :: largest

    self%context%domain_errors = 0
    PetscCall(self%chain%hold_old_state(ierr))
    PetscCall(VecCopy(self%chain%x, self%old, ierr))
    ! From the loop's time, to t + dt exactly; a fixed-step method's step reset to dt (after
    ! landing on an output time TS keeps a shortened last step as its next).
    PetscCall(TSSetTime(self%ts, self%time, ierr))
    PetscCall(TSSetMaxTime(self%ts, self%time + dt, ierr))
    if (.not. self%adaptive) then
      PetscCall(TSSetTimeStep(self%ts, dt, ierr))
    end if
    PetscCall(TSSolve(self%ts, self%chain%x, ierr))
    PetscCall(TSGetConvergedReason(self%ts, converged, ierr))
    PetscCall(TSGetSNES(self%ts, snes, ierr))
    PetscCall(SNESGetFunctionNorm(snes, outcome%residual_norm, ierr))
    PetscCall(TSGetSNESIterations(self%ts, snes_iterations, ierr))
    PetscCall(TSGetStepNumber(self%ts, ts_steps, ierr))
    PetscCall(TSGetStepRejections(self%ts, rejections, ierr))
    outcome%iterations = int(snes_iterations - self%snes_iterations)
    outcome%solves = int(ts_steps - self%ts_steps)
    outcome%rejected = int(rejections - self%rejections)
    self%snes_iterations = snes_iterations
    self%ts_steps = ts_steps
    self%rejections = rejections
    outcome%reason = int(converged)
    PetscCall(VecNorm(self%chain%x, NORM_INFINITY, largest, ierr))
    outcome%converged = converged > 0 .and. largest <= huge(largest)
    if (outcome%converged) then
      self%time = self%time + dt
    else
      outcome%failure = failure_text(converged, self%context%domain_errors > 0)
      PetscCall(VecCopy(self%old, self%chain%x, ierr))
    end if
  end subroutine step_petsc

  !> Makes the rank's part `state` the current state (a continued run's last snapshot) and
  !> restarts TS from it: a multistep method (BDF) starts again at order 1, with no history from
  !> before the snapshot, as the dense path's continued TS runs do (docs/faults.md).
  subroutine restore(self, state, failure)
    class(ts_chain_run), intent(inout) :: self
    type(distributed_part), intent(in) :: state
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call self%sparse_chain_run%restore(state, failure)
    if (failure%failed()) return
    call TSRestartStep(self%ts, ierr)
    call fail_on_code(failure, ierr, 'restarting the chain''s PETSc TS')
  end subroutine restore

  !> A continued run's time (its snapshot's) becomes TS's clock: its steps go on from [t, t + dt],
  !> not from 0 (the field has no time in it, but TS's step count and last, shortened step do).
  subroutine restore_state(self, time, values, failure)
    class(ts_chain_run), intent(inout) :: self
    real(real64), intent(in) :: time, values(:)
    type(failure_type), intent(out) :: failure

    call self%sparse_chain_run%restore_state(time, values, failure)
    if (.not. failure%failed()) self%time = time
  end subroutine restore_state

  ! Why TS did not reach the step's end (`converged` < 0), or why its state is not finite;
  ! `domain` when a stage left a spring's domain on this rank.
  function failure_text(converged, domain) result(text)
    TSConvergedReason, intent(in) :: converged
    logical, intent(in) :: domain
    character(len=:), allocatable :: text

    select case (converged)
    case (TS_DIVERGED_NONLINEAR_SOLVE)
      text = 'PETSc TS: the Newton solve of an implicit step diverged (TS_DIVERGED_NONLINEAR_SOLVE)'
    case (TS_DIVERGED_STEP_REJECTED)
      text = 'PETSc TS: too many rejected steps (TS_DIVERGED_STEP_REJECTED)'
    case default
      if (converged > 0) then
        text = 'PETSc TS: the state is not finite'
      else
        text = 'PETSc TS did not converge, TSConvergedReason '//integer_text(int(converged))
      end if
    end select
    if (domain) text = text//'; a stage left a spring''s domain (a non-positive length or temperature)'
  end function failure_text

  !> Frees the TS, then the chain's PETSc objects (sparse_chain_run's finish); failure keeps the
  !> first failure.
  subroutine finish(self, failure)
    class(ts_chain_run), intent(inout) :: self
    type(failure_type), intent(inout) :: failure
    PetscErrorCode :: ierr
    type(failure_type) :: freeing

    ierr = 0
    if (self%ts_created) call TSDestroy(self%ts, ierr)
    if (self%ts_created .and. ierr == 0) call VecDestroy(self%old, ierr)
    self%ts_created = .false.
    call fail_on_code(freeing, ierr, 'freeing the chain''s PETSc TS')
    if (.not. failure%failed() .and. freeing%failed()) failure = freeing
    call self%sparse_chain_run%finish(failure)
  end subroutine finish

  !> The TS as the options left it, with its SNES and linear solver for a type that solves
  !> equations, and PETSc's names of TS's converged reasons (distributed_system).
  function describe_solver(self) result(report)
    class(ts_chain_run), intent(in) :: self
    type(solver_report) :: report
    type(failure_type) :: failure
    character(len=32) :: ts_type
    character(len=:), allocatable :: ordering
    logical :: floor_set, implicit
    SNES :: snes
    KSP :: ksp
    PetscErrorCode :: ierr

    call TSGetType(self%ts, ts_type, ierr)
    implicit = .not. any(ts_type == explicit_types)
    ordering = ''
    if (ierr == 0 .and. implicit) call TSGetSNES(self%ts, snes, ierr)
    if (ierr == 0 .and. implicit) call SNESGetKSP(snes, ksp, ierr)
    if (ierr == 0 .and. implicit) call settings_in_code(ksp, ordering, floor_set, ierr)   ! (a TS's solves keep their atol)
    if (ierr == 0) call describe_ts(self%ts, 'PETSc TS on a DMDA split over the ranks: the chain''s field and '// &
                                    'sparse Jacobian', implicit, report, ierr, ordering)
    if (ierr == 0) call set_petsc_reasons(report, reasons_ts, failure)
    if (ierr /= 0 .or. failure%failed()) call add_setting(report, text_setting('error', 'PETSc could not describe the TS'))
  end function describe_solver

  ! TS callback: the rank's rows of f(z) at x; outside a spring's domain f is NaN and the SNES of
  ! an implicit step is told (SNESSetFunctionDomainError: the step fails).
  subroutine chain_field(ts, time, x, f, context, ierr)
    TS, intent(in) :: ts
    PetscReal, intent(in) :: time
    Vec, intent(in) :: x
    Vec, intent(in) :: f
    type(ts_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    integer :: stat
    SNES :: snes

    PetscCall(context%chain%field_at(x, f, stat, ierr))
    if (stat == failure_none) return
    context%domain_errors = context%domain_errors + 1
    PetscCall(VecSet(f, ieee_value(1.0_real64, ieee_quiet_nan), ierr))
    PetscCall(TSGetSNES(ts, snes, ierr))
    PetscCall(SNESSetFunctionDomainError(snes, ierr))
  end subroutine chain_field

  ! TS callback: the rank's rows of df/dz at x, assembled into the chain's matrix.
  subroutine chain_field_jacobian(ts, time, x, jacobian, preconditioner, context, ierr)
    TS, intent(in) :: ts
    PetscReal, intent(in) :: time
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian, preconditioner
    type(ts_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    integer :: stat
    SNES :: snes

    PetscCall(context%chain%jacobian_at(x, preconditioner, stat, ierr))
    if (jacobian /= preconditioner) then
      PetscCall(MatAssemblyBegin(jacobian, MAT_FINAL_ASSEMBLY, ierr))
      PetscCall(MatAssemblyEnd(jacobian, MAT_FINAL_ASSEMBLY, ierr))
    end if
    if (stat == failure_none) return
    context%domain_errors = context%domain_errors + 1
    PetscCall(TSGetSNES(ts, snes, ierr))
    PetscCall(SNESSetJacobianDomainError(snes, ierr))
  end subroutine chain_field_jacobian

end module spring_chain_ts_run
