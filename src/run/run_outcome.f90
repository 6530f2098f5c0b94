!> How a run ended: its status ('complete' or 'incomplete: <reason>'), why it did not complete
!> in a word (the failure kind: the run file's attribute and the study index's column
!> `failure_kind`), and the figures it is judged by (docs/output.md, docs/studies.md).
module run_outcome
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use model_interface, only: generic_model
  implicit none (type, external)
  private
  public :: run_summary, step_failure_kind, open_summary, summarize_model, close_summary
  public :: failure_none, failure_solver, failure_domain, failure_input, failure_io, failure_interrupted, &
            failure_library, failure_step_budget, failure_balance

  !> Why a run did not complete, in a word (file attribute and study index column `failure_kind`).
  character(len=*), parameter :: failure_none = 'none'              !! complete (or not yet run)
  character(len=*), parameter :: failure_solver = 'solver'          !! no acceptable root, or the solver diverged
  character(len=*), parameter :: failure_domain = 'domain'          !! the state left the model's domain
  character(len=*), parameter :: failure_input = 'input'            !! the input cannot be run as given
  character(len=*), parameter :: failure_io = 'io'                  !! the output could not be written
  character(len=*), parameter :: failure_interrupted = 'interrupted'  !! SIGTERM or SIGINT
  character(len=*), parameter :: failure_library = 'library'        !! PETSc or HDF5 failed
  !> the run took &integrator max_steps accepted steps before t_end (integrators that choose their steps)
  character(len=*), parameter :: failure_step_budget = 'step_budget'
  !> an accepted step broke a balance its integrator guarantees, also when solved again with the
  !> model's default solver settings (docs/faults.md, Every accepted step checked)
  character(len=*), parameter :: failure_balance = 'balance'

  !> The figures a run is judged by, as the summary table prints them.
  type :: run_summary
    character(len=:), allocatable :: status       !! 'complete' or 'incomplete: <reason>'
    character(len=:), allocatable :: failure_kind !! one of the failure_* words above
    !> what the driver adds to an early stop's status (why the earlier complete file was kept, ...)
    character(len=:), allocatable :: note
    integer(int64) :: steps_planned = 0
    !> the integrator chose its steps: steps_planned is then t_end/dt's count (a fixed step's plan) until it completes
    logical :: steps_chosen = .false.
    integer(int64) :: steps_completed = 0
    integer(int64) :: newton_iterations = 0
    real(real64) :: energy_drift = 0.0_real64            !! max_n |E_n - E_0 - Q_n| / |E_0|, Q: boundary heat
    real(real64) :: min_entropy_increment = huge(1.0_real64)    !! NaN without a completed step
    real(real64) :: max_lyapunov_increment = -huge(1.0_real64)  !! NaN without a completed step
    !> max_n |J_n - J_0| of the model's conserved momentum components, the largest over them (J_z
    !> alone for the paper's pendulum); NaN for a model without
    real(real64) :: angular_momentum_drift = 0.0_real64
    !> the conserved components' names separated by blanks ('J_z', 'J_x J_y J_z'); '' if none
    character(len=:), allocatable :: conserved_momentum
    character(len=16) :: energy_units = 'J', entropy_units = 'J/K'   !! the model's, for the summary line
    !> The lowest temperature of any subsystem at any recorded point; NaN once one is not finite.
    real(real64) :: min_temperature = huge(1.0_real64)
    integer(int64) :: halved_steps = 0     !! failed attempts of the completed steps replaced by two halves
    integer(int64) :: rejected_steps = 0   !! trial steps that step-size control rejected (adaptive runs)
    !> what the integrator's record of a complete run says against trusting its accuracy (the
    !> run file's attribute `warnings`, docs/integrators.md); '' if nothing
    character(len=:), allocatable :: warnings
    !> steps that broke a guaranteed balance and were solved again with the default solver settings
    integer(int64) :: resolved_steps = 0
    !> the largest figure of each balance over the run (step_balances' order), NaN where it has none
    real(real64) :: max_balance(4) = -huge(1.0_real64)
    real(real64) :: wall_seconds = 0.0_real64             !! the whole run, file set-up and closing included
    real(real64) :: solve_seconds = 0.0_real64            !! the time loop alone
    !> The CPU time of the run's process (all its threads, user and system) over the same spans:
    !> unlike the wall times, without the time spent waiting for a core that other work holds
    real(real64) :: cpu_seconds = 0.0_real64
    real(real64) :: solve_cpu_seconds = 0.0_real64
  end type run_summary

contains

  !> The failure kind of a step the integrator could not take, from its reason (the solver's
  !> "no root" first: its last attempt may name a non-positive temperature it refused).
  pure function step_failure_kind(reason) result(kind)
    character(len=*), intent(in) :: reason
    character(len=:), allocatable :: kind

    kind = failure_solver
    if (index(reason, 'no root') > 0) return
    if (index(reason, 'domain') > 0 .or. index(reason, 'non-positive') > 0 .or. index(reason, 'blow-up') > 0 .or. &
        index(reason, 'undefined') > 0) kind = failure_domain
  end function step_failure_kind

  !> The summary of a run that starts: running, no failure, `steps_planned` steps.
  pure subroutine open_summary(summary, steps_planned)
    type(run_summary), intent(out) :: summary
    integer(int64), intent(in) :: steps_planned

    summary%note = ''
    summary%warnings = ''
    summary%conserved_momentum = ''
    summary%status = 'incomplete: running'
    summary%failure_kind = failure_none
    summary%steps_planned = steps_planned
  end subroutine open_summary

  !> The model's words in the summary: its units and conserved components' names (and no
  !> momentum drift figure without one).
  pure subroutine summarize_model(summary, model)
    type(run_summary), intent(inout) :: summary
    class(generic_model), intent(in) :: model
    integer :: k

    summary%energy_units = model%words%energy_units
    summary%entropy_units = model%words%entropy_units
    summary%conserved_momentum = ''
    do k = 1, model%conserved_count()
      if (k > 1) summary%conserved_momentum = summary%conserved_momentum//' '
      summary%conserved_momentum = summary%conserved_momentum//trim(model%conserved(k)%name)
    end do
    if (model%conserved_count() == 0) summary%angular_momentum_drift = ieee_value(1.0_real64, ieee_quiet_nan)
  end subroutine summarize_model

  !> The figures a run's summary cannot have, NaN: those of the steps when none completed, the
  !> entropy's, V's and the temperature's for a model without temperatures (elastic springs: S = 0,
  !> V = E), a balance the model has not (`has_balance`: step_balances' applicable_balances).
  pure subroutine close_summary(summary, model, has_balance)
    type(run_summary), intent(inout) :: summary
    class(generic_model), intent(in) :: model
    logical, intent(in) :: has_balance(:)

    if (summary%steps_completed == 0 .or. model%temperature_count() == 0) then
      summary%min_entropy_increment = ieee_value(1.0_real64, ieee_quiet_nan)
      summary%max_lyapunov_increment = ieee_value(1.0_real64, ieee_quiet_nan)
    end if
    if (model%temperature_count() == 0) summary%min_temperature = ieee_value(1.0_real64, ieee_quiet_nan)
    where (.not. has_balance .or. summary%steps_completed == 0) summary%max_balance = ieee_value(1.0_real64, &
                                                                                                 ieee_quiet_nan)
  end subroutine close_summary

end module run_outcome
