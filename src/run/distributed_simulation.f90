!> One run of a model split over the ranks of an MPI communicator (src/model/distributed_model:
!> the spring chain's sparse path) to its HDF5 file: what `mpirun -n P eme_run FILE.nml` does for
!> a model that can be split, and `eme_run` for one beyond the dense path's size
!> (docs/output.md, "A chain's file"; docs/performance.md, "Which path serves which model"). This
!> module sets the run up and closes it; the one time loop (src/run/time_loop) steps its split
!> path (src/run/split_run_path).
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
!> accepted steps, and the controller's state is kept in the resume record), as the relaxed
!> schemes' are (split_run_setup's split_steps_chosen).
module distributed_simulation
  use, intrinsic :: iso_fortran_env, only: real64
  use mpi_f08, only: MPI_Comm_rank, MPI_Bcast, MPI_LOGICAL
  use model_constraint, only: constraint_slot
  use integrator_settings, only: step_count
  use integrator_registry, only: integrator_entry, find_integrator
  use run_config, only: run_configuration
  use run_output, only: extra_attribute
  use resume_records, only: resume_record, read_resume_record
  use run_outcome, only: run_summary, open_summary, summarize_model, close_summary, failure_input, failure_io, failure_library
  use step_balances, only: applicable_balances
  use step_check, only: checked_balances
  use run_signals, only: install_interrupt_handlers
  use run_file_steps, only: continuation_wanted, prepare_output, open_run_file, guard_output_lock
  use time_loop_steps, only: run_observer, line_reporter, complete_if_finished, pass_output_times
  use split_run_setup, only: split_run_wanted, distributed_settings_of, split_system, set_up_distributed_only, &
                             split_steps_chosen, split_diagnostics
  use split_run_path, only: split_path
  use time_loop, only: run_time_loop
  use snapshot_windows, only: take_up_snapshot, tau_dataset
  use filesystem, only: output_lock
  use rank_agreement, only: agree, share_outcome
  use failures, only: failure_type
  use solver_description, only: solver_report
  implicit none (type, external)
  private
  public :: run_distributed, distributed_settings_of, split_run_wanted, set_up_distributed_only

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
    type(run_summary), intent(out), target :: summary
    type(failure_type), intent(out), target :: failure
    procedure(line_reporter), optional :: progress
    type(output_lock), intent(inout), target, optional :: lock
    class(run_observer), intent(inout), target, optional :: observer
    logical, intent(in), optional :: keep_file
    type(extra_attribute), intent(in), optional :: extras(:)
    logical, intent(in), optional :: durable
    logical, intent(in), optional :: resume_if_possible
    type(split_path) :: run             !! the loop's state (src/run/split_run_path)
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)
    type(integrator_entry) :: entry
    type(failure_type) :: step_failure, io_failure
    type(resume_record) :: resume       !! where a continued run starts (its last snapshot)
    type(solver_report) :: solver       !! the solver as the file records it
    character(len=:), allocatable :: kind, text, status, stored
    logical :: steps_chosen           !! the steps are the integrator's (split_steps_chosen)
    logical :: found, continuing, completed, may_write
    logical :: keeping                !! the run has a file (keep_file)
    logical :: row_due

    run%config => config
    run%summary => summary
    run%failure => failure
    if (present(observer)) run%observer => observer
    if (present(lock)) run%lock => lock
    call run%timer%begin()
    run%communicator%MPI_VAL = comm
    call MPI_Comm_rank(run%communicator, run%rank)
    if (present(progress) .and. run%rank == 0) run%progress => progress
    call open_summary(summary, step_count(config%integrator))
    run%dt = config%integrator%dt
    run%t_end = config%integrator%t_end
    run%time = 0.0_real64
    run%n = 0
    run%lock_lost = .false.
    run%part = config%output_file//'.part'
    run%writing = .false.
    keeping = .true.
    if (present(keep_file)) keeping = keep_file
    call install_interrupt_handlers(io_failure)
    call find_integrator(config%integrator%scheme, entry, found)
    steps_chosen = split_steps_chosen(config)
    summary%steps_chosen = steps_chosen
    call config%scene%build(config%integrator%thermo_variable, run%model, z0, constraints, step_failure)
    if (step_failure%failed()) then
      call run%fail(failure_input, config%input_file//': '//step_failure%message)
      return
    end if
    call split_system(config, run%system, failure)
    if (failure%failed()) return
    ! Rank 0 alone looks at the output; the others learn its verdict (and read a continued run's
    ! record from FILE.part once rank 0 has made it).
    continuing = continuation_wanted(keeping, resume_if_possible)
    if (run%rank == 0 .and. keeping) then
      call prepare_output(config, steps_chosen, 0, present(resume_if_possible), continuing, resume, kind, text)
      if (len(kind) > 0) call run%fail(kind, text)
    end if
    call MPI_Bcast(continuing, 1, MPI_LOGICAL, 0, run%communicator)
    call agree(failure, summary, run%communicator, config%input_file)
    if (failure%failed()) return
    if (continuing .and. run%rank /= 0) then
      call read_resume_record(run%part, resume, status, stored, io_failure)
      if (io_failure%failed()) call run%fail(failure_io, run%part//': '//io_failure%message)
    end if
    call agree(failure, summary, run%communicator, config%input_file)
    if (failure%failed()) return
    call run%system%start(distributed_settings_of(config), run%model, z0, comm, step_failure)
    if (.not. step_failure%failed()) call run%system%figures(run%figures_0, step_failure)
    if (step_failure%failed()) then
      call run%fail(failure_input, config%input_file//': '//step_failure%message)
      call run%system%finish(step_failure)
      return
    end if
    call summarize_model(summary, run%model)
    run%checked = checked_balances(entry, run%model, constraints)
    run%has_balance = applicable_balances(run%model)
    run%every = config%snapshot_every
    call run%window%open(run%communicator, tau_dataset(config%integrator%thermo_variable, &
                                                       run%model%temperature_count() > 0))
    allocate (run%report%scheme_temperature(0))    ! the state is not in rows
    run%values = run%figures_0
    run%state_step = 0
    run%state_time = 0.0_real64
    call run%system%resume_state(run%control_state)
    if (continuing) call restore_snapshot()
    call run%observe(run%values)
    if (run%model%temperature_count() > 0 .and. .not. continuing) summary%min_temperature = run%values%min_temperature
    ! The file: its layout and first point, written whole at once (the first write takes no
    ! snapshot: every later one goes through a window's spare); a continued run's file goes on
    ! from its record's rows, its snapshots all there.
    ! Every rank describes its solver, though rank 0 alone writes it: asking PETSc may create an
    ! object (a ksponly SNES's line search), which takes a message tag on the ranks' communicator;
    ! created on rank 0 alone, the ranks' later tags differed and `-ts_type rosw` hung in its first
    ! matrix product on 2 ranks.
    solver = run%system%describe_solver()
    if (run%rank == 0 .and. keeping .and. .not. failure%failed()) then
      call open_run_file(run%output, run%part, config, entry, run%model, constraints, split_diagnostics(run%system, entry), &
                         solver, continuing, resume, summary, failure, extras, durable, state_rows=.false.)
      if (.not. (continuing .or. failure%failed())) then
        call run%record_point(0.0_real64, .true.)
        call run%output%write_rows(summary, io_failure)
        if (io_failure%failed()) call run%fail(failure_io, 'cannot write the output file '''//run%part//''' ('// &
                                               config%input_file//'): '//io_failure%message)
      end if
    end if
    call agree(failure, summary, run%communicator, config%input_file)
    if (failure%failed()) then
      call run%system%finish(failure)
      return
    end if
    run%writing = keeping
    if (.not. continuing) call run%hold_snapshot()
    ! Output times already passed (a continued run's, from the time its snapshot stands at).
    run%outputs_passed = 0
    call pass_output_times(run%time, config%output_interval, run%outputs_passed, row_due)
    call run_time_loop(run)
    call close_summary(summary, run%model, run%has_balance)
    call complete_if_finished(summary, run%finished, run%n, completed)
    if (completed) summary%warnings = run%system%accuracy_warnings()
    ! The last snapshot is the state the run ended at, if that is a completed step's (a step that
    ! did not converge left it there; one whose state broke a balance did not, nor may a failed
    ! library call, which can stop a step or a trial anywhere). With an interval the file holds
    ! the output times' states only (as the dense path's rows), and a continued run starts from
    ! the last of them, where its resume record stands.
    if (run%state_step == summary%steps_completed .and. run%snapshot_step /= run%state_step .and. &
        config%output_interval <= 0.0_real64 .and. summary%failure_kind /= failure_library) then
      run%time = run%state_time
      call run%hold_snapshot()
    end if
    call run%timer%note_times(summary, .true.)
    call run%system%finish(failure)
    ! Before the last write, as before every step: the lock still rank 0's, or taken again.
    if (run%rank == 0 .and. present(lock) .and. run%writing .and. .not. run%lock_lost) then
      call guard_output_lock(lock, config, run%part, run%n, summary, failure, run%lock_lost, may_write)
      run%writing = may_write
    end if
    call MPI_Bcast(run%writing, 1, MPI_LOGICAL, 0, run%communicator)
    if (run%writing) call run%write_window(.true.)
    call run%timer%note_times(summary, .false.)
    call agree(failure, summary, run%communicator, config%input_file)
    call share_outcome(summary, run%communicator)

  contains

    ! A continued run's state: the file's last snapshot, every rank reading its own part, which
    ! must stand where the file's resume record does; the loop's counts and sums as it recorded
    ! them (the figures of the restored state into run%values).
    subroutine restore_snapshot()
      character(len=:), allocatable :: problem

      if (size(resume%integrator_state) < 4) then
        problem = run%part//': its resume record holds no split run''s sums ('//config%input_file// &
                  ', -eme_continue); allowed: a file of a run split over ranks, as eme_run wrote it'
      else
        call take_up_snapshot(run%system, run%part, comm, run%window%tau_name, resume%time, &
                              resume%integrator_state(5:), ' ('//config%input_file//', -eme_continue)', run%values, &
                              problem)
      end if
      if (len(problem) > 0) then
        call run%fail(failure_input, problem)
        return
      end if
      run%n = resume%step
      run%time = resume%time
      run%state_time = run%time
      run%control_state = resume%integrator_state(5:)
      run%state_step = run%n
      run%snapshot_step = run%n
      call resume%restore_summary(summary)
    end subroutine restore_snapshot
  end subroutine run_distributed

end module distributed_simulation
