!> The rules that the one time loop (src/run/time_loop) and its two paths, the dense run's
!> (src/run/dense_run_path) and the split run's (src/run/split_run_path), apply alike, each
!> written once: the stop rules at the top of a step, where a step lands and whether it is the
!> last, the status of a step that failed, the summary's figures after an accepted step, the
!> completion, and how a failure that is not the method's is recorded (docs/architecture.md, The
!> time loop).
module time_loop_steps
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan
  use run_outcome, only: run_summary, step_failure_kind, failure_none, failure_solver, failure_domain, failure_input, &
                         failure_io, failure_interrupted, failure_step_budget, failure_balance
  use run_signals, only: interrupting_signal, signal_name
  use number_text, only: integer_text, fixed_text
  use failures, only: failure_type, set_failure => fail, code_input => failure_input, code_io => failure_io, &
                      code_interrupted => failure_interrupted, code_library => failure_library
  implicit none (type, external)
  private
  public :: run_observer, line_reporter, exit_status, failure_code_of, record_failure
  public :: step_budget_spent, stop_before_step, land_step, step_status, fail_step, note_petsc_error, fail_write
  public :: accumulate_step, lower_min_temperature, note_balance_figures, complete_if_finished
  public :: next_output_stop, pass_output_times

  !> Something that wants control after every accepted step (the ensemble's scheduler serves
  !> other ranks from there while rank 0 computes a case).
  type, abstract :: run_observer
  contains
    procedure(after_step_interface), deferred :: after_step
  end type run_observer

  abstract interface
    !> Called after each accepted step.
    subroutine after_step_interface(self)
      import :: run_observer
      class(run_observer), intent(inout) :: self
    end subroutine after_step_interface

    !> Receives a line for the user (progress, a study's start and warnings); the driver prints it.
    subroutine line_reporter(text)
      character(len=*), intent(in) :: text
    end subroutine line_reporter
  end interface

contains

  !> The exit status a driver gives a run: 0 complete, 3 stopped early by the method (solver,
  !> domain), 2 input it cannot run, 1 output or library failure, 128 + N after signal N.
  integer function exit_status(summary)
    type(run_summary), intent(in) :: summary

    select case (summary%failure_kind)
    case (failure_none)
      exit_status = 0
    case (failure_solver, failure_domain, failure_step_budget, failure_balance)
      exit_status = 3
    case (failure_input)
      exit_status = 2
    case (failure_interrupted)
      exit_status = 128 + interrupting_signal()
    case default
      exit_status = 1
    end select
  end function exit_status

  !> The failures' code of a run's failure kind (a word of run_outcome).
  pure integer function failure_code_of(kind)
    character(len=*), intent(in) :: kind

    select case (kind)
    case (failure_input)
      failure_code_of = code_input
    case (failure_io)
      failure_code_of = code_io
    case (failure_interrupted)
      failure_code_of = code_interrupted
    case default
      failure_code_of = code_library
    end select
  end function failure_code_of

  !> Records a failure that is not the method's, of failure kind `kind`, with its message and the
  !> input file as its origin; the first one wins.
  pure subroutine record_failure(failure, summary, kind, text, input_file)
    type(failure_type), intent(inout) :: failure
    type(run_summary), intent(inout) :: summary
    character(len=*), intent(in) :: kind, text, input_file

    if (failure%failed()) return
    call set_failure(failure, failure_code_of(kind), text, input_file)
    summary%failure_kind = kind
  end subroutine record_failure

  !> Whether the step budget (&integrator max_steps) is spent after `steps` accepted steps.
  pure logical function step_budget_spent(steps, max_steps)
    integer(int64), intent(in) :: steps
    integer, intent(in) :: max_steps

    step_budget_spent = steps >= max_steps
  end function step_budget_spent

  !> The stop rules at the top of a step: a signal (`signal`, 0 if none) or a spent step budget
  !> ends the run before step steps + 1, with its status and failure kind; .true. if it ends.
  logical function stop_before_step(signal, budget_spent, steps, time, t_end, summary) result(stop)
    integer, intent(in) :: signal
    logical, intent(in) :: budget_spent
    integer(int64), intent(in) :: steps
    real(real64), intent(in) :: time, t_end
    type(run_summary), intent(inout) :: summary

    stop = .true.
    if (signal /= 0) then
      summary%status = 'incomplete: interrupted by '//signal_name(signal)
      summary%failure_kind = failure_interrupted
    else if (budget_spent) then
      summary%status = 'incomplete: the step budget is spent: '//integer_text(steps)//' steps reached t = '// &
                       fixed_text(time, 6)//' s of t_end = '//fixed_text(t_end, 6)//' s (raise &integrator max_steps)'
      summary%failure_kind = failure_step_budget
    else
      stop = .false.
    end if
  end function stop_before_step

  !> Where step `step` landed and whether it is the run's last: a fixed step lands on step*dt and
  !> the last is the planned one; an integrator's own step (`chose_time`) at the time it reached
  !> (`reached`), the last at t_end.
  pure subroutine land_step(chose_time, reached, step, dt, t_end, steps_planned, time, finished)
    logical, intent(in) :: chose_time
    real(real64), intent(in) :: reached, dt, t_end
    integer(int64), intent(in) :: step, steps_planned
    real(real64), intent(out) :: time
    logical, intent(out) :: finished

    if (chose_time) then
      time = reached
      finished = time >= t_end
    else
      time = step*dt
      finished = step == steps_planned
    end if
  end subroutine land_step

  !> Where a step that chooses its time stops with &output interval (`interval`): at the next output
  !> time after `outputs_passed`, or at t_end when that is within rounding of it (199*0.3 =
  !> 59.699999999999996 for t_end = 59.7: else the run lands there and is left a sliver of 7e-15 s).
  pure real(real64) function next_output_stop(outputs_passed, interval, t_end) result(stop_time)
    integer, intent(in) :: outputs_passed
    real(real64), intent(in) :: interval, t_end

    stop_time = (outputs_passed + 1)*interval
    if (stop_time >= t_end*(1.0_real64 - 8*epsilon(1.0_real64))) stop_time = t_end
  end function next_output_stop

  !> Counts the output times of &output interval (`interval`, 0: none) that `time` reached (within
  !> 8 ulps) into `outputs_passed`; `reached` if it reached one (its point is then written).
  pure subroutine pass_output_times(time, interval, outputs_passed, reached)
    real(real64), intent(in) :: time, interval
    integer, intent(inout) :: outputs_passed
    logical, intent(out) :: reached

    reached = .false.
    if (interval <= 0.0_real64) return
    do while (time >= (outputs_passed + 1)*interval*(1.0_real64 - 8*epsilon(1.0_real64)))
      outputs_passed = outputs_passed + 1
      reached = .true.
    end do
  end subroutine pass_output_times

  !> The status of a run that stopped at step `step` (ending at `time`) for `reason`.
  pure function step_status(step, time, reason) result(status)
    integer(int64), intent(in) :: step
    real(real64), intent(in) :: time
    character(len=*), intent(in) :: reason
    character(len=:), allocatable :: status

    status = 'incomplete: step '//integer_text(step)//' (t = '//fixed_text(time, 4)//' s): '//reason
  end function step_status

  !> A step the integrator could not take (`reason`: its words) ends the run: the status names the
  !> step and the failure kind follows the reason (run_outcome's step_failure_kind).
  pure subroutine fail_step(summary, step, time, reason)
    type(run_summary), intent(inout) :: summary
    integer(int64), intent(in) :: step
    real(real64), intent(in) :: time
    character(len=*), intent(in) :: reason

    summary%status = step_status(step, time, reason)
    summary%failure_kind = step_failure_kind(reason)
  end subroutine fail_step

  !> The status of a run whose step `step` met a PETSc error (the failure says PETSc's words).
  pure subroutine note_petsc_error(summary, step)
    type(run_summary), intent(inout) :: summary
    integer(int64), intent(in) :: step

    summary%status = 'incomplete: PETSc error in step '//integer_text(step)
  end subroutine note_petsc_error

  !> The output file `part` could not be written (`message`: why): the run stops, its status and
  !> failure (failure_io) say so, the failure also what the file keeps (`kept`, run_output's
  !> kept_words).
  pure subroutine fail_write(failure, summary, part, input_file, message, kept)
    type(failure_type), intent(inout) :: failure
    type(run_summary), intent(inout) :: summary
    character(len=*), intent(in) :: part, input_file, message, kept

    summary%status = 'incomplete: cannot write the output file: '//message
    call record_failure(failure, summary, failure_io, 'cannot write the output file '''//part//''' ('//input_file// &
                        '): '//message//kept, input_file)
  end subroutine fail_write

  !> The summary after accepted step `step`: its Newton iterations (a failed step's are not
  !> counted), halvings and rejections, and the run's extremes: the energy's drift
  !> (|E - E_0 - Q| / |E_0|), the smallest entropy and largest V increment of a step, the largest
  !> deviation of a conserved momentum component from its initial value.
  pure subroutine accumulate_step(summary, step, newton_iterations, halvings, rejections, energy_drift, &
                                  entropy_increment, lyapunov_increment, conserved_deviation)
    type(run_summary), intent(inout) :: summary
    integer(int64), intent(in) :: step
    integer, intent(in) :: newton_iterations, halvings, rejections
    real(real64), intent(in) :: energy_drift, entropy_increment, lyapunov_increment
    real(real64), intent(in) :: conserved_deviation(:)     !! |J - J_0| of each conserved component

    summary%steps_completed = step
    summary%newton_iterations = summary%newton_iterations + newton_iterations
    summary%halved_steps = summary%halved_steps + halvings
    summary%rejected_steps = summary%rejected_steps + rejections
    summary%energy_drift = max(summary%energy_drift, energy_drift)
    summary%min_entropy_increment = min(summary%min_entropy_increment, entropy_increment)
    summary%max_lyapunov_increment = max(summary%max_lyapunov_increment, lyapunov_increment)
    if (size(conserved_deviation) > 0) summary%angular_momentum_drift = max(summary%angular_momentum_drift, &
                                                                             maxval(conserved_deviation))
  end subroutine accumulate_step

  !> The lowest temperature so far, with those of a recorded state (`theta`); NaN for good once a
  !> temperature is not finite.
  pure subroutine lower_min_temperature(summary, theta)
    type(run_summary), intent(inout) :: summary
    real(real64), intent(in) :: theta(:)

    if (.not. all(abs(theta) <= huge(1.0_real64))) then
      summary%min_temperature = ieee_value(1.0_real64, ieee_quiet_nan)
    else if (.not. ieee_is_nan(summary%min_temperature)) then
      summary%min_temperature = min(summary%min_temperature, minval(theta))
    end if
  end subroutine lower_min_temperature

  !> The run's largest balance figures (those the model has: `has_balance`), with an accepted step's.
  pure subroutine note_balance_figures(summary, has_balance, figures)
    type(run_summary), intent(inout) :: summary
    logical, intent(in) :: has_balance(:)
    real(real64), intent(in) :: figures(:)

    where (has_balance) summary%max_balance = max(summary%max_balance, figures)
  end subroutine note_balance_figures

  !> A run that finished after `steps` steps, each completed, and met no failure is complete; an
  !> integrator that chose its steps planned t_end/dt of them and took `steps` (a fixed step's
  !> plan is `steps` already). `completed` says whether it is (the caller adds its warnings).
  pure subroutine complete_if_finished(summary, finished, steps, completed)
    type(run_summary), intent(inout) :: summary
    logical, intent(in) :: finished
    integer(int64), intent(in) :: steps
    logical, intent(out) :: completed

    completed = finished .and. summary%steps_completed == steps .and. summary%failure_kind == failure_none
    if (.not. completed) return
    summary%status = 'complete'
    summary%steps_planned = steps
  end subroutine complete_if_finished

end module time_loop_steps
