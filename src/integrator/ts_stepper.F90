!> PETSc TS baselines on the continuous GENERIC vector field f(z) = L grad E + K grad S of any
!> model (its vector field at exact partials, docs/formulation.md section 4) and its exact Jacobian:
!>   ts_midpoint  TSTHETA with theta = 1/2, the implicit midpoint rule as PETSc does it
!>   ts_bdf2      TSBDF of order 2
!>   ts_rk4       TSRK 4, the classic explicit Runge-Kutta method
!>   ts_rk5dp     TSRK 5dp, Dormand-Prince with adaptive steps at &integrator tolerance
!> The fixed-step methods take one step of dt per output step; ts_rk5dp chooses its own steps
!> and lands on every output time. The TS keeps its state between output steps, so multistep
!> BDF2 keeps its history. Options with the TS prefix work from the command line (-ts_*).
module ts_stepper
#include <petsc/finclude/petscts.h>
  use petscts
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_ptr, c_funptr, c_funloc, c_loc, c_f_pointer
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report, solver_report, no_residual, accept_in_domain
  use solver_description, only: add_setting, text_setting, set_petsc_reasons, reasons_ts
  use ts_description, only: describe_ts
  use ts_type_check, only: refuse_other_problem_forms
  use dense_assembly, only: assemble_jacobian
  use failures, only: failure_type, fail, fail_on_code, failure_input, failure_mismatch
  implicit none
  private
  public :: ts_baseline, new_ts_midpoint, new_ts_bdf2, new_ts_rk4, new_ts_rk5dp

  integer, parameter :: ts_midpoint = 1, ts_bdf2 = 2, ts_rk4 = 3, ts_rk5dp = 4

  !> The model the callbacks evaluate, whether the method solves equations (the implicit ones
  !> tell their SNES when a Newton iterate leaves the domain), and how many stages the domain
  !> check has rejected.
  type :: rhs_context
    class(generic_model), allocatable :: model
    logical :: implicit = .false.
    integer :: domain_rejections = 0
  end type rhs_context

  interface
    !> Attaches the stage domain check `inside` (with `context`) to a TS (ts_domain.c).
    function eme_ts_set_domain_check(ts, inside, context) bind(C, name='eme_ts_set_domain_check') result(ierr)
      import :: c_int, c_ptr, c_funptr
      type(*), intent(in) :: ts
      type(c_funptr), value, intent(in) :: inside
      type(c_ptr), value, intent(in) :: context
      integer(c_int) :: ierr
    end function eme_ts_set_domain_check
  end interface

  !> One TS per run. Do not copy it after `start`: PETSc holds the address of `context`.
  type, extends(time_stepper) :: ts_baseline
    type(rhs_context) :: context
    TS :: ts
    Vec :: x
    Mat :: jacobian
    integer :: method = ts_midpoint
    logical :: created = .false.
    PetscInt :: snes_iterations = 0
    PetscInt :: steps = 0
    PetscInt :: rejections = 0
    real(real64) :: next_step = 0.0_real64   !! the step TS holds after the last output step (ts_rk5dp's next trial)
  contains
    procedure :: start
    procedure :: advance
    procedure :: release
    procedure :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
  end type ts_baseline

contains

  !> TSTHETA with theta = 1/2.
  subroutine new_ts_midpoint(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=ts_baseline(method=ts_midpoint))
  end subroutine new_ts_midpoint

  !> TSBDF of order 2.
  subroutine new_ts_bdf2(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=ts_baseline(method=ts_bdf2))
  end subroutine new_ts_bdf2

  !> TSRK 4.
  subroutine new_ts_rk4(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=ts_baseline(method=ts_rk4))
  end subroutine new_ts_rk4

  !> TSRK 5dp, adaptive.
  subroutine new_ts_rk5dp(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=ts_baseline(method=ts_rk5dp))
  end subroutine new_ts_rk5dp

  !> Creates the TS of the run (start_petsc); a failure if PETSc fails, or for constraints, which
  !> the TS baselines take none of (the registry says so, and the input refuses them).
  subroutine start(self, choice, model, constraints, z0, failure)
    class(ts_baseline), intent(inout), target :: self
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call start_petsc(self, choice, model, constraints, z0, ierr)
    call fail_on_code(failure, ierr, 'ts_baseline%start', 'PETSc could not set up the TS')
    if (.not. failure%failed()) call refuse_other_problem_forms(self%ts, failure)
    if (size(constraints) > 0) call fail(failure, failure_input, 'the PETSc TS baselines take no constraints', &
                                         'ts_baseline%start')
  end subroutine start

  !> Frees the PETSc objects; a failure if PETSc fails.
  subroutine release(self, failure)
    class(ts_baseline), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call release_petsc(self, ierr)
    call fail_on_code(failure, ierr, 'ts_baseline%release', 'PETSc could not free the TS')
  end subroutine release

  !> Integrates to t_old + dt (advance_petsc); a failure only for a PETSc error.
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, failure)
    class(ts_baseline), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call advance_petsc(self, x_old, t_old, dt, guess, x_new, report, ierr)
    call fail_on_code(failure, ierr, 'ts_baseline%advance', 'PETSc failed in TSSolve')
  end subroutine advance

  !> The TS's state becomes x (the time comes with each advance), its step resume_state's; a
  !> failure (failure_mismatch) if `values` are not resume_state's, or if PETSc fails.
  subroutine restore_state(self, values, x, x_previous, failure)
    class(ts_baseline), intent(inout) :: self
    real(real64), intent(in) :: values(:), x(:), x_previous(:)
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    if (size(values) /= 1) then
      call fail(failure, failure_mismatch, 'the stored integrator state is not the TS''s step', &
                'ts_baseline%restore_state')
      return
    end if
    call restore_state_petsc(self, values, x, ierr)
    call fail_on_code(failure, ierr, 'ts_baseline%restore_state', 'PETSc could not restore the TS')
  end subroutine restore_state

  ! Creates the TS of the run for `model` from state z0 at t = 0 with step dt (the first step
  ! for ts_rk5dp), Newton tolerance and iteration limit (implicit methods) and tolerance
  ! tolerance (ts_rk5dp); a TS of an earlier run is destroyed first. It takes no
  ! constraints.
  subroutine start_petsc(self, choice, model, constraints, z0, ierr)
    class(ts_baseline), intent(inout), target :: self
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    PetscErrorCode, intent(out) :: ierr
    SNES :: snes
    TSAdapt :: adapt
    PetscScalar, pointer :: values(:)
    PetscInt :: n, max_iterations, max_evaluations, max_steps

    if (self%created) then
      PetscCall(release_petsc(self, ierr))
    end if
    if (allocated(self%context%model)) deallocate (self%context%model)
    allocate (self%context%model, source=model)
    self%context%implicit = self%method == ts_midpoint .or. self%method == ts_bdf2
    self%context%domain_rejections = 0
    self%snes_iterations = 0
    self%steps = 0
    self%rejections = 0
    self%created = .true.
    n = model%state_size
    PetscCall(VecCreateSeq(PETSC_COMM_SELF, n, self%x, ierr))
    PetscCall(VecGetArrayF90(self%x, values, ierr))
    values = z0
    PetscCall(VecRestoreArrayF90(self%x, values, ierr))
    PetscCall(TSCreate(PETSC_COMM_SELF, self%ts, ierr))
    PetscCall(TSSetProblemType(self%ts, TS_NONLINEAR, ierr))
    PetscCall(TSSetSolution(self%ts, self%x, ierr))
    PetscCall(TSSetRHSFunction(self%ts, PETSC_NULL_VEC, form_rhs, self%context, ierr))
    ierr = eme_ts_set_domain_check(self%ts, c_funloc(stage_inside), c_loc(self%context))
    if (ierr /= 0) return
    select case (self%method)
    case (ts_midpoint)
      PetscCall(TSSetType(self%ts, TSTHETA, ierr))
      PetscCall(TSThetaSetTheta(self%ts, 0.5_real64, ierr))
    case (ts_bdf2)
      PetscCall(TSSetType(self%ts, 'bdf', ierr))   ! PETSc 3.18's Fortran headers lack TSBDF
      PetscCall(TSBDFSetOrder(self%ts, 2, ierr))
    case (ts_rk4)
      PetscCall(TSSetType(self%ts, TSRK, ierr))
      PetscCall(TSRKSetType(self%ts, TSRK4, ierr))
    case (ts_rk5dp)
      PetscCall(TSSetType(self%ts, TSRK, ierr))
      PetscCall(TSRKSetType(self%ts, TSRK5DP, ierr))
    end select
    if (self%context%implicit) then
      PetscCall(MatCreateSeqDense(PETSC_COMM_SELF, n, n, PETSC_NULL_SCALAR, self%jacobian, ierr))
      PetscCall(TSSetRHSJacobian(self%ts, self%jacobian, self%jacobian, form_rhs_jacobian, self%context, ierr))
      PetscCall(TSGetSNES(self%ts, snes, ierr))
      max_iterations = choice%newton_max_iterations
      max_evaluations = 10000
      PetscCall(SNESSetTolerances(snes, choice%newton_tol, 0.0_real64, 0.0_real64, max_iterations, max_evaluations, ierr))
      PetscCall(set_direct_solver(snes, ierr))
    end if
    PetscCall(TSSetTime(self%ts, 0.0_real64, ierr))
    PetscCall(TSSetTimeStep(self%ts, choice%dt, ierr))
    max_steps = 1000000000
    PetscCall(TSSetMaxSteps(self%ts, max_steps, ierr))
    PetscCall(TSSetExactFinalTime(self%ts, TS_EXACTFINALTIME_MATCHSTEP, ierr))
    ! A step that fails ends TSSolve with a negative converged reason, not a PETSc error.
    PetscCall(TSSetErrorIfStepFails(self%ts, PETSC_FALSE, ierr))
    PetscCall(TSGetAdapt(self%ts, adapt, ierr))
    if (self%method == ts_rk5dp) then
      PetscCall(TSSetTolerances(self%ts, choice%tolerance, PETSC_NULL_VEC, choice%tolerance, PETSC_NULL_VEC, ierr))
    else
      ! Fixed steps: a stage outside the domain ends the run instead of halving the step.
      PetscCall(TSAdaptSetType(adapt, TSADAPTNONE, ierr))
      PetscCall(TSSetMaxStepRejections(self%ts, 0, ierr))
    end if
    PetscCall(TSSetFromOptions(self%ts, ierr))
  end subroutine start_petsc

  ! Frees the PETSc objects.
  subroutine release_petsc(self, ierr)
    class(ts_baseline), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    ierr = 0
    if (.not. self%created) return
    self%created = .false.
    PetscCall(TSDestroy(self%ts, ierr))
    PetscCall(VecDestroy(self%x, ierr))
    if (self%context%implicit) then
      PetscCall(MatDestroy(self%jacobian, ierr))
    end if
  end subroutine release_petsc

  ! Integrates from the TS's current state to t_old + dt. x_old and guess are not needed: the
  ! TS carries its state (and BDF2 its history) from one output step to the next.
  subroutine advance_petsc(self, x_old, t_old, dt, guess, x_new, report, ierr)
    class(ts_baseline), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: values(:)
    TSConvergedReason :: converged
    SNES :: snes
    PetscInt :: snes_iterations, steps, rejections
    character(len=80) :: text

    report%reason = ''
    report%last_rejection = ''
    allocate (report%scheme_temperature(self%context%model%temperature_count()))
    report%scheme_temperature = 0.0_real64
    self%context%domain_rejections = 0
    ! Start from the exact output time: the TS's own sum of steps drifts by rounding, and a
    ! remainder of 1e-16 s would become a step of its own (which t + dt cannot even resolve).
    ! For the fixed-step methods, reset dt too: after landing on an output time the TS keeps
    ! the shortened last step as its next one. They then take exactly one step of dt.
    PetscCall(TSSetTime(self%ts, t_old, ierr))
    PetscCall(TSSetMaxTime(self%ts, t_old + dt, ierr))
    if (self%method /= ts_rk5dp) then
      PetscCall(TSSetTimeStep(self%ts, dt, ierr))
    else
      ! Dormand-Prince's first stage is the last one's f (FSAL), which TS carries from one solve to
      ! the next; a continued run (-eme_continue) starts without it and computes f at the stored
      ! state, which differs from the last stage's in the last bits. Each output step starts
      ! afresh instead, so that a continued run is the uninterrupted one bit for bit (one more
      ! field evaluation an output step).
      PetscCall(TSRestartStep(self%ts, ierr))
    end if
    PetscCall(TSSolve(self%ts, self%x, ierr))
    PetscCall(TSGetConvergedReason(self%ts, converged, ierr))
    report%converged_reason = int(converged)
    report%residual_norm = no_residual
    if (self%context%implicit) then
      PetscCall(TSGetSNES(self%ts, snes, ierr))
      PetscCall(SNESGetFunctionNorm(snes, report%residual_norm, ierr))
    end if
    PetscCall(TSGetTimeStep(self%ts, self%next_step, ierr))
    PetscCall(TSGetSNESIterations(self%ts, snes_iterations, ierr))
    PetscCall(TSGetStepNumber(self%ts, steps, ierr))
    PetscCall(TSGetStepRejections(self%ts, rejections, ierr))
    report%newton_iterations = int(snes_iterations - self%snes_iterations)
    report%solves = int(steps - self%steps)
    report%rejected = int(rejections - self%rejections)
    self%snes_iterations = snes_iterations
    self%steps = steps
    self%rejections = rejections
    PetscCall(VecGetArrayReadF90(self%x, values, ierr))
    x_new = values
    PetscCall(VecRestoreArrayReadF90(self%x, values, ierr))
    if (converged < 0) then
      select case (converged)
      case (TS_DIVERGED_NONLINEAR_SOLVE)
        report%reason = 'PETSc TS: the Newton solve of an implicit step diverged (TS_DIVERGED_NONLINEAR_SOLVE)'
      case (TS_DIVERGED_STEP_REJECTED)
        if (self%context%domain_rejections > 0) then
          report%reason = 'PETSc TS: a stage left the model''s domain, a non-positive temperature or length ' &
                          //'(TS_DIVERGED_STEP_REJECTED)'
        else
          report%reason = 'PETSc TS: too many rejected steps (TS_DIVERGED_STEP_REJECTED)'
        end if
      case default
        write (text, '(a, i0)') 'PETSc TS did not converge, TSConvergedReason ', converged
        report%reason = trim(text)
      end select
      return
    end if
    call accept_in_domain(self%context%model, x_new, report)
  end subroutine advance_petsc

  !> What an output step leaves for the next beyond the state: the step TS holds (ts_rk5dp's
  !> next trial step). A multistep method's history (BDF2's earlier states) is not kept: a
  !> continued ts_bdf2 run starts again as at t = 0, with one step of order 1, and is correct to
  !> its order, not bit for bit (docs/faults.md).
  subroutine resume_state(self, values)
    class(ts_baseline), intent(in) :: self
    real(real64), allocatable, intent(inout) :: values(:)

    values = [self%next_step]
  end subroutine resume_state

  ! The TS's state becomes x, its step values(1) (restore_state has checked the size).
  subroutine restore_state_petsc(self, values, x, ierr)
    class(ts_baseline), intent(inout) :: self
    real(real64), intent(in) :: values(:), x(:)
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: state(:)

    PetscCall(VecGetArrayF90(self%x, state, ierr))
    state = x(1:size(state))
    PetscCall(VecRestoreArrayF90(self%x, state, ierr))
    PetscCall(TSSetTimeStep(self%ts, values(1), ierr))
  end subroutine restore_state_petsc

  !> The TS as the options database left it (after TSSetFromOptions): type, adaptivity and
  !> tolerances, and for the implicit methods their SNES and linear solver; PETSc's names of the
  !> TS converged reasons (/converged_reason holds TSSolve's of each output step).
  function describe_solver(self) result(report)
    class(ts_baseline), intent(in) :: self
    type(solver_report) :: report
    PetscErrorCode :: ierr

    type(failure_type) :: failure

    call describe_ts(self%ts, 'PETSc TS', self%context%implicit, report, ierr)
    if (ierr == 0) call set_petsc_reasons(report, reasons_ts, failure)
    if (ierr /= 0 .or. failure%failed()) call add_setting(report, text_setting('error', 'PETSc could not describe the TS'))
  end function describe_solver

  ! Dense LU for the implicit methods' Newton solves, as for the EME schemes.
  subroutine set_direct_solver(snes, ierr)
    SNES, intent(in) :: snes
    PetscErrorCode, intent(out) :: ierr
    KSP :: ksp
    PC :: pc

    PetscCall(SNESGetKSP(snes, ksp, ierr))
    PetscCall(KSPSetType(ksp, KSPPREONLY, ierr))
    PetscCall(KSPGetPC(ksp, pc, ierr))
    PetscCall(PCSetType(pc, PCLU, ierr))
  end subroutine set_direct_solver

  ! TS callback: f(z) = L grad E + K grad S at z. The stage check keeps the explicit methods'
  ! stages inside the model's domain; a Newton iterate of an implicit method can leave it, and
  ! then the field is NaN and the SNES is told (SNESSetFunctionDomainError).
  subroutine form_rhs(ts, time, x, f, context, ierr)
    TS, intent(in) :: ts
    PetscReal, intent(in) :: time
    Vec, intent(in) :: x
    Vec, intent(in) :: f
    type(rhs_context), intent(in) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscScalar, pointer :: x_values(:), f_values(:)
    integer :: stat
    SNES :: snes

    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(VecGetArrayF90(f, f_values, ierr))
    call context%model%continuous_field(x_values, f_values, stat)
    if (stat /= 0) f_values = ieee_nan()
    PetscCall(VecRestoreArrayF90(f, f_values, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    if (stat /= 0 .and. context%implicit) then
      PetscCall(TSGetSNES(ts, snes, ierr))
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine form_rhs

  ! TS callback: df/dz = (df/dz at fixed partials) + (df/dpartials)(dpartials/dz).
  subroutine form_rhs_jacobian(ts, time, x, jacobian, preconditioner, context, ierr)
    TS, intent(in) :: ts
    PetscReal, intent(in) :: time
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian
    Mat, intent(in) :: preconditioner
    type(rhs_context), intent(in) :: context
    PetscErrorCode, intent(out) :: ierr
    SNES :: snes
    PetscScalar, pointer :: x_values(:), entries(:, :)
    integer :: stat

    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(MatDenseGetArrayF90(preconditioner, entries, ierr))
    block
      real(real64) :: f(context%model%state_size)

      call context%model%continuous_field(x_values, f, stat, entries)
      if (stat /= 0) entries = 0.0_real64
    end block
    PetscCall(MatDenseRestoreArrayF90(preconditioner, entries, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    PetscCall(assemble_jacobian(jacobian, preconditioner, ierr))
    if (stat /= 0) then
      PetscCall(TSGetSNES(ts, snes, ierr))
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine form_rhs_jacobian

  ! TS stage domain check (called through ts_domain.c): 1 if the stage lies in the model's
  ! domain (positive temperatures and spring lengths, finite values), else 0, counted.
  integer(c_int) function stage_inside(state, n, context) bind(C)
    integer(c_int), value, intent(in) :: n
    real(c_double), intent(in) :: state(n)
    type(c_ptr), value, intent(in) :: context
    type(rhs_context), pointer :: rhs
    integer :: stat

    call c_f_pointer(context, rhs)
    stat = 1
    if (all(abs(state) <= huge(1.0_real64))) call in_domain(rhs%model, state, stat)
    stage_inside = merge(1_c_int, 0_c_int, stat == 0)
    if (stat /= 0) rhs%domain_rejections = rhs%domain_rejections + 1
  end function stage_inside

  ! stat = 0 if the model's partials exist at `state` (positive lengths and temperatures).
  subroutine in_domain(model, state, stat)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: state(:)
    integer, intent(out) :: stat
    real(real64) :: partials(model%max_invariants, 2, model%subsystem_count())

    call model%exact_partials(state, partials, stat=stat)
  end subroutine in_domain

  pure real(real64) function ieee_nan()
    use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
    ieee_nan = ieee_value(1.0_real64, ieee_quiet_nan)
  end function ieee_nan

end module ts_stepper
