!> A model whose state is split over the ranks of an MPI communicator and stepped there, each rank
!> holding its own part (the spring chain's sparse path: docs/formulation.md section 10, "Sparse
!> and distributed"). It is what the distributed time loop (src/run/distributed_simulation) asks
!> of such a model: start from the scene's initial state, take a step, sum the balances'
!> quantities over the ranks, hand over the rank's part of the state for a snapshot (and take it
!> back, to continue a run), and finish.
!> Every procedure but `part` is collective: all ranks call it, in the same order.
module distributed_model
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use butcher_tableaux, only: butcher_tableau
  use failures, only: failure_type, fail, failure_input
  use solver_description, only: solver_report
  implicit none (type, external)
  private
  public :: distributed_system, distributed_settings, distributed_step, distributed_figures, distributed_part

  !> What a run asks of the steps (the input's &integrator, src/integrator/integrator_settings).
  type :: distributed_settings
    character(len=:), allocatable :: input_file      !! named in refusals
    character(len=16) :: scheme = 'eme'
    real(real64) :: dt = 0.0_real64                  !! the time loop's step (a TS's first step)
    integer :: discrete_gradient = 1
    integer :: metric = 1
    real(real64) :: newton_tol = 1.0e-8_real64
    integer :: newton_max_iterations = 50
    logical :: tolerance_given = .false.
    real(real64) :: tolerance = 1.0e-10_real64       !! an adaptive integrator's (ts_rk5dp's) error per step
    real(real64) :: t_end = 0.0_real64               !! where the run ends (adaptive steps land on it)
    !> A relaxed Runge-Kutta scheme's tableau (src/scheme/butcher_tableaux, given by the run; no
    !> stages for other schemes)
    type(butcher_tableau) :: tableau
  end type distributed_settings

  !> One step's solve, the same on every rank.
  type :: distributed_step
    logical :: converged = .false.
    integer :: iterations = 0                  !! Newton iterations
    integer :: solves = 1                      !! the integrator's own steps in it (a TS's)
    integer :: rejected = 0                    !! of them, rejected
    integer :: reason = 0                      !! the solver's converged reason (SNES's, or TS's)
    real(real64) :: residual_norm = 0.0_real64
    character(len=:), allocatable :: failure   !! why it did not converge, in words
    !> The step chose the time it reached, `time` (exactly t_end on the last step: an adaptive or a
    !> relaxed step), as the dense path's step_report says; otherwise it reached n dt.
    logical :: chose_time = .false.
    real(real64) :: time = 0.0_real64
    !> halves that replaced the step (substeps - 1: a fixed step without a root, a relaxed step
    !> without a relaxation root)
    integer :: halvings = 0
    !> trial steps rejected (by step-size control; a relaxed step's attempts replaced by halves)
    integer :: rejected_steps = 0
    !> the step's own figures: a step controller's datasets (src/integrator/distributed_step_control),
    !> or the per-step figures the dense path's integrator of the same name declares (its registry
    !> entry's `diagnostics`, src/integrator/stepper) for a system whose integrator_diagnostics is true
    real(real64), allocatable :: diagnostics(:)
  end type distributed_step

  !> The balances' quantities of the state and of the last step to it, summed over the ranks
  !> (src/structure/step_balances names the scales): the step's differences are sums of the
  !> parts' differences, free of the cancellation of a difference of two sums of 10^5 terms.
  type :: distributed_figures
    real(real64) :: energy = 0.0_real64, energy_scale = 0.0_real64
    real(real64) :: entropy = 0.0_real64, entropy_scale = 0.0_real64
    real(real64) :: delta_energy = 0.0_real64, delta_entropy = 0.0_real64     !! of the last step
    real(real64) :: angular_momentum(3) = 0.0_real64                          !! J = sum_i x_i x p_i
    integer :: conserved_count = 0                                             !! conserved momenta
    real(real64) :: conserved(3) = 0.0_real64, delta_conserved(3) = 0.0_real64, momentum_scale = 0.0_real64
    real(real64) :: min_temperature = huge(1.0_real64)                         !! [K]
    !> the last step's smallest entropy production of a viscous branch and of a conducting link
    !> [W/K] (huge if the model has none)
    real(real64) :: min_viscous_production = huge(1.0_real64), min_link_production = huge(1.0_real64)
  end type distributed_figures

  !> The rank's part of the state as a snapshot holds it (src/io/hdf5_snapshots): the whole
  !> state's counts, the rank's first mass and spring, its masses' positions and momenta
  !> (dimension x masses), its springs' gamma (none without a viscous branch), tau and
  !> temperatures (none without temperatures).
  type :: distributed_part
    integer :: masses = 0, springs = 0, dimension = 3
    integer :: first_mass = 1, first_spring = 1, spring_count = 0
    real(real64), allocatable :: positions(:, :), momenta(:, :), gamma(:), tau(:), theta(:)
  end type distributed_part

  !> A model split over ranks.
  type, abstract :: distributed_system
    !> A step of the system's own size does not pass this time (the next output time of
    !> &output interval; the time loop sets it before each step), as time_stepper's stop_time.
    real(real64) :: stop_time = huge(1.0_real64)
  contains
    procedure(start_interface), deferred :: start
    procedure(step_interface), deferred :: step
    procedure(figures_interface), deferred :: figures
    procedure(part_interface), deferred :: part
    procedure(restore_interface), deferred :: restore
    procedure(finish_interface), deferred :: finish
    procedure(describe_interface), deferred :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
    procedure :: state_rows
    procedure :: set_state_rows
    procedure :: field_rows
    procedure :: integrator_diagnostics
    procedure :: accuracy_warnings
    procedure :: step_again_tightly
    procedure :: tighten_linear_solves
  end type distributed_system

  abstract interface
    !> Sets the system up on `comm` (an MPI communicator's Fortran handle) from the scene's
    !> `model` and initial state z0 (the whole state, on every rank); a failure (failure_input)
    !> if it cannot run what `settings` ask, naming the field.
    subroutine start_interface(self, settings, model, z0, comm, failure)
      import :: distributed_system, distributed_settings, generic_model, real64, failure_type
      class(distributed_system), intent(inout), target :: self
      type(distributed_settings), intent(in) :: settings
      class(generic_model), intent(in) :: model
      real(real64), intent(in) :: z0(:)
      integer, intent(in) :: comm
      type(failure_type), intent(out) :: failure
    end subroutine start_interface

    !> One step of size dt from the current state; the state moves only if the solve converged.
    subroutine step_interface(self, dt, outcome, failure)
      import :: distributed_system, distributed_step, real64, failure_type
      class(distributed_system), intent(inout) :: self
      real(real64), intent(in) :: dt
      type(distributed_step), intent(out) :: outcome
      type(failure_type), intent(out) :: failure
    end subroutine step_interface

    !> The figures of the current state and of the step to it (zero differences before a step).
    subroutine figures_interface(self, values, failure)
      import :: distributed_system, distributed_figures, failure_type
      class(distributed_system), intent(inout) :: self
      type(distributed_figures), intent(out) :: values
      type(failure_type), intent(out) :: failure
    end subroutine figures_interface

    !> The rank's part of the current state.
    subroutine part_interface(self, state, failure)
      import :: distributed_system, distributed_part, failure_type
      class(distributed_system), intent(inout) :: self
      type(distributed_part), intent(out) :: state
      type(failure_type), intent(out) :: failure
    end subroutine part_interface

    !> Makes `state`, the rank's part as `part` gives it (a continued run's last snapshot), the
    !> current state; tau is the state's thermodynamic variable (theta is not read).
    subroutine restore_interface(self, state, failure)
      import :: distributed_system, distributed_part, failure_type
      class(distributed_system), intent(inout) :: self
      type(distributed_part), intent(in) :: state
      type(failure_type), intent(out) :: failure
    end subroutine restore_interface

    !> The solver of the steps as the run file records it (after the options were applied) and
    !> the legend of its converged reasons.
    function describe_interface(self) result(report)
      import :: distributed_system, solver_report
      class(distributed_system), intent(in) :: self
      type(solver_report) :: report
    end function describe_interface

    !> Frees what `start` made; `failure` keeps a failure it comes in with.
    subroutine finish_interface(self, failure)
      import :: distributed_system, failure_type
      class(distributed_system), intent(inout) :: self
      type(failure_type), intent(inout) :: failure
    end subroutine finish_interface
  end interface

