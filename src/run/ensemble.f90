!> Runs the cases of a study on all ranks of MPI_COMM_WORLD, which serves only the scheduling:
!> each case runs on one rank through run_simulation, the same code path as eme_run, solving on
!> PETSC_COMM_SELF. Cases go out largest first (planned steps), dynamically: a rank that finishes
!> asks rank 0 for the next one. Rank 0 computes cases too and serves requests between its own
!> time steps (a run_observer), so no core idles as a pure manager.
!>
!> Files, in the study's output_dir: case_NNNNN.h5 per case, written as case_NNNNN.h5.part and
!> renamed when the case ends (complete or failed), so a killed study leaves no file that looks
!> finished; and index.h5, whose dataset /cases has one row per case (h5py: f['cases'][:]),
!> written with every case pending before any runs and updated by rank 0 as cases end. Running
!> the study again keeps the cases the index records as complete whose files exist, and redoes
!> the others; `run_count` counts how often each case has run.
module ensemble
  use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_COMM_WORLD, MPI_Send, MPI_Recv, MPI_Iprobe, MPI_Probe, &
                     MPI_Status, MPI_Bcast, MPI_ANY_SOURCE, MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_CHARACTER, &
                     MPI_Wtime, MPI_STATUS_IGNORE
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use study_config, only: study_definition
  use run_config, only: run_configuration
  use simulation, only: run_summary, run_simulation, run_observer
  use step_solver, only: snes_solver
  use hdf5_series, only: hdf5_file
  use hdf5_table, only: table_columns, column_real, column_integer, table_rows
  use filesystem, only: make_directories, rename_file
  use build_info, only: code_version
  use number_text, only: integer_text, fixed_text
  implicit none (type, external)
  private
  public :: run_study, study_outcome, world_rank, line_reporter

  abstract interface
    !> Receives a line for the user (the start, progress and warnings); the driver prints it.
    subroutine line_reporter(text)
      character(len=*), intent(in) :: text
    end subroutine line_reporter
  end interface

  integer, parameter :: status_length = 256
  integer, parameter :: tag_request = 1, tag_status = 2, tag_assign = 3
  integer, parameter :: metric_count = 11
  real(real64), parameter :: progress_interval = 2.0_real64   !! seconds between progress lines

  !> What happened to one case (an index row without its parameters).
  type :: case_result
    character(len=status_length) :: status = 'pending'
    real(real64) :: metrics(metric_count) = 0.0_real64
  end type case_result
  ! metrics: steps_completed, steps_planned, newton_iterations, wall_time_seconds, solve_time_seconds,
  ! energy_drift, min_entropy_increment, max_lyapunov_increment, angular_momentum_drift, rank, run_count
  integer, parameter :: m_run_count = 11, m_rank = 10

  !> Counts at the end of a study (on every rank; meaningful on rank 0).
  type :: study_outcome
    integer :: cases = 0
    integer :: complete = 0
    integer :: failed = 0
    integer :: skipped = 0     !! complete from an earlier run, not rerun
    integer :: index_errors = 0   !! index rows that could not be written
    real(real64) :: wall_seconds = 0.0_real64
  end type study_outcome

  !> Rank 0's state: the queue, the results, the index, and the ranks still working.
  type, extends(run_observer) :: study_manager
    type(study_definition), pointer :: study => null()
    integer, allocatable :: queue(:)          !! case numbers, largest first
    integer :: next = 1                       !! next position in the queue
    type(case_result), allocatable :: results(:)
    type(hdf5_file) :: index
    type(table_columns) :: columns
    integer :: active_workers = 0
    integer :: done = 0
    integer :: failed = 0
    integer :: index_errors = 0
    procedure(line_reporter), pointer, nopass :: report => null()
    real(real64) :: started = 0.0_real64
    real(real64) :: last_progress = 0.0_real64
    real(real64) :: planned_cost = 0.0_real64
    real(real64) :: done_cost = 0.0_real64
  contains
    procedure :: after_step => serve_requests
  end type study_manager

