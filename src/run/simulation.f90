!> One run from a validated configuration to its HDF5 file: the time loop shared by eme_run and
!> eme_ensemble. The model and its initial state come from the configuration's scene, the
!> integrator from the registry; the loop advances it one output step at a time and records
!> every point and step (src/run/run_output). The file is written as FILE.part and renamed to
!> FILE when the run has ended and the file has been read back; an existing complete FILE is
!> not replaced unless asked (&output overwrite, -eme_overwrite). A run ends early, cleanly, when
!> a step cannot be solved, when SIGTERM or SIGINT arrives, or when the output cannot be
!> written: the file then keeps every step written before, its `status` reads 'incomplete:
!> <reason>' and its `failure_kind` says why in a word. Every write stores the state after its last
!> row (run_output's resume record), so that -eme_continue goes on from there, appending to the
!> file (docs/faults.md, Continuing a run).
module simulation
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_settings, only: step_count
  use integrator_registry, only: integrator_entry, find_integrator, build_integrator
  use stepper, only: time_stepper, step_report
  use run_config, only: run_configuration
  use run_output, only: run_file, extra_attribute
  use resume_records, only: resume_record
  use run_file_steps, only: continuation_wanted, prepare_output, open_run_file, holds_complete_run, &
                            name_finished_file, guard_output_lock
  use time_loop_steps, only: run_observer, line_reporter, exit_status, failure_code_of, record_failure, &
                             step_budget_spent, stop_before_step, land_step, step_status, fail_step, note_petsc_error, fail_write, &
                             accumulate_step, note_balance_figures, complete_if_finished, &
                             next_output_stop, pass_output_times
  use run_outcome, only: run_summary, open_summary, summarize_model, close_summary, failure_none, failure_input, &
                         failure_io, failure_library, failure_balance
  use step_balances, only: balance_count, applicable_balances
  use dense_observation, only: state_observation
  use step_check, only: checked_balances, broken_balance, balance_text
  use run_signals, only: install_interrupt_handlers, interrupting_signal
  use hdf5_files, only: file_template
  use command_line, only: petsc_error_text
  use filesystem, only: output_lock
  use number_text, only: integer_text
  use run_clock, only: run_timer
  use dense_setup, only: dense_max_unknowns, set_up_only, check_dense_size, setup_failure_text
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: run_summary, extra_attribute, run_simulation, run_observer, line_reporter, exit_status, set_up_only
  public :: dense_max_unknowns, holds_complete_run, failure_code_of

  real(real64), parameter :: progress_interval = 2.0_real64   !! seconds between progress lines

contains

  !> Runs `config` and writes its HDF5 file (none if keep_file is .false.: an index-only study).
  !> A failure (its code from the failure kind, its origin the input file), with a message naming
  !> the file, the input file and the OS's reason, if the output could not be written, a library
  !> failed, or the output file holds a complete run that may not be replaced; a run that stops
  !> early is reported through summary%status (and summary%note). Either way
  !> summary%failure_kind says why in a word (src/run/run_outcome's failure_* words).
  !> With `reusable`, the caller's integrator is used when it is of the configured kind (an
  !> ensemble rank keeps its PETSc objects from case to case), replaced otherwise, and left for
  !> the next run; without, the run builds and frees its own. `progress` receives a line at most
  !> every 2 s; `extras` are root attributes added to the file. The finished file is synced to
  !> disk unless `durable` is .false. (an ensemble's case: its index is the record). The run
  !> continues the one its file holds if the command line asks (-eme_continue: else it fails with
  !> failure_input); with `resume_if_possible` instead, it does when it can (an interrupted case of
  !> a study) and starts from t = 0 otherwise. With `lock` (eme_run's lock of the output), the
  !> run checks before each write that the lock file is still the one it holds: one removed or
  !> replaced behind its back stops the run (failure_io), and the file is written once more,
  !> marked with the reason, only if the lock can be taken again (else another writer has it, and
  !> the file is left as the last write made it). The time loop's many exits set `failure` as they
  !> go; summary%note says what the driver adds to a run without one.
  subroutine run_simulation(config, summary, failure, observer, reusable, progress, keep_file, extras, durable, &
                            template, resume_if_possible, lock)
    type(run_configuration), intent(in), target :: config
    type(run_summary), intent(out) :: summary
    type(failure_type), intent(out) :: failure
    class(run_observer), intent(inout), optional :: observer
    class(time_stepper), allocatable, intent(inout), target, optional :: reusable
    procedure(line_reporter), optional :: progress
    logical, intent(in), optional :: keep_file
    type(extra_attribute), intent(in), optional :: extras(:)
    logical, intent(in), optional :: durable
    type(file_template), intent(inout), target, optional :: template
    logical, intent(in), optional :: resume_if_possible
    type(output_lock), intent(inout), optional :: lock
    class(time_stepper), allocatable, target :: own
    class(time_stepper), pointer :: integrator
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    type(integrator_entry) :: entry
    type(step_report) :: report
    type(run_file) :: output
    type(resume_record) :: resume       !! the state a continued run starts from
    character(len=:), allocatable :: part, kind, text, line
    real(real64), allocatable :: x(:), x_previous(:), x_new(:), z0(:), residuals(:)
    real(real64) :: energy_0, entropy_old, lyapunov_old, time, boundary_heat, dt
    real(real64), allocatable :: conserved_0(:)   !! the conserved momentum components at the initial state
    ! The step check (src/run/step_check): the states before and after the step, the step's
    ! figures, which balances are checked, and which momenta are conserved.
    type(state_observation) :: seen
    real(real64) :: figures(balance_count), step_heat
    logical :: checked(balance_count), has_balance(balance_count), resolved
    real(real64) :: t_end, time_old
    integer(int64) :: step_start, step_end     !! the monotonic clock around the step (vDSO: ~20 ns a reading)
    type(run_timer) :: timer
    integer(int64) :: n             !! steps taken (accepted)
    integer :: n_state
    type(failure_type) :: step_failure, release_failure, io_failure
    logical :: found, finished, writing, chooses_time, row_due, continuing, completed
    logical :: lock_lost                !! the output's lock was removed or replaced (guard_lock)
    integer :: outputs_passed           !! output times (&output interval) reached so far

    call timer%begin()
    call open_summary(summary, step_count(config%integrator))
    dt = config%integrator%dt
    t_end = config%integrator%t_end
    time = 0.0_real64
    n = 0
    writing = .true.
    lock_lost = .false.
    if (present(keep_file)) writing = keep_file
    part = config%output_file//'.part'
    call install_interrupt_handlers(io_failure)     ! (a run without them still runs)
    call find_integrator(config%integrator%scheme, entry, found)
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, step_failure)
    if (.not. step_failure%failed()) call check_dense_size(size(z0), step_failure)
    if (step_failure%failed()) then
      call fail(failure_input, config%input_file//': '//step_failure%message)
      return
    end if
    ! Integrators that choose their times: those of the registry, and EME with a tolerance.
    chooses_time = entry%chooses_time .or. (config%integrator%tolerance_given .and. entry%error_control)
    continuing = continuation_wanted(writing, resume_if_possible)
    if (writing) then
      call prepare_output(config, chooses_time, model%state_size + size(constraints), present(resume_if_possible), &
                          continuing, resume, kind, text)
      if (len(kind) > 0) call fail(kind, text)
    end if
    if (failure%failed()) return
    n_state = model%state_size
    ! The unknowns: the state and the multipliers of the active constraints (initial guess 0).
    allocate (x(n_state + size(constraints)), x_previous(n_state + size(constraints)), x_new(n_state + size(constraints)))
    allocate (residuals(size(constraints)))
    call summarize_model(summary, model)
    ! The conserved components at t = 0 (a continued run's too: its input builds the same z0).
    conserved_0 = model%conserved_momenta(z0)
    x = 0.0_real64
    x(1:n_state) = z0
    boundary_heat = 0.0_real64
    checked = checked_balances(entry, model, constraints)
    has_balance = applicable_balances(model)

    if (present(reusable)) then
      if (allocated(reusable)) then
        if (reusable%scheme /= entry%name) then
          call reusable%release(release_failure)
          deallocate (reusable)
        end if
      end if
      if (.not. allocated(reusable)) call new_integrator(reusable)
      integrator => reusable
    else
      call new_integrator(own)
      integrator => own
    end if
    ! The integrator starts first: the datasets of its own figures can depend on its settings.
    call integrator%start(config%integrator, model, constraints, z0, step_failure)
    if (step_failure%failed()) then
      ! The drivers set the solver up once before (set_up_only), so this is rare: nothing is written.
      call fail(failure_input, config%input_file//': '//setup_failure_text())
      if (.not. present(reusable)) call integrator%release(release_failure)
      return
    end if
    if (writing) call open_run_file(output, part, config, entry, model, constraints, integrator%diagnostics(), &
                                    integrator%describe_solver(), continuing, resume, summary, failure, extras, durable, &
                                    template)
    if (failure%failed()) then
      if (.not. present(reusable)) call integrator%release(release_failure)
      return
    end if
    if (continuing) then
      call restore(resume)
      call integrator%restore_state(resume%integrator_state, x, x_previous, step_failure)
      if (step_failure%failed()) then
        call fail(failure_input, part//": its integrator state does not fit &integrator scheme = '"// &
                  trim(entry%name)//"' ("//config%input_file//', -eme_continue); allowed: a file of the same input')
        if (.not. present(reusable)) call integrator%release(release_failure)
        return
      end if
    else
      call observe(z0)
      energy_0 = seen%energy
      call record_point(0.0_real64, z0, .true.)
      outputs_passed = 0
      x_previous = x
      call output%note_resume_state(n, time, outputs_passed, energy_0, first_conserved_0(), boundary_heat, summary, x, &
                                    x_previous, integrator)
    end if
    line = ''
    call timer%begin_loop()
    ! Integrators on the output grid take steps_planned steps to n dt (at least one: the input
    ! refuses dt > t_end); those that choose their times go on until they reach t_end (the last
    ! step lands on it), or until the step budget (&integrator max_steps) is spent.
    finished = .false.
    summary%steps_chosen = chooses_time
    do while (.not. finished)
      if (stop_before_step(interrupting_signal(), step_budget_spent(n, config%integrator%max_steps), n, time, t_end, &
                           summary)) exit
      n = n + 1
      if (.not. chooses_time) time = (n - 1)*dt
      time_old = time
      ! With &output interval the step lands on the next output time when it reaches it.
      if (config%output_interval > 0.0_real64) &
        integrator%stop_time = next_output_stop(outputs_passed, config%output_interval, t_end)
      ! Predictor: linear extrapolation of the last step (the old state on the first step).
      call system_clock(step_start)
      call integrator%advance(x, time, dt, 2*x - x_previous, x_new, report, step_failure)
      call system_clock(step_end)
      if (step_failure%failed()) then
        call fail(failure_library, 'PETSc failed during the solve: '//petsc_error_text())
        call note_petsc_error(summary, n)
        exit
      end if
      call land_step(report%chose_time, report%time, n, dt, t_end, summary%steps_planned, time, finished)
      if (.not. report%accepted) then
        call fail_step(summary, n, time, report%reason)
        exit
      end if
      call check_step(resolved)
      if (failure%failed() .or. summary%failure_kind /= failure_none) exit
      boundary_heat = boundary_heat + step_heat
      entropy_old = seen%entropy
      lyapunov_old = seen%lyapunov
      x_previous = x
      x = x_new
      call seen%take(summary, config%theta_r)
      call output%record_step(n, time, report, x(n_state + 1:), real(step_end - step_start, real64)/real(timer%rate, real64), &
                              seen%entropy - entropy_old, seen%lyapunov - lyapunov_old, figures, has_balance, &
                              resolved)
      call pass_output_times(time, config%output_interval, outputs_passed, row_due)
      call record_point(time, x(1:n_state), row_due)
      ! Newton iterations per step: those of the completed steps over their number, as
      ! newton_iterations_total / steps_completed in the file; the conserved components' drift
      ! from the step check's values of them (observe_balances).
      call accumulate_step(summary, n, report%newton_iterations, report%halvings, report%rejected_steps, &
                           abs(seen%energy - energy_0 - boundary_heat)/abs(energy_0), seen%entropy - entropy_old, &
                           seen%lyapunov - lyapunov_old, abs(seen%new%conserved(1:size(conserved_0)) - conserved_0))
      call output%note_resume_state(n, time, outputs_passed, energy_0, first_conserved_0(), boundary_heat, summary, x, &
                                    x_previous, integrator)
      if (output%write_due()) then
        call guard_lock()
        if (lock_lost) exit
        call set_times(.true.)
        call output%write_rows(summary, io_failure)
        if (io_failure%failed()) then
          call fail_write(failure, summary, part, config%input_file, io_failure%message)
          exit
        end if
      end if
      if (present(observer)) call observer%after_step()
      if (present(progress)) then
        line = timer%progress_line(progress_interval, time, t_end, n)
        if (len(line) > 0) call progress(line)
      end if
    end do
    call close_summary(summary, model, has_balance)
    call set_times(.true.)
    call complete_if_finished(summary, finished, n, completed)
    if (completed) summary%warnings = integrator%accuracy_warnings()
    if (.not. present(reusable)) then
      call integrator%release(release_failure)
      if (release_failure%failed()) call fail(failure_library, 'PETSc failed to free the solver: '//petsc_error_text())
    end if
    call close_output()
    call set_times(.false.)

  contains

    subroutine new_integrator(made)
      class(time_stepper), allocatable, intent(out) :: made

      call build_integrator(entry, made)
    end subroutine new_integrator

    ! The loop's state as `record` stored it (the point after its step was recorded).
    subroutine restore(record)
      type(resume_record), intent(in) :: record

      n = record%step
      time = record%time
      outputs_passed = record%outputs_passed
      energy_0 = record%energy_0
      boundary_heat = record%boundary_heat
      x = record%x
      x_previous = record%x_previous
      call record%restore_summary(summary)
      call observe(x(1:n_state))
      summary%min_temperature = record%summary%min_temperature
    end subroutine restore

    ! Records a failure that is not the method's (the first one wins) with its message.
    subroutine fail(kind, text)
      character(len=*), intent(in) :: kind, text

      call record_failure(failure, summary, kind, text, config%input_file)
    end subroutine fail

    ! The whole run's seconds so far, and the time loop's while it runs (src/run/run_clock).
    subroutine set_times(in_loop)
      logical, intent(in) :: in_loop

      call timer%note_times(summary, in_loop)
    end subroutine set_times

    ! Looks at the state z and takes it (its E, S, V into `seen`).
    subroutine observe(z)
      real(real64), intent(in) :: z(:)

      call seen%look(model, z)
      call seen%take(summary, config%theta_r)
    end subroutine observe

    ! The check of the step the integrator just accepted, from x to x_new (src/run/step_check):
    ! its heat through the constraints (step_heat; a multiplier is the step's mean rate, lambda_2 a
    ! heat power, so the heat is rate times the step), its balance figures, and, where it breaks a
    ! guaranteed balance, the step solved again with the model's default solver settings (then
    ! `resolved`). A step that still breaks one ends the run (failure_balance), as does a re-solve
    ! without a root; a library failure sets `failure`.
    subroutine check_step(resolved)
      logical, intent(out) :: resolved
      integer :: broken, first_iterations
      type(failure_type) :: resolving

      resolved = .false.
      call seen%measure(model, constraints, x_new, time - time_old, has_balance, config%theta_r, step_heat, figures)
      broken = broken_balance(figures, checked, report%halvings + 1)
      if (broken == 0) then
        call note_balance_figures(summary, has_balance, figures)
        return
      end if
      resolved = .true.
      summary%resolved_steps = summary%resolved_steps + 1
      first_iterations = report%newton_iterations
      call integrator%resolve(x, time_old, time - time_old, 2*x - x_previous, x_new, report, resolving)
      report%newton_iterations = report%newton_iterations + first_iterations
      if (resolving%failed()) then
        call fail(failure_library, 'PETSc failed during the solve: '//petsc_error_text())
        call note_petsc_error(summary, n)
        return
      end if
      if (.not. report%accepted) then
        summary%status = step_status(n, time, balance_text(broken, figures)//'; solved again with the default '// &
                                     'solver settings: '//report%reason)
        summary%failure_kind = failure_balance
        return
      end if
      call seen%measure(model, constraints, x_new, time - time_old, has_balance, config%theta_r, step_heat, figures)
      broken = broken_balance(figures, checked, report%halvings + 1)
      if (broken == 0) then
        call note_balance_figures(summary, has_balance, figures)
        return
      end if
      summary%status = step_status(n, time, balance_text(broken, figures)//', also when solved again with the '// &
                                   'default solver settings')
      summary%failure_kind = failure_balance
    end subroutine check_step

    ! The first conserved component's initial value, which the resume record keeps (0 if none).
    real(real64) function first_conserved_0()
      first_conserved_0 = 0.0_real64
      if (size(conserved_0) > 0) first_conserved_0 = conserved_0(1)
    end function first_conserved_0

    ! One point: the state `observe` saw last, with what it is judged by (its temperatures, energy,
    ! entropy, V and momentum, kept by observe), and the active constraints' g.
    subroutine record_point(time, z, row_due)
      real(real64), intent(in) :: time, z(:)
      logical, intent(in) :: row_due     !! an output time (&output interval): the point is written
      integer :: k, domain

      do k = 1, size(constraints)
        call constraints(k)%item%value(model, z, residuals(k), domain)
      end do
      call output%record_point(time, z, seen%theta, seen%energy, seen%entropy, seen%lyapunov, seen%momentum, &
                               boundary_heat, residuals, row_due)
    end subroutine record_point

    ! Writes the file's last rows and final attributes, reads it back, and gives it its final
    ! name; an incomplete run does not take the name of a complete one.
    subroutine close_output()
      type(failure_type) :: finishing
      character(len=:), allocatable :: kept

      if (.not. writing) return
      call guard_lock()
      if (.not. writing) return
      call set_times(.false.)
      call output%finish(summary, finishing)
      if (finishing%failed()) then
        summary%status = 'incomplete: cannot write the output file: '//finishing%message
        if (output%store%on_disk) then
          kept = '; '//part//' keeps the '//integer_text(output%disk_steps)//' steps written before'
        else
          kept = '; nothing was kept'
        end if
        failure = failure_type()
        call fail(failure_io, 'cannot write the output file '''//part//''' ('//config%input_file//'): ' &
                  //finishing%message//kept)
        return
      end if
      call name_finished_file(config, part, output%store%durable, summary, failure)
    end subroutine close_output

    ! Before a write: whether the output's lock (eme_run's) is still this process's
    ! (run_file_steps' guard_output_lock: a lost one stops the run, which writes nothing more
    ! unless it took the lock again).
    subroutine guard_lock()
      logical :: may_write

      if (.not. present(lock) .or. lock_lost) return
      call guard_output_lock(lock, config, part, n, summary, failure, lock_lost, may_write)
      writing = writing .and. may_write
    end subroutine guard_lock

  end subroutine run_simulation

end module simulation
