!> What the time loop drives: an integrator that advances the run's unknowns x = (z,
!> multipliers of the active constraints) from one output time to the next and reports what
!> happened. The discrete-gradient steps (SNES), the PETSc TS baselines and later families
!> extend it; src/integrator/integrator_registry builds them by name. An integrator reports its
!> solver's settings as the solver used them (`describe_solver`, after `start`; none by
!> default) and, with each step, the final residual norm and converged reason of its last solve.
module stepper
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_settings, only: integrator_choice
  use solver_description, only: solver_report, no_solver
  use failures, only: failure_type, fail, failure_mismatch
  implicit none (type, external)
  private
  public :: time_stepper, step_report, step_diagnostic, solver_report, no_residual, accept_in_domain

  !> The residual norm of a step that solves no nonlinear system: NaN.
  real(real64), parameter :: no_residual = transfer(int(z'7FF8000000000000', int64), 1.0_real64)

  !> How a step went.
  type :: step_report
    logical :: accepted = .false.
    integer :: strategy = 0              !! what found the root (retry_strategies' strategy_*; 0 for TS)
    integer :: newton_iterations = 0     !! summed over every solve of the step
    integer :: solves = 0                !! nonlinear solves (continuation stages included), or TS steps taken
    integer :: rejected = 0              !! roots rejected as unphysical, or TS steps rejected
    integer :: halvings = 0              !! failed attempts replaced by two halves (EME's substeps, relaxed RK)
    integer :: rejected_steps = 0        !! trial steps rejected by step-size control before the accepted one
    real(real64), allocatable :: scheme_temperature(:)   !! the temperatures the step's K0 used
    character(len=:), allocatable :: reason              !! why the step failed (if it did)
    character(len=:), allocatable :: last_rejection      !! why the last rejected root was rejected
    logical :: chose_time = .false.      !! the integrator chose the time it reached: `time`
    real(real64) :: time = 0.0_real64
    real(real64), allocatable :: diagnostics(:)   !! the integrator's own per-step figures (its `diagnostics`)
    !> 2-norm of the final residual of the step's last nonlinear solve, as the solver's
    !> convergence test measured it; NaN if the step solves none.
    real(real64) :: residual_norm = no_residual
    integer :: converged_reason = 0      !! the solver's converged reason of that solve (describe_solver's legend)
  end type step_report

  !> A per-step figure an integrator records beyond step_report's fields (a dataset of its own).
  type :: step_diagnostic
    character(len=24) :: name = ''
    character(len=8) :: units = ''
    character(len=200) :: description = ''
    !> A file row that stands for several steps (&output every) holds the 'last' step's value,
    !> or the 'sum', 'min', 'max' or 'mean' over them.
    character(len=4) :: combine = 'last'
  end type step_diagnostic

  !> An integrator of one run at a time; `start` may reuse what an earlier run set up. An
  !> integrator that chooses its own times (relaxation, adaptive steps) reports them in
  !> step_report%time and the run goes on until t_end; the others step to n dt.
  type, abstract :: time_stepper
    character(len=16) :: scheme = ''     !! the registry name it was built for
    !> An integrator that chooses its times does not step past this time: the step that reaches
    !> it lands on it (the time loop sets it to the next output time of &output interval).
    real(real64) :: stop_time = huge(1.0_real64)
  contains
    procedure(start_interface), deferred :: start
    procedure(advance_interface), deferred :: advance
    procedure(release_interface), deferred :: release
    procedure :: diagnostics
    procedure :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
    procedure :: accuracy_warnings
    procedure :: resolve
  end type time_stepper

  abstract interface
    !> Prepares a run of `model` from state z0 at t = 0 with the active `constraints`. A failure
    !> for a library error, or an initial state the integrator cannot take.
    subroutine start_interface(self, choice, model, constraints, z0, failure)
      import :: time_stepper, integrator_choice, generic_model, constraint_slot, real64, failure_type
      class(time_stepper), intent(inout), target :: self
      type(integrator_choice), intent(in) :: choice
      class(generic_model), intent(in) :: model
      type(constraint_slot), intent(in) :: constraints(:)
      real(real64), intent(in) :: z0(:)
      type(failure_type), intent(out) :: failure
    end subroutine start_interface

    !> From x_old (at time t_old) to x_new at t_old + dt; `guess` is a predictor the integrator
    !> may use. A failure only for a library error; a step that cannot be done is reported.
    subroutine advance_interface(self, x_old, t_old, dt, guess, x_new, report, failure)
      import :: time_stepper, step_report, real64, failure_type
      class(time_stepper), intent(inout), target :: self
      real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
      real(real64), intent(out) :: x_new(:)
      type(step_report), intent(out) :: report
      type(failure_type), intent(out) :: failure
    end subroutine advance_interface

    !> Frees what the stepper holds (library objects); it can start again afterwards.
    subroutine release_interface(self, failure)
      import :: time_stepper, failure_type
      class(time_stepper), intent(inout) :: self
      type(failure_type), intent(out) :: failure
    end subroutine release_interface
  end interface

contains

  !> The integrator's own per-step figures, in the order of step_report%diagnostics; none by default.
  function diagnostics(self) result(specs)
    class(time_stepper), intent(in) :: self
    type(step_diagnostic), allocatable :: specs(:)

    allocate (specs(0))
  end function diagnostics

  !> The solver's settings as the solver holds them after `start` (command-line options
  !> applied), and the legend of step_report%converged_reason; by default, no solver.
  function describe_solver(self) result(report)
    class(time_stepper), intent(in) :: self
    type(solver_report) :: report

    report = no_solver('the integrator reports no solver')
  end function describe_solver

  !> What the integrator carries from one step to the next beyond the unknowns (docs/faults.md,
  !> Continuing a run), as numbers that restore_state takes back; none by default.
  subroutine resume_state(self, values)
    class(time_stepper), intent(in) :: self
    real(real64), allocatable, intent(inout) :: values(:)

    if (allocated(values)) then
      if (size(values) == 0) return
      deallocate (values)
    end if
    allocate (values(0))
  end subroutine resume_state

  !> Takes back what resume_state gave after `start`, at the state x reached from x_previous.
  !> A failure (failure_mismatch) if `values` are not the integrator's; by default there is
  !> nothing to take.
  subroutine restore_state(self, values, x, x_previous, failure)
    class(time_stepper), intent(inout) :: self
    real(real64), intent(in) :: values(:), x(:), x_previous(:)
    type(failure_type), intent(out) :: failure
    if (size(values) /= 0) call fail(failure, failure_mismatch, 'the stored integrator state has '// &
                                     'values this integrator does not keep', 'time_stepper%restore_state')
  end subroutine restore_state

  !> What the integrator's record of the run so far says against trusting its accuracy, as one
  !> text with the figures behind it ('' if nothing); by default nothing.
  function accuracy_warnings(self) result(text)
    class(time_stepper), intent(in) :: self
    character(len=:), allocatable :: text

    text = ''
  end function accuracy_warnings

  !> The step of h from x_old (at t_old) solved again with the model's default solver settings,
  !> whatever the command line set, and to the solver's rounding floor: the time loop's remedy for
  !> an accepted step that broke a balance the integrator guarantees (src/run/step_check). By
  !> default an integrator has no other settings: the step is not accepted, with the reason.
  subroutine resolve(self, x_old, t_old, h, guess, x_new, report, failure)
    class(time_stepper), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, h, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    type(failure_type), intent(out) :: failure

    x_new = x_old
    report%accepted = .false.
    report%reason = 'the integrator has no default solver settings to solve it again with'
    failure = failure_type()
  end subroutine resolve

  !> Accepts a step whose end state z_new is finite and in the model's domain (its temperatures
  !> then go to report%scheme_temperature); otherwise says why not.
  subroutine accept_in_domain(model, z_new, report)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z_new(:)
    type(step_report), intent(inout) :: report
    real(real64) :: energy, entropy
    integer :: stat

    call model%observe(z_new, energy, entropy, report%scheme_temperature, stat)
    report%accepted = stat == 0 .and. all(abs(z_new) <= huge(1.0_real64))
    if (.not. report%accepted) report%reason = 'the state left the model''s domain (a non-positive temperature, or a blow-up)'
  end subroutine accept_in_domain

end module stepper