contains

  !> This process's rank in MPI_COMM_WORLD.
  integer function world_rank()
    call MPI_Comm_rank(MPI_COMM_WORLD, world_rank)
  end function world_rank

  !> Runs every pending case of `study`. Collective over MPI_COMM_WORLD. stat /= 0 (on every
  !> rank) if the index could not be prepared; failed cases are not errors. Rank 0 hands its
  !> start line, progress lines and warnings to `report`.
  subroutine run_study(study, outcome, stat, message, report)
    type(study_definition), intent(inout), target :: study
    type(study_outcome), intent(out) :: outcome
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    procedure(line_reporter), optional :: report
    type(study_manager) :: manager
    integer :: rank, ranks, flag(1)

    call MPI_Comm_rank(MPI_COMM_WORLD, rank)
    call MPI_Comm_size(MPI_COMM_WORLD, ranks)
    if (present(report)) manager%report => report
    message = ''
    stat = 0
    outcome%cases = size(study%cases)
    if (rank == 0) call prepare(manager, study, ranks, stat, message)
    flag = stat
    call MPI_Bcast(flag, 1, MPI_INTEGER, 0, MPI_COMM_WORLD)
    stat = flag(1)
    if (stat /= 0) then
      if (rank /= 0) message = 'rank 0 could not prepare the study index'
      return
    end if
    if (rank == 0) then
      call manage(manager, outcome)
    else
      call work(study, rank)
    end if
  end subroutine run_study

  ! ------------------------------------------------------------------ rank 0

  subroutine prepare(manager, study, ranks, stat, message)
    type(study_manager), intent(inout) :: manager
    type(study_definition), intent(in), target :: study
    integer, intent(in) :: ranks
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    integer :: c, i, j
    logical :: pending(size(study%cases))

    manager%study => study
    manager%active_workers = ranks - 1
    manager%started = MPI_Wtime()
    manager%last_progress = manager%started
    allocate (manager%results(size(study%cases)))
    call define_columns(study, manager%columns)
    call make_directories(study%output_dir, stat)
    if (stat /= 0) then
      message = study%input_file//': cannot create the output directory '''//study%output_dir//''''
      return
    end if
    call read_previous_index(manager, stat, message)
    if (stat /= 0) return
    ! A case is done if an earlier run completed it and its file is still there.
    do c = 1, size(study%cases)
      inquire (file=case_file(study, c), exist=pending(c), iostat=stat)
      pending(c) = .not. (stat == 0 .and. pending(c) .and. manager%results(c)%status == 'complete')
      if (pending(c)) manager%results(c)%status = 'pending'
    end do
    call write_index(manager, stat, message)
    if (stat /= 0) return
    ! The queue: pending cases, largest planned cost first (stable for equal costs).
    manager%queue = pack([(c, c=1, size(study%cases))], pending)
    do i = 2, size(manager%queue)
      c = manager%queue(i)
      j = i - 1
      do while (j >= 1)
        if (study%cases(manager%queue(j))%cost >= study%cases(c)%cost) exit
        manager%queue(j + 1) = manager%queue(j)
        j = j - 1
      end do
      manager%queue(j + 1) = c
    end do
    manager%planned_cost = sum(study%cases(manager%queue)%cost)
    manager%done = count(.not. pending)
    call say(manager, 'eme_ensemble: '//integer_text(size(study%cases))//' cases, '//integer_text(size(manager%queue)) &
             //' to run ('//integer_text(manager%done)//' complete from an earlier run), on '//integer_text(ranks) &
             //' rank'//repeat('s', merge(0, 1, ranks == 1)))
  end subroutine prepare

  subroutine manage(manager, outcome)
    type(study_manager), intent(inout) :: manager
    type(study_outcome), intent(inout) :: outcome
    type(case_result) :: result
    type(snes_solver), target :: solver
    integer :: c, skipped, ierr, stat

    skipped = manager%done
    do
      call manager%after_step()
      c = take_next(manager)
      if (c == 0) exit
      call run_case(manager%study, c, 0, result, solver, manager)
      call record(manager, c, result)
    end do
    ! Nothing left to start: collect the last results and stop every worker.
    do while (manager%active_workers > 0)
      call serve_one(manager, blocking=.true.)
    end do
    if (solver%created) call solver%destroy(ierr)
    call progress(manager, final=.true.)
    outcome%complete = count(manager%results%status == 'complete')
    outcome%failed = count(manager%results%status(1:7) == 'failed:')
    outcome%skipped = skipped
    outcome%wall_seconds = MPI_Wtime() - manager%started
    call manager%index%close(stat)
    if (stat /= 0) manager%index_errors = manager%index_errors + 1
    outcome%index_errors = manager%index_errors
  end subroutine manage

  ! Observer hook: between two of rank 0's own steps, answer every waiting request.
  subroutine serve_requests(self)
    class(study_manager), intent(inout) :: self

    if (self%active_workers > 0) call serve_one(self, blocking=.false.)
    call progress(self, final=.false.)
  end subroutine serve_requests

  ! Receives requests (a finished case's result, or none) and answers each with a case number,
  ! or 0 to stop. Non-blocking: only what has arrived; blocking: waits for one request.
  subroutine serve_one(manager, blocking)
    type(study_manager), intent(inout) :: manager
    logical, intent(in) :: blocking
    type(MPI_Status) :: probe
    type(case_result) :: result
    real(real64) :: message(metric_count + 1)
    integer :: c(1)
    logical :: waiting

    do
      if (blocking) then
        call MPI_Probe(MPI_ANY_SOURCE, tag_request, MPI_COMM_WORLD, probe)
        waiting = .true.
      else
        call MPI_Iprobe(MPI_ANY_SOURCE, tag_request, MPI_COMM_WORLD, waiting, probe)
      end if
      if (.not. waiting) return
      call MPI_Recv(message, metric_count + 1, MPI_DOUBLE_PRECISION, probe%MPI_SOURCE, tag_request, MPI_COMM_WORLD, &
                    MPI_STATUS_IGNORE)
      call MPI_Recv(result%status, status_length, MPI_CHARACTER, probe%MPI_SOURCE, tag_status, MPI_COMM_WORLD, &
                    MPI_STATUS_IGNORE)
      if (message(1) > 0) then
        result%metrics = message(2:)
        call record(manager, nint(message(1)), result)
      end if
      c(1) = take_next(manager)
      if (c(1) == 0) manager%active_workers = manager%active_workers - 1
      call MPI_Send(c, 1, MPI_INTEGER, probe%MPI_SOURCE, tag_assign, MPI_COMM_WORLD)
      if (blocking) return
    end do
  end subroutine serve_one

  integer function take_next(manager)
    type(study_manager), intent(inout) :: manager

    take_next = 0
    if (manager%next > size(manager%queue)) return
    take_next = manager%queue(manager%next)
    manager%next = manager%next + 1
  end function take_next

  ! Stores a case's result and writes its index row.
  subroutine record(manager, c, result)
    type(study_manager), intent(inout) :: manager
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    integer :: stat

    manager%results(c)%status = result%status
    manager%results(c)%metrics(1:m_rank) = result%metrics(1:m_rank)
    manager%results(c)%metrics(m_run_count) = manager%results(c)%metrics(m_run_count) + 1
    manager%done = manager%done + 1
    if (result%status(1:7) == 'failed:') manager%failed = manager%failed + 1
    manager%done_cost = manager%done_cost + manager%study%cases(c)%cost
    call write_row(manager, c, stat)
    if (stat == 0) call manager%index%flush(stat)
    if (stat /= 0) then
      manager%index_errors = manager%index_errors + 1
      call say(manager, 'eme_ensemble: could not update index.h5 for case '//integer_text(c))
    end if
  end subroutine record

  ! One line at most every progress_interval seconds, and a last one at the end.
  subroutine progress(manager, final)
    type(study_manager), intent(inout) :: manager
    logical, intent(in) :: final
    real(real64) :: now, elapsed, remaining

    now = MPI_Wtime()
    if (.not. final .and. now - manager%last_progress < progress_interval) return
    manager%last_progress = now
    elapsed = now - manager%started
    remaining = 0.0_real64
    if (manager%done_cost > 0) remaining = elapsed*(manager%planned_cost - manager%done_cost)/manager%done_cost
    call say(manager, 'eme_ensemble: '//integer_text(manager%done)//'/'//integer_text(size(manager%results)) &
             //' cases done, '//integer_text(manager%failed)//' failed, '//fixed_text(elapsed, 1) &
             //' s elapsed, about '//fixed_text(remaining, 1)//' s left')
  end subroutine progress

  ! Hands a line to the driver's reporter, if it gave one.
  subroutine say(manager, text)
    type(study_manager), intent(in) :: manager
    character(len=*), intent(in) :: text

    if (associated(manager%report)) call manager%report(text)
  end subroutine say

  ! ------------------------------------------------------------------ workers

  subroutine work(study, rank)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: rank
    type(case_result) :: result
    type(snes_solver), target :: solver
    real(real64) :: message(metric_count + 1)
    integer :: c(1), ierr

    message = 0.0_real64
    result%status = ''
    do
      call MPI_Send(message, metric_count + 1, MPI_DOUBLE_PRECISION, 0, tag_request, MPI_COMM_WORLD)
      call MPI_Send(result%status, status_length, MPI_CHARACTER, 0, tag_status, MPI_COMM_WORLD)
      call MPI_Recv(c, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
      if (c(1) == 0) exit
      call run_case(study, c(1), rank, result, solver)
      message = [real(c(1), real64), result%metrics]
    end do
    if (solver%created) call solver%destroy(ierr)
  end subroutine work

  ! ------------------------------------------------------------------ one case, any rank

  ! The rank's PETSc objects, reused from case to case (recreated when the unknowns change).
  subroutine run_case(study, c, rank, result, solver, observer)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c, rank
    type(case_result), intent(out) :: result
    type(snes_solver), intent(inout), target :: solver
    class(run_observer), intent(inout), optional :: observer
    type(run_configuration) :: config
    type(run_summary) :: summary
    character(len=:), allocatable :: message, final_file
    integer :: stat, rename_stat, inquire_stat
    logical :: written

    config = study%cases(c)%config
    final_file = case_file(study, c)
    config%output_file = final_file//'.part'
    call run_simulation(config, summary, stat, message, observer, solver)
    if (stat /= 0) then
      result%status = 'failed: '//message
    else if (summary%status == 'complete') then
      result%status = 'complete'
    else
      result%status = 'failed: '//summary%status
    end if
    inquire (file=config%output_file, exist=written, iostat=inquire_stat)
    if (inquire_stat == 0 .and. written) then
      call rename_file(config%output_file, final_file, rename_stat)
      if (rename_stat /= 0) result%status = 'failed: cannot rename '//config%output_file
    end if
    result%metrics = [real(summary%steps_completed, real64), real(summary%steps_planned, real64), &
                      real(summary%newton_iterations, real64), summary%wall_seconds, summary%solve_seconds, &
                      summary%energy_drift, &
                      summary%min_entropy_increment, summary%max_lyapunov_increment, &
                      summary%angular_momentum_drift, real(rank, real64), 0.0_real64]
  end subroutine run_case

  ! ------------------------------------------------------------------ the index

  pure function case_file(study, c) result(path)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c
    character(len=:), allocatable :: path
    character(len=16) :: name

    write (name, '("case_", i5.5, ".h5")') c
    path = study%output_dir//'/'//trim(name)
  end function case_file

  ! case, file, one column per sweep, status, the metrics, rank and run_count.
  subroutine define_columns(study, columns)
    type(study_definition), intent(in) :: study
    type(table_columns), intent(out) :: columns
    integer :: s

    call columns%add('case', column_integer)
    call columns%add('file', 64)
    do s = 1, size(study%sweeps)
      if (study%sweeps(s)%textual) then
        call columns%add(study%sweeps(s)%field, 64)
      else
        call columns%add(study%sweeps(s)%field, column_real)
      end if
    end do
    call columns%add('status', status_length)
    call columns%add('steps_completed', column_integer)
    call columns%add('steps_planned', column_integer)
    call columns%add('newton_iterations', column_integer)
    call columns%add('wall_time_seconds', column_real)
    call columns%add('solve_time_seconds', column_real)
    call columns%add('energy_drift', column_real)
    call columns%add('min_entropy_increment', column_real)
    call columns%add('max_lyapunov_increment', column_real)
    call columns%add('angular_momentum_drift', column_real)
    call columns%add('rank', column_integer)
    call columns%add('run_count', column_integer)
  end subroutine define_columns

  ! The row of case c: numbers and texts in column order.
  subroutine row_values(manager, c, numbers, texts)
    type(study_manager), intent(in) :: manager
    integer, intent(in) :: c
    real(real64), allocatable, intent(out) :: numbers(:)
    character(len=status_length), allocatable, intent(out) :: texts(:)
    character(len=16) :: name
    real(real64) :: value
    integer :: s, ios

    write (name, '("case_", i5.5, ".h5")') c
    numbers = [real(c, real64)]
    texts = [character(len=status_length) :: name]
    do s = 1, size(manager%study%sweeps)
      associate (sweep => manager%study%sweeps(s), item => manager%study%cases(c)%overrides(s)%item)
        if (sweep%textual) then
          texts = [character(len=status_length) :: texts, unquoted(item(index(item, '=') + 1:))]
        else
          read (item(index(item, '=') + 1:), *, iostat=ios) value
          if (ios /= 0) value = ieee_value(value, ieee_quiet_nan)
          numbers = [numbers, value]
        end if
      end associate
    end do
    texts = [texts, manager%results(c)%status]
    numbers = [numbers, manager%results(c)%metrics]
  end subroutine row_values

  subroutine write_row(manager, c, stat)
    type(study_manager), intent(inout) :: manager
    integer, intent(in) :: c
    integer, intent(out) :: stat
    real(real64), allocatable :: numbers(:)
    character(len=status_length), allocatable :: texts(:)

    call row_values(manager, c, numbers, texts)
    call manager%columns%write_row(manager%index%id, 'cases', c, numbers, texts, stat)
  end subroutine write_row

  ! Creates index.h5 with every case's row (pending, or kept from an earlier run).
  subroutine write_index(manager, stat, message)
    type(study_manager), intent(inout) :: manager
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    integer :: c
    character(len=:), allocatable :: path, ignored

    path = manager%study%output_dir//'/index.h5'
    message = 'cannot write '//path
    call manager%index%create(path, stat, ignored)
    if (stat /= 0) return
    call manager%columns%create(manager%index%id, 'cases', size(manager%results), stat)
    if (stat == 0) call manager%index%set_text('study', manager%study%input_file, stat)
    if (stat == 0) call manager%index%set_text('base', manager%study%base, stat)
    if (stat == 0) call manager%index%set_text('combine', manager%study%combine, stat)
    if (stat == 0) call manager%index%set_text('code_version', code_version, stat)
    do c = 1, size(manager%results)
      if (stat == 0) call write_row(manager, c, stat)
    end do
    if (stat == 0) call manager%index%flush(stat)
    if (stat == 0) message = ''
  end subroutine write_index

  ! Results of an earlier run of the same study, if its index.h5 exists. A different case list
  ! (other sweeps or values) is an error: the old files would not match their rows.
  subroutine read_previous_index(manager, stat, message)
    type(study_manager), intent(inout) :: manager
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(hdf5_file) :: old
    real(real64), allocatable :: numbers(:), old_numbers(:)
    character(len=status_length), allocatable :: texts(:), old_texts(:)
    character(len=:), allocatable :: path
    integer :: c, rows, n_sweep_numbers, close_stat
    logical :: exists

    stat = 0
    message = ''
    path = manager%study%output_dir//'/index.h5'
    inquire (file=path, exist=exists, iostat=close_stat)
    if (close_stat /= 0 .or. .not. exists) return
    call old%open_existing(path, .false., stat)
    if (stat /= 0) then
      message = 'cannot read '//path//' of an earlier run; remove it to start the study afresh'
      return
    end if
    rows = table_rows(old%id, 'cases')
    if (rows /= size(manager%results)) then
      stat = 1
      message = path//' belongs to a different study (its case count differs); use another output_dir or remove it'
    end if
    do c = 1, rows
      if (stat /= 0) exit
      call row_values(manager, c, numbers, texts)
      allocate (old_numbers(size(numbers)), old_texts(size(texts)))
      call manager%columns%read_row(old%id, 'cases', c, old_numbers, old_texts, stat)
      ! The parameters (case, file, sweep values) must be the same; keep status and metrics.
      n_sweep_numbers = size(numbers) - metric_count
      if (stat /= 0 .or. any(abs(old_numbers(1:n_sweep_numbers) - numbers(1:n_sweep_numbers)) > 0.0_real64) .or. &
          any(old_texts(1:size(texts) - 1) /= texts(1:size(texts) - 1))) then
        stat = 1
        message = path//' belongs to a different study (case '//integer_text(c)// &
                  ' differs); use another output_dir or remove it'
      else
        manager%results(c)%status = old_texts(size(texts))
        manager%results(c)%metrics = old_numbers(n_sweep_numbers + 1:)
      end if
      deallocate (old_numbers, old_texts)
    end do
    call old%close(close_stat)
  end subroutine read_previous_index

  pure function unquoted(text) result(plain)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: plain

    plain = trim(adjustl(text))
    if (len(plain) >= 2) then
      if (index('''"', plain(1:1)) > 0) plain = plain(2:len(plain) - 1)
    end if
  end function unquoted

end module ensemble
