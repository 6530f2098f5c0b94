!> One run of a model split over the ranks of an MPI communicator (src/model/distributed_model:
!> the spring chain's sparse path) to its HDF5 file: what `mpirun -n P eme_run FILE.nml` does for
!> a model that can be split, and `eme_run` for one beyond the dense path's size
!> (docs/output.md, "A chain's file"; docs/performance.md, "Which path serves which model").
!>
!> The file keeps the dense path's promises (src/run/simulation): it is written as FILE.part by
!> rank 0 (src/run/run_output, crash-safe windows) and renamed when the run ends, with its status,
!> failure_kind and checksums; every step is checked (src/structure/step_balances, from the ranks'
!> summed figures) and a step that breaks a guaranteed balance ends the run. Its rows hold the
!> scalars (E, S, V, the angular momentum J, Newton's iterations, the residual, the step's smallest
!> viscous and conduction entropy production), not the state: the state goes to /snapshots
!> (src/io/hdf5_snapshots), every rank writing its own part with parallel HDF5, every
!> `&output snapshot_every`-th step and the last, or, with &output interval (adaptive steps, which
!> then land on every output time as on the dense path), at every output time. A snapshot reaches the file in a window of the
!> crash-safe writer: rank 0 closes the window's spare, all ranks append the snapshots the spare
!> lacks, and only then does the spare take the file's name, so that a kill leaves the file of
!> the last window, snapshots included. The model's system steps by the input's integrator (the
!> chain: EME, the midpoint rule, PETSc TS); the balances checked are those it guarantees
!> (step_check, as on the dense path). -eme_continue goes on from the file's last snapshot, at
!> which its resume record stands (src/run/run_continuation), on any number of ranks. EME and the
!> midpoint rule step under the dense path's control (src/integrator/distributed_step_control): a
!> fixed step without a root is taken in halves, and with &integrator tolerance the steps are
!> chosen (each reports the time it reached, the last t_end exactly; rows and snapshots count
!> accepted steps, and the controller's state is kept in the resume record), as relaxed_dp853's
!> are (split_run_setup's split_steps_chosen).
module distributed_simulation
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Allreduce, MPI_Bcast, MPI_IN_PLACE, MPI_INTEGER, &
                     MPI_LOGICAL, MPI_MAX
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use distributed_model, only: distributed_system, distributed_step, distributed_figures
  use integrator_settings, only: step_count
  use integrator_registry, only: integrator_entry, find_integrator
  use stepper, only: step_report
  use run_config, only: run_configuration
  use run_output, only: run_file, extra_attribute
  use resume_records, only: resume_record, read_resume_record
  use run_outcome, only: run_summary, open_summary, summarize_model, close_summary, failure_none, failure_domain, &
                         failure_input, failure_io, failure_library, failure_balance
  use step_balances, only: balance_count, balanced_state, balance_figures, applicable_balances
  use step_check, only: checked_balances, broken_balance, balance_text
  use run_signals, only: install_interrupt_handlers, interrupting_signal
  use run_file_steps, only: continuation_wanted, prepare_output, open_run_file, name_finished_file, guard_output_lock
  use time_loop_steps, only: run_observer, line_reporter, record_failure, step_budget_spent, stop_before_step, &
                             land_step, step_status, fail_step, note_petsc_error, fail_write, accumulate_step, &
                             lower_min_temperature, note_balance_figures, complete_if_finished, &
                             next_output_stop, pass_output_times
  use split_run_setup, only: split_run_wanted, distributed_settings_of, split_system, set_up_distributed_only, &
                             split_steps_chosen, split_diagnostics, report_step, balanced_state_of
  use snapshot_windows, only: held_snapshot, snapshot_window, take_up_snapshot, tau_dataset
  use filesystem, only: output_lock
  use number_text, only: integer_text, scientific_text
  use run_clock, only: run_timer
  use rank_agreement, only: agree, share_outcome
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: run_distributed, distributed_settings_of, split_run_wanted, set_up_distributed_only

  real(real64), parameter :: progress_interval = 2.0_real64     !! seconds between progress lines
contains

  !> Runs `config` split over the ranks of `comm` (every rank calls it) and writes its file; the
  !> summary and failure are the same on every rank. As simulation's run_simulation: a failure
  !> for output that cannot be written, a library's failure, or a complete file that may not be
  !> replaced; a run that stops early says why in summary%status and summary%failure_kind.
  !> `progress` (rank 0) receives a line at most every 2 s; with `lock` (rank 0's), a lock
  !> removed or replaced behind the run's back stops it. An ensemble's case (src/run/ensemble, on
  !> MPI_COMM_SELF) passes what run_simulation takes for it: `observer` (called after every step),
  !> `keep_file` (.false.: no file, an index-only study), `extras` (root attributes), `durable`
  !> (.false.: the file is not synced) and `resume_if_possible` (continue the run its file holds
  !> when it can, from t = 0 otherwise, instead of -eme_continue's all or nothing).
  subroutine run_distributed(config, comm, summary, failure, progress, lock, observer, keep_file, extras, durable, &
                             resume_if_possible)
    type(run_configuration), intent(in), target :: config
    integer, intent(in) :: comm
    type(run_summary), intent(out) :: summary
    type(failure_type), intent(out) :: failure
    procedure(line_reporter), optional :: progress
    type(output_lock), intent(inout), optional :: lock
    class(run_observer), intent(inout), optional :: observer
    logical, intent(in), optional :: keep_file
    type(extra_attribute), intent(in), optional :: extras(:)
    logical, intent(in), optional :: durable
    logical, intent(in), optional :: resume_if_possible
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)
    type(integrator_entry) :: entry
    type(run_file) :: output
    type(snapshot_window) :: window
    type(distributed_step) :: outcome
    type(distributed_figures) :: figures_0, values
    type(balanced_state) :: balance_old, balance_new
    type(step_report) :: report
    type(failure_type) :: step_failure, io_failure
    type(resume_record) :: resume       !! where a continued run starts (its last snapshot)
    character(len=:), allocatable :: part, kind, text, status, stored, line
    real(real64) :: figures(balance_count), dt, time, energy_change, conserved_change(3), dv
    real(real64) :: step_seconds
    integer(int64) :: n, step_start, step_end
    type(run_timer) :: timer
    integer(int64) :: state_step      !! the step whose end the system's state is
    integer(int64) :: snapshot_step   !! the step of the last snapshot held
    real(real64) :: state_time        !! the time of the system's state (the end of step state_step)
    !> the integrator's state after the last accepted step (a continued run's, at its snapshot)
    real(real64), allocatable :: control_state(:)
    logical :: steps_chosen           !! the steps are the integrator's (split_steps_chosen)
    integer :: rank, every, stop_flags(4)
    logical :: lock_lost, may_write    !! rank 0's lock of the output (run_file_steps' guard_output_lock)
    logical :: checked(balance_count), has_balance(balance_count), found, finished, writing, continuing, completed
    logical :: keeping                !! the run has a file (keep_file)
    integer :: outputs_passed         !! output times (&output interval) reached so far
    logical :: row_due                !! the step reached the next output time
    type(MPI_Comm) :: communicator

    call timer%begin()
    communicator%MPI_VAL = comm
    call MPI_Comm_rank(communicator, rank)
    call open_summary(summary, step_count(config%integrator))
    dt = config%integrator%dt
    time = 0.0_real64
    n = 0
    lock_lost = .false.
    part = config%output_file//'.part'
    writing = .false.
    keeping = .true.
    if (present(keep_file)) keeping = keep_file
    call install_interrupt_handlers(io_failure)
    call find_integrator(config%integrator%scheme, entry, found)
    steps_chosen = split_steps_chosen(config)
    summary%steps_chosen = steps_chosen
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, step_failure)
    if (step_failure%failed()) then
      call fail(failure_input, config%input_file//': '//step_failure%message)
      return
    end if
    call split_system(config, system, failure)
    if (failure%failed()) return
    ! Rank 0 alone looks at the output; the others learn its verdict (and read a continued run's
    ! record from FILE.part once rank 0 has made it).
    continuing = continuation_wanted(keeping, resume_if_possible)
    if (rank == 0 .and. keeping) then
      call prepare_output(config, steps_chosen, 0, present(resume_if_possible), continuing, resume, kind, text)
      if (len(kind) > 0) call fail(kind, text)
    end if
    call MPI_Bcast(continuing, 1, MPI_LOGICAL, 0, communicator)
    call agree(failure, summary, communicator, config%input_file)
    if (failure%failed()) return
    if (continuing .and. rank /= 0) then
      call read_resume_record(part, resume, status, stored, io_failure)
      if (io_failure%failed()) call fail(failure_io, part//': '//io_failure%message)
    end if
    call agree(failure, summary, communicator, config%input_file)
    if (failure%failed()) return
    call system%start(distributed_settings_of(config), model, z0, comm, step_failure)
    if (.not. step_failure%failed()) call system%figures(figures_0, step_failure)
    if (step_failure%failed()) then
      call fail(failure_input, config%input_file//': '//step_failure%message)
      call system%finish(step_failure)
      return
    end if
    call summarize_model(summary, model)
    checked = checked_balances(entry, model, constraints)
    has_balance = applicable_balances(model)
    every = config%snapshot_every
    energy_change = 0.0_real64
    conserved_change = 0.0_real64
    call window%open(communicator, tau_dataset(config%integrator%thermo_variable, model%temperature_count() > 0))
    allocate (report%scheme_temperature(0))    ! the state is not in rows
    values = figures_0
    state_step = 0
    state_time = 0.0_real64
    call system%resume_state(control_state)
    if (continuing) call restore_snapshot()
    call observe(values)
    if (model%temperature_count() > 0 .and. .not. continuing) summary%min_temperature = values%min_temperature
    ! The file: its layout and first point, written whole at once (the first write takes no
    ! snapshot: every later one goes through a window's spare); a continued run's file goes on
    ! from its record's rows, its snapshots all there.
    if (rank == 0 .and. keeping .and. .not. failure%failed()) then
      call open_run_file(output, part, config, entry, model, constraints, split_diagnostics(system, entry), &
                         system%describe_solver(), continuing, resume, summary, failure, extras, durable, &
                         state_rows=.false.)
      if (.not. (continuing .or. failure%failed())) then
        call record_point(0.0_real64, .true.)
        call output%write_rows(summary, io_failure)
        if (io_failure%failed()) call fail(failure_io, 'cannot write the output file '''//part//''' ('// &
                                           config%input_file//'): '//io_failure%message)
      end if
    end if
    call agree(failure, summary, communicator, config%input_file)
    if (failure%failed()) then
      call system%finish(failure)
      return
    end if
    writing = keeping
    if (.not. continuing) call hold_snapshot()
    ! Output times already passed (a continued run's, from the time its snapshot stands at).
    outputs_passed = 0
    call pass_output_times(time, config%output_interval, outputs_passed, row_due)
    line = ''
    call timer%begin_loop()
    finished = .false.
    do while (.not. finished)
      ! Every rank stops at the same step: a signal to any, the budget, a lost lock on rank 0
      ! (after which the file is written once more only if rank 0 took the lock again).
      stop_flags = [interrupting_signal(), merge(1, 0, step_budget_spent(n, config%integrator%max_steps)), 0, 0]
      if (rank == 0 .and. present(lock)) then
        call guard_output_lock(lock, config, part, n, summary, failure, lock_lost, may_write)
        stop_flags(3:4) = [merge(1, 0, lock_lost), merge(1, 0, .not. may_write)]
      end if
      call MPI_Allreduce(MPI_IN_PLACE, stop_flags, 4, MPI_INTEGER, MPI_MAX, communicator)
      if (stop_flags(3) /= 0) writing = writing .and. stop_flags(4) == 0
      if (stop_before_step(stop_flags(1), stop_flags(2) /= 0, n, time, config%integrator%t_end, summary)) exit
      if (stop_flags(3) /= 0) exit
      n = n + 1
      ! With &output interval a chosen step lands on the next output time when it reaches it
      ! (one within rounding of t_end is t_end), as on the dense path.
      if (config%output_interval > 0.0_real64) &
        system%stop_time = next_output_stop(outputs_passed, config%output_interval, config%integrator%t_end)
      call system_clock(step_start)
      call system%step(dt, outcome, step_failure)
      call system_clock(step_end)
      step_seconds = real(step_end - step_start, real64)/real(timer%rate, real64)
      if (step_failure%failed()) then
        call fail(failure_library, 'PETSc failed during the solve: '//step_failure%message)
        call note_petsc_error(summary, n)
        exit
      end if
      call land_step(outcome%chose_time, outcome%time, n, dt, config%integrator%t_end, summary%steps_planned, time, &
                     finished)
      if (.not. outcome%converged) then
        if (.not. allocated(outcome%failure)) outcome%failure = ''
        if (len(outcome%failure) == 0) outcome%failure = 'no root: Newton did not converge (SNES reason '// &
          integer_text(outcome%reason)//', |R| = '//scientific_text(outcome%residual_norm, 3)//')'
        call fail_step(summary, n, time, outcome%failure)
        exit
      end if
      state_step = n
      state_time = time
      call system%figures(values, step_failure)
      if (step_failure%failed()) then
        summary%status = step_status(n, time, step_failure%message)
        summary%failure_kind = failure_domain
        exit
      end if
      call check_step()
      if (summary%failure_kind /= failure_none) exit
      call system%resume_state(control_state)
      energy_change = energy_change + values%delta_energy
      conserved_change = conserved_change + values%delta_conserved
      dv = values%delta_energy - config%theta_r*values%delta_entropy
      call accumulate_step(summary, n, outcome%iterations, outcome%halvings, outcome%rejected_steps, &
                           abs(energy_change)/abs(figures_0%energy), values%delta_entropy, dv, &
                           abs(conserved_change(1:values%conserved_count)))
      if (model%temperature_count() > 0) call lower_min_temperature(summary, [values%min_temperature])
      call pass_output_times(time, config%output_interval, outputs_passed, row_due)
      if (rank == 0) then
        call report_step(outcome, values, report)
        call output%record_step(n, time, report, [real(real64) ::], step_seconds, values%delta_entropy, dv, figures, &
                                has_balance, .false.)
        call record_point(time, row_due)
      end if
      if (finished .or. row_due) then
        call hold_snapshot()
      else if (every > 0) then
        if (mod(n, int(every, int64)) == 0) call hold_snapshot()
      end if
      call write_window(.false.)
      if (failure%failed()) exit
      if (rank == 0 .and. present(progress)) then
        line = timer%progress_line(progress_interval, time, config%integrator%t_end, n)
        if (len(line) > 0) call progress(line)
      end if
      if (present(observer)) call observer%after_step()
    end do
    call close_summary(summary, model, has_balance)
    call complete_if_finished(summary, finished, n, completed)
    if (completed) summary%warnings = system%accuracy_warnings()
    ! The last snapshot is the state the run ended at, if that is a completed step's (a step that
    ! did not converge left it there; one whose state broke a balance did not). With an interval
    ! the file holds the output times' states only (as the dense path's rows), and a continued
    ! run starts from the last of them, where its resume record stands.
    if (state_step == summary%steps_completed .and. snapshot_step /= state_step .and. &
        config%output_interval <= 0.0_real64) then
      time = state_time
      call hold_snapshot()
    end if
    call timer%note_times(summary, .true.)
    call system%finish(failure)
    ! Before the last write, as before every step: the lock still rank 0's, or taken again.
    if (rank == 0 .and. present(lock) .and. writing .and. .not. lock_lost) then
      call guard_output_lock(lock, config, part, n, summary, failure, lock_lost, may_write)
      writing = may_write
    end if
    call MPI_Bcast(writing, 1, MPI_LOGICAL, 0, communicator)
    if (writing) call write_window(.true.)
    call timer%note_times(summary, .false.)
    call agree(failure, summary, communicator, config%input_file)
    call share_outcome(summary, communicator)

  contains

    ! Records a failure that is not the method's (the first one wins).
    subroutine fail(kind, text)
      character(len=*), intent(in) :: kind, text

      call record_failure(failure, summary, kind, text, config%input_file)
    end subroutine fail

    ! The balances' state of the figures `values` (into balance_new; balance_old takes the last).
    subroutine observe(values)
      type(distributed_figures), intent(in) :: values

      balance_old = balance_new
      balance_new = balanced_state_of(values)
    end subroutine observe

    ! The step's balance figures, from the summed differences of its parts (over its halves, if
    ! halved: their rounding bounds add up); a step that breaks a guaranteed balance ends the run
    ! (the dense path solves it again first; this path has no other solver settings to try).
    subroutine check_step()
      integer :: broken

      call observe(values)
      figures = balance_figures(has_balance, balance_old, balance_new, 0.0_real64, config%theta_r, &
                                [values%delta_energy, values%delta_entropy], values%delta_conserved)
      broken = broken_balance(figures, checked, outcome%halvings + 1)
      if (broken == 0) then
        call note_balance_figures(summary, has_balance, figures)
        return
      end if
      summary%status = step_status(n, time, balance_text(broken, figures))
      summary%failure_kind = failure_balance
    end subroutine check_step

    ! One point row (rank 0): the state's scalars, from `values`; the model's momenta are J's last
    ! momentum_count() components (J in 3D, J_z in 2D, none in 1D). The rows follow &output every
    ! (of accepted steps when the integrator chooses them), or the output times (`row_due`).
    subroutine record_point(time, row_due)
      real(real64), intent(in) :: time
      logical, intent(in) :: row_due

      call output%record_point(time, [real(real64) ::], [real(real64) ::], values%energy, values%entropy, &
                               values%energy - config%theta_r*values%entropy, &
                               values%angular_momentum(4 - model%momentum_count():), 0.0_real64, [real(real64) ::], &
                               row_due)
    end subroutine record_point

    ! The rank's part of the state (the end of step state_step, at `time`), held for the next
    ! window, which also stores the resume record that stands at it (rank 0: its row is recorded).
    subroutine hold_snapshot()
      type(held_snapshot) :: snapshot
      type(failure_type) :: reading

      if (.not. writing) return          ! no file (keep_file = .false.)
      snapshot%time = time
      snapshot_step = state_step
      call system%part(snapshot%state, reading)
      if (reading%failed()) then
        call fail(failure_library, 'cannot read the state for a snapshot: '//reading%message)
        return
      end if
      call window%hold(snapshot)
      if (rank == 0) call output%note_snapshot_point(state_step, time, figures_0%energy, summary, &
                                                     [energy_change, conserved_change, control_state])
    end subroutine hold_snapshot

    ! A continued run's state: the file's last snapshot, every rank reading its own part, which
    ! must stand where the file's resume record does; the loop's counts and sums as it recorded
    ! them (the figures of the restored state into `values`).
    subroutine restore_snapshot()
      character(len=:), allocatable :: problem

      if (size(resume%integrator_state) < 4) then
        problem = part//': its resume record holds no split run''s sums ('//config%input_file//', -eme_continue)'// &
                  '; allowed: a file of a run split over ranks, as eme_run wrote it'
      else
        call take_up_snapshot(system, part, comm, window%tau_name, resume%time, resume%integrator_state(5:), &
                              ' ('//config%input_file//', -eme_continue)', values, problem)
      end if
      if (len(problem) > 0) then
        call fail(failure_input, problem)
        return
      end if
      n = resume%step
      time = resume%time
      state_time = time
      control_state = resume%integrator_state(5:)
      state_step = n
      snapshot_step = n
      call resume%restore_summary(summary)
      energy_change = resume%integrator_state(1)
      conserved_change = resume%integrator_state(2:4)
    end subroutine restore_snapshot

    ! A write of the file when one is due (rank 0's clock, or a rank's full snapshot buffer), or
    ! the last one (`final`): rank 0 writes the rows and attributes, and every rank joins its
    ! window to add the snapshots (snapshot_window).
    subroutine write_window(final)
      logical, intent(in) :: final
      integer :: flags(2), outcome_code

      flags = 0
      if (rank == 0 .and. .not. final) flags(1) = merge(1, 0, output%write_due())
      flags(2) = merge(1, 0, window%full())
      if (.not. final) then
        call MPI_Allreduce(MPI_IN_PLACE, flags, 2, MPI_INTEGER, MPI_MAX, communicator)
        if (all(flags == 0)) return
      end if
      window%added = .false.
      if (rank == 0) then
        call timer%note_times(summary, .not. final)
        if (final) then
          call output%finish(summary, io_failure, window)
        else
          call output%write_rows(summary, io_failure, window)
        end if
        ! A window that did not reach its addition (deferred, or failed before) releases the others.
        if (.not. window%added) then
          outcome_code = 0
          call MPI_Bcast(outcome_code, 1, MPI_INTEGER, 0, communicator)
        end if
      else
        call window%join()
      end if
      outcome_code = merge(1, 0, window%added .and. .not. io_failure%failed())
      call MPI_Bcast(outcome_code, 1, MPI_INTEGER, 0, communicator)
      if (outcome_code == 1) call window%written()
      if (rank == 0 .and. io_failure%failed()) then
        call fail_write(failure, summary, part, config%input_file, io_failure%message)
      end if
      call agree(failure, summary, communicator, config%input_file)
      ! The last write reached the file (a run stopped by a failure too, marked incomplete): it
      ! takes the output's name, as on the dense path.
      if (final .and. rank == 0 .and. .not. io_failure%failed()) &
        call name_finished_file(config, part, output%store%durable, summary, failure)
    end subroutine write_window
  end subroutine run_distributed

end module distributed_simulation
