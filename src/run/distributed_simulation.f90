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
!> accepted steps, and the controller's state is kept in the resume record).
module distributed_simulation
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Allreduce, MPI_Bcast, MPI_IN_PLACE, MPI_INTEGER, MPI_CHARACTER, &
                     MPI_LOGICAL, MPI_MAX
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use distributed_model, only: distributed_system, distributed_settings, distributed_step, distributed_figures, &
                               distributed_part
  use thermo_variable_kinds, only: tau_entropy, tau_internal_energy
  use integrator_settings, only: step_count
  use integrator_registry, only: integrator_entry, find_integrator, family_discrete_gradient, build_integrator
  use distributed_step_control, only: controlled_system, controlled_diagnostics
  use butcher_tableaux, only: butcher_tableau, tableau_named
  use stepper, only: time_stepper, step_report, step_diagnostic
  use run_config, only: run_configuration
  use run_output, only: run_file, extra_attribute, spare_addition, resume_record, read_resume_record
  use run_continuation, only: find_resume_record
  use run_outcome, only: run_summary, step_failure_kind, open_summary, summarize_model, close_summary, failure_none, &
                         failure_domain, failure_input, failure_io, &
                         failure_interrupted, failure_library, failure_step_budget, failure_balance
  use step_balances, only: balance_count, balanced_state, balance_figures, applicable_balances
  use step_check, only: checked_balances, broken_balance, balance_text
  use run_signals, only: install_interrupt_handlers, interrupting_signal, signal_name
  use run_options, only: overwrite_requested, continue_requested, petsc_options_in_force
  use simulation, only: line_reporter, run_observer, holds_complete_run, failure_code_of
  use hdf5_snapshots, only: snapshot_layout, append_snapshot, read_last_snapshot
  use output_path, only: check_output_path
  use filesystem, only: make_parent_directories, rename_file, output_lock, recheck_lock
  use number_text, only: integer_text, fixed_text, scientific_text
  use run_clock, only: run_timer
  use failures, only: failure_type, set_failure => fail, code_input => failure_input
  implicit none (type, external)
  private
  public :: run_distributed, distributed_settings_of, split_run_wanted, set_up_distributed_only

  real(real64), parameter :: progress_interval = 2.0_real64     !! seconds between progress lines
  !> Bytes of snapshots a rank holds for the next window at most: more force the window.
  integer(int64), parameter :: snapshot_buffer_bytes = 256_int64*1024*1024

  !> A snapshot held for the file: its time and the rank's part.
  type :: held_snapshot
    real(real64) :: time = 0.0_real64
    type(distributed_part) :: state
  end type held_snapshot

  !> The snapshots a window adds to the spare (crash_safe_file's spare_addition): those of the
  !> window before (`kept`: the spare, one window behind, lacks them) and the new ones; rank 0
  !> calls `add` inside its window, the other ranks `join` at the same point.
  type, extends(spare_addition) :: snapshot_window
    type(MPI_Comm) :: comm
    integer :: rank = 0
    character(len=:), allocatable :: tau_name              !! the snapshot's dataset of tau ('' if none)
    !> kept(1:kept_count) and new(1:new_count) hold them (capacity doubling as snapshots come)
    type(held_snapshot), allocatable :: kept(:), new(:)
    integer :: kept_count = 0, new_count = 0
    integer(int64) :: new_bytes = 0                        !! the new snapshots' values, in bytes
    logical :: added = .false.                             !! rank 0: `add` ran in this window
  contains
    procedure :: add
    procedure :: join
    procedure :: hold
    procedure :: written
  end type snapshot_window

contains

  !> Whether `config`'s run goes to the split path on `ranks` ranks: its model can be split
  !> (model_scene's `distributed`) and it runs on several ranks or has more than `dense_limit`
  !> unknowns (the dense path's). A scene that cannot be built is left to the caller's run.
  logical function split_run_wanted(config, ranks, dense_limit)
    type(run_configuration), intent(in) :: config
    integer, intent(in) :: ranks, dense_limit
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)
    type(failure_type) :: building

    call config%scene%distributed(config%integrator%scheme, system)
    split_run_wanted = allocated(system)
    if (.not. split_run_wanted .or. ranks > 1) return
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, building)
    split_run_wanted = .not. building%failed() .and. size(z0) > dense_limit
  end function split_run_wanted

  !> What the split path's steps need of the input's &integrator.
  function distributed_settings_of(config) result(settings)
    type(run_configuration), intent(in) :: config
    type(distributed_settings) :: settings
    type(butcher_tableau) :: tableau
    logical :: found

    settings%input_file = config%input_file
    settings%scheme = config%integrator%scheme
    settings%discrete_gradient = config%integrator%discrete_gradient
    settings%metric = config%integrator%metric
    settings%newton_tol = config%integrator%newton_tol
    settings%newton_max_iterations = config%integrator%newton_max_iterations
    settings%tolerance_given = config%integrator%tolerance_given
    settings%tolerance = config%integrator%tolerance
    settings%dt = config%integrator%dt
    settings%t_end = config%integrator%t_end
    call tableau_named(config%integrator%scheme, tableau, found)
    if (.not. found) return
    settings%stage_matrix = tableau%a
    settings%weights = tableau%b
    settings%order = tableau%order
    settings%implicit_stages = tableau%implicit
    settings%embedded_weights = tableau%embedded
  end function distributed_settings_of

  !> The split model of `config`'s scene for its integrator: EME's and the midpoint rule's steps
  !> under the dense path's control (src/integrator/distributed_step_control: halving, adaptive
  !> steps), others as the scene gives them; a failure (failure_input) for &output interval
  !> unless the steps are chosen (&integrator tolerance with EME or the midpoint rule: a relaxed
  !> scheme's steps land on n dt here), or with snapshot_every as well.
  subroutine split_system(config, system, failure)
    type(run_configuration), intent(in) :: config
    class(distributed_system), allocatable, intent(out) :: system
    type(failure_type), intent(out) :: failure
    type(integrator_entry) :: entry
    type(controlled_system), allocatable :: controlled
    logical :: found

    call find_integrator(config%integrator%scheme, entry, found)
    if (config%output_interval > 0.0_real64) then
      if (.not. (found .and. entry%family == family_discrete_gradient .and. config%integrator%tolerance_given)) then
        call set_failure(failure, code_input, config%input_file//', &output: interval: a run split over ranks '// &
                         'lands on output times only with steps it chooses (&integrator tolerance with scheme = '// &
                         '''eme'' or ''midpoint''); scheme = '''//trim(config%integrator%scheme)//''' steps on n dt '// &
                         'here; allowed: leave it out (0), or give a tolerance', 'interval')
        return
      else if (config%snapshot_every > 0) then
        call set_failure(failure, code_input, config%input_file//', &output: interval and snapshot_every both '// &
                         'given: with an interval the snapshots are taken at the output times; allowed: one of them', &
                         'snapshot_every')
        return
      end if
    end if
    call config%scene%distributed(config%integrator%scheme, system)
    if (.not. found .or. entry%family /= family_discrete_gradient) return
    allocate (controlled)
    call move_alloc(system, controlled%inner)
    call move_alloc(controlled, system)
  end subroutine split_system

  !> Sets the split model up on `comm` and frees it again, writing nothing (as simulation's
  !> set_up_only): what the path cannot run, and PETSc options it cannot take, are refused
  !> (failure_input) before anything is written.
  subroutine set_up_distributed_only(config, comm, failure)
    type(run_configuration), intent(in) :: config
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)

    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, failure)
    if (failure%failed()) then
      call set_failure(failure, failure%code, config%input_file//': '//failure%message)
      return
    end if
    call split_system(config, system, failure)
    if (failure%failed()) return
    call system%start(distributed_settings_of(config), model, z0, comm, failure)
    if (failure%failed() .and. failure%code /= code_input) &
      call set_failure(failure, code_input, config%input_file//': the split run could not be set up with the '// &
                       'options given: '//failure%message)
    call system%finish(failure)
  end subroutine set_up_distributed_only

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
    class(time_stepper), allocatable :: integrator
    type(step_diagnostic), allocatable :: integrator_diagnostics(:)
    type(failure_type) :: step_failure, io_failure
    type(resume_record) :: resume       !! where a continued run starts (its last snapshot)
    character(len=:), allocatable :: part, kind, text, status, stored
    real(real64) :: figures(balance_count), dt, time, energy_change, conserved_change(3), dv
    real(real64) :: step_seconds
    integer(int64) :: n, step_start, step_end
    type(run_timer) :: timer
    integer(int64) :: state_step      !! the step whose end the system's state is
    integer(int64) :: snapshot_step   !! the step of the last snapshot held
    real(real64) :: state_time        !! the time of the system's state (the end of step state_step)
    !> the integrator's state after the last accepted step (a continued run's, at its snapshot)
    real(real64), allocatable :: control_state(:)
    logical :: steps_chosen           !! the steps are the integrator's (&integrator tolerance)
    integer :: rank, every, stop_flags(3)
    logical :: checked(balance_count), has_balance(balance_count), found, replace, finished, writing, continuing
    logical :: keeping                !! the run has a file (keep_file)
    integer :: outputs_passed         !! output times (&output interval) reached so far
    logical :: row_due                !! the step reached the next output time
    type(extra_attribute), allocatable :: added(:)
    type(MPI_Comm) :: communicator

    call timer%begin()
    communicator%MPI_VAL = comm
    call MPI_Comm_rank(communicator, rank)
    call open_summary(summary, step_count(config%integrator))
    dt = config%integrator%dt
    time = 0.0_real64
    n = 0
    part = config%output_file//'.part'
    writing = .false.
    keeping = .true.
    if (present(keep_file)) keeping = keep_file
    call install_interrupt_handlers(io_failure)
    call find_integrator(config%integrator%scheme, entry, found)
    steps_chosen = config%integrator%tolerance_given .and. entry%family == family_discrete_gradient
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
    if (present(resume_if_possible)) then
      continuing = resume_if_possible .and. keeping
    else
      continuing = continue_requested()
    end if
    if (rank == 0 .and. continuing) then
      call find_resume_record(config, steps_chosen, resume, kind, text)
      if (len(kind) > 0) call fail(kind, text)
      if (.not. failure%failed() .and. size(resume%x) > 0) &
        call fail(failure_input, config%output_file//': its run was not split over ranks (its state is in /state) '// &
                  'and continues on the dense path ('//config%input_file//', -eme_continue); allowed: eme_run on '// &
                  'one process, as it ran')
      if (failure%failed() .and. present(resume_if_possible)) then
        ! Nothing to continue from: the run starts from t = 0, as it would have.
        failure = failure_type()
        summary%failure_kind = failure_none
        continuing = .false.
      end if
    end if
    call MPI_Bcast(continuing, 1, MPI_LOGICAL, 0, communicator)
    if (rank == 0 .and. keeping .and. .not. continuing) then
      replace = overwrite_requested() .or. config%overwrite
      call check_output_path(config%output_file, config%input_file, replace, io_failure)
      if (io_failure%failed()) then
        call fail(failure_input, io_failure%message)
      else
        call make_parent_directories(config%output_file, io_failure)
        if (io_failure%failed()) call fail(failure_io, 'cannot create the directory of the output file '''// &
                                           config%output_file//''' ('//config%input_file//', &output: file): '// &
                                           io_failure%message)
      end if
      if (.not. failure%failed() .and. .not. replace) replace = .not. holds_complete_run(config%output_file)
      if (.not. failure%failed() .and. .not. replace) &
        call fail(failure_input, config%output_file//' holds a complete run, which is kept; to replace it, set '// &
                  '&output overwrite = .true. in '//config%input_file//', give -eme_overwrite, or choose another '// &
                  '&output file')
    end if
    call agree(failure)
    if (failure%failed()) return
    if (continuing .and. rank /= 0) then
      call read_resume_record(part, resume, status, stored, io_failure)
      if (io_failure%failed()) call fail(failure_io, part//': '//io_failure%message)
    end if
    call agree(failure)
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
    window%comm = communicator
    window%rank = rank
    window%tau_name = tau_dataset(config%integrator%thermo_variable, model%temperature_count() > 0)
    allocate (window%kept(0), window%new(4))
    ! The step report's parts of the split path: no scheme temperatures (the state is not in
    ! rows); the integrator's figures are the step control's (controlled_diagnostics), or those
    ! the dense path's integrator of the same name declares for a system that runs it on its own
    ! steps (a relaxed scheme's), then the two production minima.
    allocate (report%scheme_temperature(0))
    allocate (integrator_diagnostics(0))
    if (system%integrator_diagnostics()) then
      call build_integrator(entry, integrator)
      integrator_diagnostics = integrator%diagnostics()
    end if
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
    allocate (added(0))
    if (present(extras)) added = extras
    if (present(durable)) output%store%durable = durable
    if (rank == 0 .and. keeping .and. .not. failure%failed()) then
      call output%create(part, config, entry, model, constraints, &
                         [controlled_diagnostics(system), integrator_diagnostics, diagnostics()], added, &
                         petsc_options_in_force(), io_failure, state_rows=.false.)
      if (.not. io_failure%failed()) call output%record_solver(system%describe_solver(), io_failure)
      if (io_failure%failed()) then
        call fail(failure_library, 'HDF5 could not prepare the output file '''//part//''' ('//config%input_file//')')
      else if (continuing) then
        call output%continue_file(resume, config, io_failure)
        if (io_failure%failed()) call fail(failure_io, "cannot continue the output file '"//part//"' ("// &
                                           config%input_file//'): '//io_failure%message)
      else
        call record_point(0.0_real64, .true.)
        call output%write_rows(summary, io_failure)
        if (io_failure%failed()) call fail(failure_io, 'cannot write the output file '''//part//''' ('// &
                                           config%input_file//'): '//io_failure%message)
      end if
    end if
    call agree(failure)
    if (failure%failed()) then
      call system%finish(failure)
      return
    end if
    writing = keeping
    if (.not. continuing) call hold_snapshot()
    ! Output times already passed (a continued run's, from the time its snapshot stands at).
    outputs_passed = 0
    row_due = output_time_reached()
    call timer%begin_loop()
    finished = .false.
    do while (.not. finished)
      ! Every rank stops at the same step: a signal to any, the budget, a lost lock on rank 0.
      stop_flags = [interrupting_signal(), merge(1, 0, n >= config%integrator%max_steps), 0]
      if (rank == 0 .and. present(lock)) stop_flags(3) = merge(1, 0, lock_lost())
      call MPI_Allreduce(MPI_IN_PLACE, stop_flags, 3, MPI_INTEGER, MPI_MAX, communicator)
      if (stop_flags(1) /= 0) then
        summary%status = 'incomplete: interrupted by '//signal_name(stop_flags(1))
        summary%failure_kind = failure_interrupted
        exit
      else if (stop_flags(2) /= 0) then
        summary%status = 'incomplete: the step budget is spent: '//integer_text(n)//' steps reached t = '// &
                         fixed_text(time, 6)//' s of t_end = '//fixed_text(config%integrator%t_end, 6)// &
                         ' s (raise &integrator max_steps)'
        summary%failure_kind = failure_step_budget
        exit
      else if (stop_flags(3) /= 0) then
        summary%status = 'incomplete: the lock '//config%output_file//'.lock was removed or replaced while the run wrote'
        summary%failure_kind = failure_io
        call fail(failure_io, config%output_file//' ('//config%input_file//'): its lock was removed or replaced '// &
                  'while the run wrote: the run stops after '//integer_text(n)//' steps')
        exit
      end if
      n = n + 1
      ! With &output interval a chosen step lands on the next output time when it reaches it
      ! (one within rounding of t_end is t_end), as on the dense path.
      if (config%output_interval > 0.0_real64) then
        system%stop_time = (outputs_passed + 1)*config%output_interval
        if (system%stop_time >= config%integrator%t_end*(1.0_real64 - 8*epsilon(1.0_real64))) &
          system%stop_time = config%integrator%t_end
      end if
      call system_clock(step_start)
      call system%step(dt, outcome, step_failure)
      call system_clock(step_end)
      step_seconds = real(step_end - step_start, real64)/real(timer%rate, real64)
      if (step_failure%failed()) then
        call fail(failure_library, 'PETSc failed during the solve: '//step_failure%message)
        summary%status = 'incomplete: PETSc error in step '//integer_text(n)
        exit
      end if
      ! A fixed step lands on n dt; the integrator's own steps at the time they reached (t_end
      ! exactly on the last).
      if (outcome%chose_time) then
        time = outcome%time
        finished = time >= config%integrator%t_end
      else
        time = n*dt
        finished = n == summary%steps_planned
      end if
      if (.not. outcome%converged) then
        if (.not. allocated(outcome%failure)) outcome%failure = ''
        if (len(outcome%failure) == 0) outcome%failure = 'no root: Newton did not converge (SNES reason '// &
          integer_text(outcome%reason)//', |R| = '//scientific_text(outcome%residual_norm, 3)//')'
        summary%status = 'incomplete: step '//integer_text(n)//' (t = '//fixed_text(time, 4)//' s): '//outcome%failure
        summary%failure_kind = step_failure_kind(outcome%failure)
        exit
      end if
      state_step = n
      state_time = time
      call system%figures(values, step_failure)
      if (step_failure%failed()) then
        summary%status = 'incomplete: step '//integer_text(n)//' (t = '//fixed_text(time, 4)//' s): '// &
                         step_failure%message
        summary%failure_kind = failure_domain
        exit
      end if
      call check_step()
      if (summary%failure_kind /= failure_none) exit
      summary%steps_completed = n
      summary%newton_iterations = summary%newton_iterations + outcome%iterations
      summary%halved_steps = summary%halved_steps + outcome%halvings
      summary%rejected_steps = summary%rejected_steps + outcome%rejected_steps
      call system%resume_state(control_state)
      energy_change = energy_change + values%delta_energy
      conserved_change = conserved_change + values%delta_conserved
      summary%energy_drift = max(summary%energy_drift, abs(energy_change)/abs(figures_0%energy))
      dv = values%delta_energy - config%theta_r*values%delta_entropy
      summary%min_entropy_increment = min(summary%min_entropy_increment, values%delta_entropy)
      summary%max_lyapunov_increment = max(summary%max_lyapunov_increment, dv)
      if (values%conserved_count > 0) summary%angular_momentum_drift = max(summary%angular_momentum_drift, &
        maxval(abs(conserved_change(1:values%conserved_count))))
      if (model%temperature_count() > 0) summary%min_temperature = min(summary%min_temperature, values%min_temperature)
      row_due = output_time_reached()
      if (rank == 0) then
        report%newton_iterations = outcome%iterations
        report%solves = outcome%solves
        report%rejected = outcome%rejected
        report%residual_norm = outcome%residual_norm
        report%converged_reason = outcome%reason
        report%diagnostics = [values%min_viscous_production, values%min_link_production]
        where (report%diagnostics >= huge(1.0_real64)) report%diagnostics = ieee_value(1.0_real64, ieee_quiet_nan)
        if (allocated(outcome%diagnostics)) report%diagnostics = [outcome%diagnostics, report%diagnostics]
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
      if (rank == 0 .and. present(progress)) call report_progress()
      if (present(observer)) call observer%after_step()
    end do
    call close_summary(summary, model, has_balance)
    if (finished .and. summary%steps_completed == n .and. summary%failure_kind == failure_none) then
      summary%status = 'complete'
      if (steps_chosen) summary%steps_planned = n       ! it planned t_end/dt steps and took n
      summary%warnings = system%accuracy_warnings()
    end if
    ! The last snapshot is the state the run ended at, if that is a completed step's (a step that
    ! did not converge left it there; one whose state broke a balance did not). With an interval
    ! the file holds the output times' states only (as the dense path's rows), and a continued
    ! run starts from the last of them, where its resume record stands.
    if (state_step == summary%steps_completed .and. snapshot_step /= state_step .and. &
        config%output_interval <= 0.0_real64) then
      time = state_time
      call hold_snapshot()
    end if
    call set_times(.true.)
    call system%finish(failure)
    if (writing) call write_window(.true.)
    call set_times(.false.)
    call agree(failure)
    call share_outcome()

  contains

    ! Records a failure that is not the method's (the first one wins).
    subroutine fail(kind, text)
      character(len=*), intent(in) :: kind, text

      if (failure%failed()) return
      call set_failure(failure, failure_code_of(kind), text, config%input_file)
      summary%failure_kind = kind
    end subroutine fail

    ! Every rank takes rank 0's failure when it has none of its own (rank 0's is the output's).
    subroutine agree(failure)
      type(failure_type), intent(inout) :: failure
      integer :: code
      character(len=:), allocatable :: text, kind

      code = failure%code
      call MPI_Bcast(code, 1, MPI_INTEGER, 0, communicator)
      if (code == 0) return
      text = ''
      if (rank == 0) text = failure%message
      call share_text(text)
      kind = summary%failure_kind
      call share_text(kind)
      if (rank /= 0 .and. .not. failure%failed()) then
        call set_failure(failure, code, text, config%input_file)
        summary%failure_kind = kind
      end if
    end subroutine agree

    ! rank 0's status, note and failure kind on every rank (the exit status depends on them).
    subroutine share_outcome()
      call share_text(summary%status)
      call share_text(summary%failure_kind)
      call share_text(summary%note)
    end subroutine share_outcome

    subroutine share_text(text)
      character(len=:), allocatable, intent(inout) :: text
      integer :: length

      length = len(text)
      call MPI_Bcast(length, 1, MPI_INTEGER, 0, communicator)
      if (rank /= 0) then
        deallocate (text)
        allocate (character(len=length) :: text)
      end if
      if (length > 0) call MPI_Bcast(text, length, MPI_CHARACTER, 0, communicator)
    end subroutine share_text

    ! The balances' state of the figures `values` (into balance_new; balance_old takes the last).
    subroutine observe(values)
      type(distributed_figures), intent(in) :: values

      balance_old = balance_new
      balance_new%energy = values%energy
      balance_new%energy_scale = values%energy_scale
      balance_new%entropy = values%entropy
      balance_new%entropy_scale = values%entropy_scale
      balance_new%conserved_count = values%conserved_count
      balance_new%conserved = values%conserved
      balance_new%momentum_scale = values%momentum_scale
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
        where (has_balance) summary%max_balance = max(summary%max_balance, figures)
        return
      end if
      summary%status = 'incomplete: step '//integer_text(n)//' (t = '//fixed_text(time, 4)//' s): '// &
                       balance_text(broken, figures)
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

    ! Whether `time` reached the next output time of &output interval (counting it passed), as
    ! the dense path counts them (within 8 ulps).
    logical function output_time_reached() result(reached)
      reached = .false.
      do while (config%output_interval > 0.0_real64 .and. &
                time >= (outputs_passed + 1)*config%output_interval*(1.0_real64 - 8*epsilon(1.0_real64)))
        outputs_passed = outputs_passed + 1
        reached = .true.
      end do
    end function output_time_reached

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
      type(distributed_part) :: state
      type(failure_type) :: reading
      real(real64) :: snapshot_time
      character(len=:), allocatable :: where

      where = ' ('//config%input_file//', -eme_continue)'
      call system%part(state, reading)       ! this rank's part of the state: the shapes to read
      if (.not. reading%failed()) call transfer_part(part, comm, snapshot_time, state, window%tau_name, .true., reading)
      if (len(window%tau_name) == 0) state%tau = state%theta      ! tau is the temperature, stored as theta
      if (.not. reading%failed()) then
        if (abs(snapshot_time - resume%time) > 0.0_real64 .or. size(resume%integrator_state) < 4) then
          call fail(failure_input, part//': its last snapshot (t = '//fixed_text(snapshot_time, 6)//' s) is not '// &
                    'where its resume record stands (t = '//fixed_text(resume%time, 6)//' s)'//where// &
                    '; allowed: a file of a run split over ranks, as eme_run wrote it')
          return
        end if
        call system%restore(state, reading)
        if (.not. reading%failed()) call system%restore_state(resume%time, resume%integrator_state(5:), reading)
      end if
      if (.not. reading%failed()) call system%figures(values, reading)
      if (reading%failed()) then
        call fail(failure_input, part//': its last snapshot cannot be taken up: '//reading%message//where// &
                  '; allowed: a file of this input''s run split over ranks')
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
      flags(2) = merge(1, 0, window%new_bytes > snapshot_buffer_bytes)
      if (.not. final) then
        call MPI_Allreduce(MPI_IN_PLACE, flags, 2, MPI_INTEGER, MPI_MAX, communicator)
        if (all(flags == 0)) return
      end if
      window%added = .false.
      if (rank == 0) then
        call set_times(.not. final)
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
        summary%status = 'incomplete: cannot write the output file: '//io_failure%message
        call fail(failure_io, 'cannot write the output file '''//part//''' ('//config%input_file//'): '// &
                  io_failure%message)
      end if
      call agree(failure)
      if (final .and. rank == 0 .and. .not. failure%failed()) call close_output()
    end subroutine write_window

    ! The finished file takes its name, unless an incomplete run would replace a complete one.
    subroutine close_output()
      type(failure_type) :: renaming
      logical :: keep

      keep = summary%status /= 'complete'
      if (keep) keep = holds_complete_run(config%output_file)
      if (keep) then
        summary%note = config%output_file//' keeps the earlier complete run; this run''s file is '//part
        return
      end if
      call rename_file(part, config%output_file, renaming, sync=output%store%durable)
      if (renaming%failed()) call fail(failure_io, 'cannot rename '''//part//''' to '''//config%output_file// &
                                       ''' ('//config%input_file//'): '//renaming%message)
    end subroutine close_output

    ! Whether rank 0's lock of the output was removed or replaced (the run then stops). (A result
    ! named apart from the function: passing the function's own name made gfortran pass the
    ! nested function, through a trampoline on an executable stack.)
    logical function lock_lost() result(lost)
      character(len=:), allocatable :: holder, what
      logical :: retaken

      call recheck_lock(lock, lost, retaken, what, holder)
    end function lock_lost

    subroutine set_times(in_loop)
      logical, intent(in) :: in_loop

      call timer%note_times(summary, in_loop)
    end subroutine set_times

    subroutine report_progress()
      real(real64) :: elapsed, left

      if (.not. timer%progress_due(progress_interval)) return
      elapsed = timer%loop_seconds()
      left = elapsed*max(0.0_real64, config%integrator%t_end - time)/max(time, tiny(time))
      call progress('t = '//fixed_text(time, 3)//' of '//fixed_text(config%integrator%t_end, 3)//' s, '// &
                    integer_text(n)//' steps, about '//fixed_text(left, 1)//' s left')
    end subroutine report_progress
  end subroutine run_distributed

  !> Appends the window's snapshots to the closed spare at `path` (rank 0, inside its window):
  !> tells the other ranks where, and writes with them.
  subroutine add(self, path, failure)
    class(snapshot_window), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure
    integer :: length
    character(len=:), allocatable :: text

    self%added = .true.
    length = len(path)
    call MPI_Bcast(length, 1, MPI_INTEGER, 0, self%comm)
    text = path
    call MPI_Bcast(text, length, MPI_CHARACTER, 0, self%comm)
    call append_held(self, text, failure)
  end subroutine add

  !> The other ranks' side of a window: the spare's path from rank 0 (none if the window did not
  !> reach its addition), and the snapshots written with it.
  subroutine join(self)
    class(snapshot_window), intent(inout) :: self
    integer :: length
    character(len=:), allocatable :: path
    type(failure_type) :: failure

    call MPI_Bcast(length, 1, MPI_INTEGER, 0, self%comm)
    if (length == 0) return
    allocate (character(len=length) :: path)
    call MPI_Bcast(path, length, MPI_CHARACTER, 0, self%comm)
    self%added = .true.
    call append_held(self, path, failure)
  end subroutine join

  ! Every held snapshot, kept then new, appended by all ranks (append_snapshot is collective and
  ! makes every rank agree on a failure).
  subroutine append_held(self, path, failure)
    type(snapshot_window), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(failure_type), intent(out) :: failure
    integer :: k

    do k = 1, self%kept_count
      if (.not. failure%failed()) call transfer_part(path, self%comm%MPI_VAL, self%kept(k)%time, self%kept(k)%state, &
                                                     self%tau_name, .false., failure)
    end do
    do k = 1, self%new_count
      if (.not. failure%failed()) call transfer_part(path, self%comm%MPI_VAL, self%new(k)%time, self%new(k)%state, &
                                                     self%tau_name, .false., failure)
    end do
  end subroutine append_held

  !> Holds `snapshot` for the next window.
  subroutine hold(self, snapshot)
    class(snapshot_window), intent(inout) :: self
    type(held_snapshot), intent(in) :: snapshot
    type(held_snapshot), allocatable :: grown(:)

    if (self%new_count == size(self%new)) then
      allocate (grown(2*size(self%new)))
      grown(1:self%new_count) = self%new(1:self%new_count)
      call move_alloc(grown, self%new)
    end if
    self%new_count = self%new_count + 1
    self%new(self%new_count) = snapshot
    associate (state => snapshot%state)
      self%new_bytes = self%new_bytes + 8_int64*(size(state%positions) + size(state%momenta) + size(state%gamma) + &
                                                 size(state%tau) + size(state%theta))
    end associate
  end subroutine hold

  !> A window reached the file with every held snapshot: its new spare (the old file) lacks this
  !> window's, which are kept for the next.
  subroutine written(self)
    class(snapshot_window), intent(inout) :: self

    call move_alloc(self%new, self%kept)
    self%kept_count = self%new_count
    allocate (self%new(4))
    self%new_count = 0
    self%new_bytes = 0
  end subroutine written

  !> Appends the snapshot of `state` (every rank its part) at `time` to the closed file `path`
  !> (collective on `comm`, a communicator's Fortran handle), or with `reading` reads the file's
  !> last snapshot into `state` (its arrays allocated to the rank's part) and its `time`; tau as
  !> dataset `tau_name` ('': none, tau being the temperature).
  subroutine transfer_part(path, comm, time, state, tau_name, reading, failure)
    character(len=*), intent(in) :: path, tau_name
    integer, intent(in) :: comm
    real(real64), intent(inout) :: time
    type(distributed_part), intent(inout), target :: state
    logical, intent(in) :: reading
    type(failure_type), intent(out) :: failure
    type(snapshot_layout) :: layout
    real(real64), pointer, contiguous :: gamma(:), tau(:), theta(:)

    layout = snapshot_layout(masses=state%masses, springs=state%springs, dimension=state%dimension, &
                             first_mass=state%first_mass, mass_count=size(state%positions, 2), &
                             first_spring=state%first_spring, spring_count=state%spring_count)
    ! Arrays the state has not are absent (a disassociated pointer is an absent argument), tau too
    ! when it is the temperature.
    gamma => null()
    tau => null()
    theta => null()
    if (size(state%theta) > 0) theta => state%theta
    if (size(state%gamma) > 0 .and. size(state%theta) > 0) gamma => state%gamma
    if (size(state%theta) > 0 .and. len(tau_name) > 0) tau => state%tau
    if (reading) then
      call read_last_snapshot(path, comm, layout, time, state%positions, state%momenta, failure, viscous_strains=gamma, &
                              tau=tau, tau_name=tau_name, temperatures=theta)
    else
      call append_snapshot(path, comm, layout, time, state%positions, state%momenta, failure, viscous_strains=gamma, &
                           tau=tau, tau_name=tau_name, temperatures=theta)
    end if
  end subroutine transfer_part

  ! The snapshot's dataset of tau: the run's own variable when it is the entropy or the internal
  ! energy, none when it is the temperature or the model has none.
  function tau_dataset(variable, thermal) result(name)
    integer, intent(in) :: variable
    logical, intent(in) :: thermal
    character(len=:), allocatable :: name

    name = ''
    if (.not. thermal) return
    if (variable == tau_entropy) name = 'entropy'
    if (variable == tau_internal_energy) name = 'internal_energy'
  end function tau_dataset

  ! The per-step figures of the split path beyond the schema's.
  function diagnostics() result(items)
    type(step_diagnostic) :: items(2)

    items(1) = step_diagnostic('min_viscous_production', 'W/K', 'the step''s smallest entropy production of a '// &
                               'spring''s viscous branch, Theta y^2/eta (docs/formulation.md section 10); NaN '// &
                               'without viscous branches', 'min')
    items(2) = step_diagnostic('min_link_production', 'W/K', 'the step''s smallest entropy production of a '// &
                               'conducting link, kappa (Theta_a - Theta_b)^2/(Theta_a Theta_b); NaN without links', &
                               'min')
  end function diagnostics

end module distributed_simulation