contains

  !> What a step leaves for the next that a continued run needs (src/run/run_output's resume
  !> record keeps it at every snapshot): none unless the system says.
  subroutine resume_state(self, values)
    class(distributed_system), intent(in) :: self
    real(real64), allocatable, intent(out) :: values(:)

    allocate (values(0))
  end subroutine resume_state

  !> Takes back, at `time`, what resume_state gave (after `start` and `restore`).
  subroutine restore_state(self, time, values, failure)
    class(distributed_system), intent(inout) :: self
    real(real64), intent(in) :: time, values(:)
    type(failure_type), intent(out) :: failure

    if (size(values) > 0) call fail(failure, failure_input, 'the stored integrator state does not fit this split '// &
                                    'system (it keeps none)', 'restore_state')
  end subroutine restore_state

  !> The rank's rows of the state (its unknowns, as the DM numbers them): what a step controller
  !> keeps to go back to. A failure unless the system offers it.
  subroutine state_rows(self, z, failure)
    class(distributed_system), intent(inout) :: self
    real(real64), allocatable, intent(out) :: z(:)
    type(failure_type), intent(out) :: failure

    allocate (z(0))
    call fail(failure, failure_input, 'this split system offers no rows of its state', 'state_rows')
  end subroutine state_rows

  !> Makes the rank's rows z the current state, and z_old the state its step's figures
  !> (differences, productions) start from. Collective.
  subroutine set_state_rows(self, z, z_old, failure)
    class(distributed_system), intent(inout) :: self
    real(real64), intent(in) :: z(:), z_old(:)
    type(failure_type), intent(out) :: failure

    call fail(failure, failure_input, 'this split system cannot take rows of a state', 'set_state_rows')
  end subroutine set_state_rows

  !> The rank's rows of the model's continuous vector field f(z) at the state whose rows are z
  !> (every rank its own; collective); stat: a domain code where a spring of z is outside its
  !> domain (f is then not all defined).
  subroutine field_rows(self, z, f, stat, failure)
    class(distributed_system), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    type(failure_type), intent(out) :: failure

    f = 0.0_real64
    stat = 0
    call fail(failure, failure_input, 'this split system offers no field', 'field_rows')
  end subroutine field_rows
  !> Whether each step's outcome carries the per-step figures the dense path's integrator of the
  !> same name declares (distributed_step%diagnostics); none by default.
  pure logical function integrator_diagnostics(self)
    class(distributed_system), intent(in) :: self

    integrator_diagnostics = .false.
  end function integrator_diagnostics

  !> Solves the last step again, from the state it started from, with tighter linear solves than
  !> the default's (a step that broke a guaranteed balance: src/run/split_run_path): `again`
  !> says whether the system has such settings; if it has none (the default), nothing changes.
  !> Collective.
  subroutine step_again_tightly(self, outcome, again, failure)
    class(distributed_system), intent(inout) :: self
    type(distributed_step), intent(out) :: outcome
    logical, intent(out) :: again
    type(failure_type), intent(out) :: failure

    again = .false.
    outcome%converged = .false.
    failure = failure_type()
  end subroutine step_again_tightly

  !> With `on`, the steps to come solve their linear systems tighter than by default (until
  !> called with .false.); `available` says whether the system has such settings (none by
  !> default). Collective.
  subroutine tighten_linear_solves(self, on, available, failure)
    class(distributed_system), intent(inout) :: self
    logical, intent(in) :: on
    logical, intent(out) :: available
    type(failure_type), intent(out) :: failure

    available = .false.
    failure = failure_type()
  end subroutine tighten_linear_solves

  !> What the run's record says against its accuracy, as the dense path's integrators say it
  !> (src/integrator/stepper's accuracy_warnings; '' if nothing); nothing by default.
  function accuracy_warnings(self) result(text)
    class(distributed_system), intent(in) :: self
    character(len=:), allocatable :: text

    text = ''
  end function accuracy_warnings

end module distributed_model
