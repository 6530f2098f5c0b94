!> Runs the cases of a study on all ranks of MPI_COMM_WORLD, which serves only the scheduling:
!> each case runs on one rank through the same code path as eme_run on one process, solving on
!> PETSC_COMM_SELF: run_simulation (the dense path), or run_distributed on MPI_COMM_SELF for a
!> model that eme_run would split (a spring chain beyond the dense path's 1000 unknowns). Cases go out largest first (planned steps), dynamically: a rank that finishes
!> asks rank 0 for the next one. Rank 0 computes cases too and serves requests between its own
!> time steps (a run_observer), so no core idles as a pure manager.
!>
!> Files: case_NNNNN.h5 per case in the study's output_dir (none in an index-only study), written
!> as case_NNNNN.h5.part and renamed when the case ends, so a killed study leaves no file that
!> looks finished; rank 0 records each result in the study's index (src/run/study_index) as the
!> case ends, and running the study again redoes only what the index does not record as
!> complete. SIGTERM or SIGINT stops the study cleanly: no new case starts, running cases end
!> marked 'incomplete: interrupted by <signal>', and the index is written; so does an output
!> that cannot be written (a full disk), since every later case would fail the same way.
module ensemble
  use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_COMM_WORLD, MPI_COMM_SELF, MPI_Send, MPI_Recv, MPI_Irecv, MPI_Wait, &
                     MPI_Iprobe, MPI_Probe, MPI_Status, MPI_Request, MPI_Bcast, MPI_ANY_SOURCE, MPI_DOUBLE_PRECISION, &
                     MPI_INTEGER, MPI_CHARACTER, MPI_Wtime, MPI_STATUS_IGNORE
  use, intrinsic :: iso_fortran_env, only: real64
  use study_config, only: study_definition
  use study_index, only: case_index, case_result, status_length, kind_length, metric_count, m_warned
  use study_case_files, only: case_file, case_overrides
  use run_config, only: run_configuration
  use run_outcome, only: failure_io, failure_interrupted
  use run_signals, only: install_interrupt_handlers, interrupting_signal, signal_name
  use simulation, only: run_summary, run_simulation, run_observer, line_reporter, extra_attribute
  use distributed_simulation, only: run_distributed, split_run_wanted
  use statistics, only: median
  use stepper, only: time_stepper
  use hdf5_files, only: file_template
  use number_text, only: integer_text, fixed_text
  use filesystem, only: output_lock, lock_output, unlock_output, lock_held_elsewhere, lock_not_offered, recheck_lock
  use failures, only: failure_type, fail, code_input => failure_input, code_io => failure_io
  implicit none (type, external)
  private
  public :: run_study, study_outcome, world_rank, line_reporter

  !> run_study's stat when another study holds the lock of output_dir (the drivers' exit status 2).

  integer, parameter :: tag_request = 1, tag_status = 2, tag_assign = 3
  integer, parameter :: message_length = metric_count + 2    !! case, metrics, leaving
  ! A request's last value: the worker goes on (and is answered with its next case), or leaves
  ! after this answer (no case left, or a signal stopped it).
  real(real64), parameter :: going_on = 0.0_real64, leaving = 1.0_real64
  real(real64), parameter :: progress_interval = 2.0_real64   !! seconds between progress lines

  !> Counts at the end of a study (on every rank).
  type :: study_outcome
    integer :: cases = 0
    integer :: complete = 0
    integer :: failed = 0
    integer :: skipped = 0     !! complete from an earlier run, not rerun
    integer :: index_errors = 0   !! times the index could not be written
    integer :: signal = 0      !! the SIGTERM or SIGINT that stopped the study, or 0
    logical :: io_failure = .false.   !! a case's output or the index could not be written
    character(len=:), allocatable :: io_message
    real(real64) :: wall_seconds = 0.0_real64
  end type study_outcome

  !> Rank 0's state: the queue, the index, and the ranks still working.
  type, extends(run_observer) :: study_manager
    type(study_definition), pointer :: study => null()
    integer, allocatable :: queue(:)          !! case numbers, largest first
    integer :: next = 1                       !! next position in the queue
    type(case_index) :: index
    integer :: active_workers = 0
    integer :: done = 0
    integer :: failed = 0
    integer :: index_errors = 0
    logical :: stopping = .false.             !! hand out no more cases
    character(len=:), allocatable :: io_message
    type(output_lock) :: lock                 !! output_dir/study.lock: one study at a time in output_dir
    logical :: lock_lost = .false.            !! it was removed or replaced behind the study's back
    logical :: index_lost = .false.           !! ... and another study holds it: the index is not ours
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

  !> Runs every pending case of `study`. Collective over MPI_COMM_WORLD. A failure (on every
  !> rank, with rank 0's code): failure_input if another study holds output_dir (nothing is
  !> written) or output_dir holds cases this study refuses, another code if the index could not
  !> be prepared; failed cases are not failures. Rank 0 hands its start line, progress lines and
  !> warnings to `report`.
  subroutine run_study(study, outcome, failure, report)
    type(study_definition), intent(inout), target :: study
    type(study_outcome), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    procedure(line_reporter), optional :: report
    type(study_manager) :: manager            !! (rank 0's, with the lock of output_dir)
    type(failure_type) :: handlers
    integer :: rank, ranks, flag(1), counts(7)

    call MPI_Comm_rank(MPI_COMM_WORLD, rank)
    call MPI_Comm_size(MPI_COMM_WORLD, ranks)
    call install_interrupt_handlers(handlers)     ! (a study without them still runs)
    if (present(report)) manager%report => report
    outcome%io_message = ''
    outcome%cases = size(study%cases)
    if (rank == 0) call lock_directory(study, manager%lock, failure, report)
    if (rank == 0 .and. .not. failure%failed()) call prepare(manager, study, ranks, failure)
    flag = failure%code
    call MPI_Bcast(flag, 1, MPI_INTEGER, 0, MPI_COMM_WORLD)
    if (flag(1) /= 0) then
      if (rank /= 0) call fail(failure, flag(1), 'rank 0 could not prepare the study index')
      call unlock_output(manager%lock)
      return
    end if
    if (rank == 0) then
      call manage(manager, outcome)
    else
      call work(study, rank)
    end if
    ! Every rank ends with rank 0's verdict (the drivers' exit status).
    counts = [outcome%complete, outcome%failed, outcome%skipped, outcome%index_errors, outcome%signal, &
              merge(1, 0, outcome%io_failure), 0]
    call MPI_Bcast(counts, size(counts), MPI_INTEGER, 0, MPI_COMM_WORLD)
    outcome%complete = counts(1)
    outcome%failed = counts(2)
    outcome%skipped = counts(3)
    outcome%index_errors = counts(4)
    outcome%signal = counts(5)
    outcome%io_failure = counts(6) == 1
    call unlock_output(manager%lock)
  end subroutine run_study

  ! Takes the lock of the study's output_dir (created if missing), output_dir/study.lock, so that
  ! a second study there is refused before it writes anything. A failure: failure_input (the
  ! directory is in use), or the OS's words (the lock file cannot be made).
  subroutine lock_directory(study, lock, failure, report)
    type(study_definition), intent(in) :: study
    type(output_lock), intent(out) :: lock
    type(failure_type), intent(out) :: failure
    procedure(line_reporter), optional :: report
    character(len=:), allocatable :: holder, reason
    integer :: found

    call lock_output(lock, study%output_dir//'/study.lock', found, holder, failure)
    if (failure%failed()) then
      reason = failure%message
      call fail(failure, code_io, study%input_file//': cannot create the lock file '''//study%output_dir// &
                '/study.lock'': '//reason, study%input_file)
    else if (found == lock_held_elsewhere) then
      if (len(holder) == 0) holder = 'another process'
      call fail(failure, code_input, study%output_dir//' (output_dir of '//study%input_file//') is in use by '// &
                'another study, '//holder//', which holds '//study%output_dir//'/study.lock; this study is '// &
                'refused and writes nothing', study%output_dir)
    else if (found == lock_not_offered) then
      if (present(report)) call report('eme_ensemble: warning: the file system of '//study%output_dir//' offers no '// &
                                       'lock; a second study there at the same time would not be refused')
    end if
  end subroutine lock_directory

  ! ------------------------------------------------------------------ rank 0

  subroutine prepare(manager, study, ranks, failure)
    type(study_manager), intent(inout) :: manager
    type(study_definition), intent(in), target :: study
    integer, intent(in) :: ranks
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: notes
    integer :: c, i, j, start
    logical, allocatable :: pending(:)

    manager%study => study
    manager%active_workers = ranks - 1
    manager%started = MPI_Wtime()
    manager%last_progress = manager%started
    manager%io_message = ''
    call manager%index%open(study, pending, notes, failure, ranks)
    if (failure%failed()) return
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
    start = 1
    do while (start <= len(notes))
      i = index(notes(start:), new_line('a'))
      if (i == 0) i = len(notes) - start + 2
      call say(manager, 'eme_ensemble: '//notes(start:start + i - 2))
      start = start + i
    end do
    call say_warnings(manager, study)
    call say(manager, 'eme_ensemble: '//integer_text(size(study%cases))//' cases, '//integer_text(size(manager%queue)) &
             //' to run ('//integer_text(manager%done)//' complete from an earlier run), on '//integer_text(ranks) &
             //' rank'//repeat('s', merge(0, 1, ranks == 1))//trim(merge('; only the index is kept (index_only)', &
                                                                      '                                     ', &
                                                                      study%index_only)))
  end subroutine prepare

  ! Each swept setting that a case's integrator does not read, once, with how many cases (the
  ! base input is a template every case shares: its settings for other integrators are not named),
  ! and each temperature that looks like degrees Celsius, once for the study.
  subroutine say_warnings(manager, study)
    type(study_manager), intent(inout) :: manager
    type(study_definition), intent(in) :: study
    character(len=400), allocatable :: seen(:)
    integer, allocatable :: cases(:)
    integer :: c, k, w

    allocate (seen(0), cases(0))
    do c = 1, size(study%cases)
      if (.not. allocated(study%cases(c)%config%warnings)) cycle
      do w = 1, size(study%cases(c)%config%warnings)
        if (index(study%cases(c)%config%warnings(w), study%input_file//': &sweep') /= 1 .and. &
            index(study%cases(c)%config%warnings(w), 'looks like degrees Celsius') == 0) cycle
        k = findloc(seen, study%cases(c)%config%warnings(w), dim=1)
        if (k == 0) then
          seen = [seen, study%cases(c)%config%warnings(w)]
          cases = [cases, 1]
        else
          cases(k) = cases(k) + 1
        end if
      end do
    end do
    do k = 1, size(seen)
      call say(manager, 'eme_ensemble: warning: '//trim(seen(k))//' ('//integer_text(cases(k))//' case'// &
               repeat('s', merge(0, 1, cases(k) == 1))//')')
    end do
  end subroutine say_warnings

  subroutine manage(manager, outcome)
    type(study_manager), intent(inout) :: manager
    type(study_outcome), intent(inout) :: outcome
    type(case_result) :: result
    class(time_stepper), allocatable :: integrator
    type(file_template), target :: template     !! the root attributes of the rank's case files
    integer :: c, skipped
    type(failure_type) :: release_failure, closing

    skipped = manager%done
    do
      call manager%after_step()
      c = take_next(manager)
      if (c == 0) exit
      call run_case(manager%study, c, 0, result, integrator, template, manager)
      call record(manager, c, result)
    end do
    ! Nothing left to start: collect the last results and stop every worker.
    do while (manager%active_workers > 0)
      call serve_one(manager, blocking=.true.)
    end do
    if (allocated(integrator)) call integrator%release(release_failure)
    call progress(manager, final=.true.)
    outcome%complete = count(manager%index%results%status == 'complete')
    outcome%failed = count(manager%index%results%status(1:7) == 'failed:')
    outcome%skipped = skipped
    outcome%wall_seconds = MPI_Wtime() - manager%started
    call guard_lock(manager)
    if (.not. manager%index_lost) call manager%index%close(closing)
    if (closing%failed()) then
      call index_failed(manager, closing)
      call say(manager, 'eme_ensemble: '//closing%message//'; '//manager%index%journal_path//' holds every result; running '// &
               'the study again (with room) rewrites the index')
    end if
    outcome%index_errors = manager%index_errors
    outcome%signal = interrupting_signal()
    outcome%io_failure = len(manager%io_message) > 0
    outcome%io_message = manager%io_message
  end subroutine manage

  ! Observer hook: between two of rank 0's own steps, answer every waiting request.
  subroutine serve_requests(self)
    class(study_manager), intent(inout) :: self

    if (self%active_workers > 0) call serve_one(self, blocking=.false.)
    call progress(self, final=.false.)
  end subroutine serve_requests

  ! Receives requests (a finished case's result, or none) and answers each with a case number,
  ! or 0: none left. A worker that says it is leaving gets 0 and is no longer waited for.
  ! Non-blocking: only what has arrived; blocking: waits for one request.
  subroutine serve_one(manager, blocking)
    type(study_manager), intent(inout) :: manager
    logical, intent(in) :: blocking
    type(MPI_Status) :: probe
    type(case_result) :: result
    real(real64) :: message(message_length)
    character(len=status_length + kind_length) :: texts
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
      call MPI_Recv(message, message_length, MPI_DOUBLE_PRECISION, probe%MPI_SOURCE, tag_request, MPI_COMM_WORLD, &
                    MPI_STATUS_IGNORE)
      call MPI_Recv(texts, len(texts), MPI_CHARACTER, probe%MPI_SOURCE, tag_status, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
      if (message(1) > 0) then
        result%status = texts(1:status_length)
        result%failure_kind = texts(status_length + 1:)
        result%metrics = message(2:metric_count + 1)
        call record(manager, nint(message(1)), result)
      end if
      if (message(message_length) > going_on) then
        c(1) = 0
        manager%active_workers = manager%active_workers - 1
      else
        c(1) = take_next(manager)
      end if
      call MPI_Send(c, 1, MPI_INTEGER, probe%MPI_SOURCE, tag_assign, MPI_COMM_WORLD)
      if (blocking) return
    end do
  end subroutine serve_one

  ! The next case to start, or 0 when none is left or the study is stopping.
  integer function take_next(manager)
    type(study_manager), intent(inout) :: manager
    integer :: signal

    take_next = 0
    signal = interrupting_signal()
    if (signal /= 0 .and. .not. manager%stopping) then
      manager%stopping = .true.
      call say(manager, 'eme_ensemble: '//signal_name(signal)//' received: no new cases; the running ones stop '// &
               'after their current step, and the index is written (run the study again to go on)')
    end if
    if (manager%stopping .or. manager%next > size(manager%queue)) return
    take_next = manager%queue(manager%next)
    manager%next = manager%next + 1
  end function take_next

  ! Stores a case's result in the index. A case whose output could not be written, or an index
  ! that cannot be, stops the study: every later case would meet the same full disk.
  subroutine record(manager, c, result)
    type(study_manager), intent(inout) :: manager
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    type(failure_type) :: recording

    manager%done = manager%done + 1
    if (result%status(1:7) == 'failed:') manager%failed = manager%failed + 1
    manager%done_cost = manager%done_cost + manager%study%cases(c)%cost
    call guard_lock(manager)
    if (manager%index_lost) return
    call manager%index%record(c, result, recording)
    if (recording%failed()) call index_failed(manager, recording)
    if (result%failure_kind == failure_io .and. len(manager%io_message) == 0) then
      manager%io_message = 'case '//integer_text(c)//': '//trim(result%status)
      manager%stopping = .true.
      call say(manager, 'eme_ensemble: '//manager%io_message//'; no new cases start (run the study again when there '//&
               'is room)')
    end if
  end subroutine record

  ! Before the index is written: whether output_dir/study.lock is still the study's. Removed or
  ! replaced behind its back, it lets a second study in: no new cases start and the study ends as
  ! after a failed write (exit 1); the index and the journal are written on only if the lock can
  ! be taken again, else they are the other study's now.
  subroutine guard_lock(manager)
    type(study_manager), intent(inout) :: manager
    character(len=:), allocatable :: holder, what
    logical :: retaken

    if (manager%lock_lost) return
    call recheck_lock(manager%lock, manager%lock_lost, retaken, what, holder)
    if (.not. manager%lock_lost) return
    manager%stopping = .true.
    manager%index_lost = .not. retaken
    manager%io_message = manager%lock%path//' was '//what//' while the study ran, so that a second study could '// &
                         'start in '//manager%study%output_dir//'; no new cases start'
    if (manager%index_lost) then
      manager%io_message = manager%io_message//', and the index is left to '//holder//', which holds the lock now'
    else
      manager%io_message = manager%io_message//' (the lock was taken again; run the study again to go on)'
    end if
    call say(manager, 'eme_ensemble: '//manager%io_message)
  end subroutine guard_lock

  ! The index could not be written: counted, said once, and no new cases start.
  subroutine index_failed(manager, failure)
    type(study_manager), intent(inout) :: manager
    type(failure_type), intent(in) :: failure

    manager%index_errors = manager%index_errors + 1
    if (len(manager%io_message) == 0) manager%io_message = failure%message
    if (.not. manager%stopping) call say(manager, 'eme_ensemble: '//failure%message//'; no new cases start')
    manager%stopping = .true.
  end subroutine index_failed

  ! One line at most every progress_interval seconds, and a last one at the end.
  subroutine progress(manager, final)
    type(study_manager), intent(inout) :: manager
    logical, intent(in) :: final
    real(real64) :: now, elapsed, remaining
    character(len=:), allocatable :: interrupted, warned, left
    integer :: warned_cases

    now = MPI_Wtime()
    if (.not. final .and. now - manager%last_progress < progress_interval) return
    manager%last_progress = now
    elapsed = now - manager%started
    ! The time left from the cost done so far: none before any case is done (it said 'about 0.0 s
    ! left' then) and none at the end.
    left = ''
    if (manager%done_cost > 0 .and. .not. final) then
      remaining = elapsed*(manager%planned_cost - manager%done_cost)/manager%done_cost
      left = ', about '//fixed_text(remaining, 1)//' s left'
    end if
    ! What the index holds: a case interrupted by a signal or not run yet is neither complete nor failed.
    associate (results => manager%index%results)
      interrupted = ''
      if (count(results%status(1:11) == 'incomplete:') > 0) &
        interrupted = integer_text(count(results%status(1:11) == 'incomplete:'))//' interrupted, '
      ! Complete cases whose accuracy is in doubt (the index's column warned; docs/integrators.md).
      warned = ''
      warned_cases = count(results%status == 'complete' .and. results%metrics(m_warned) > 0)
      if (warned_cases > 0) warned = ' ('//integer_text(warned_cases)//' warned)'
      call say(manager, 'eme_ensemble: '//integer_text(count(results%status == 'complete'))//'/'// &
               integer_text(size(results))//' cases complete'//warned//', '// &
               integer_text(count(results%status(1:7) == 'failed:')) &
               //' failed, '//interrupted//fixed_text(elapsed, 1)//' s elapsed'//left)
    end associate
  end subroutine progress

  ! Hands a line to the driver's reporter, if it gave one.
  subroutine say(manager, text)
    type(study_manager), intent(in) :: manager
    character(len=*), intent(in) :: text

    if (associated(manager%report)) call manager%report(text)
  end subroutine say

  ! ------------------------------------------------------------------ workers

  ! A worker holds its next case while it computes one: it asks for the next before it starts a
  ! case, so that it never waits for rank 0, which answers between its own steps.
  subroutine work(study, rank)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: rank
    type(case_result) :: result
    class(time_stepper), allocatable :: integrator
    type(file_template), target :: template     !! the root attributes of the rank's case files
    type(MPI_Request) :: asked
    real(real64) :: message(message_length)
    character(len=status_length + kind_length) :: texts
    integer :: current(1), next(1)
    type(failure_type) :: release_failure

    message = 0.0_real64
    texts = ''
    call request(message, texts)
    call MPI_Recv(current, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
    if (current(1) /= 0) then
      call request(message, texts)
      call MPI_Irecv(next, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, asked)
    end if
    do while (current(1) /= 0)
      call run_case(study, current(1), rank, result, integrator, template)
      call MPI_Wait(asked, MPI_STATUS_IGNORE)
      message(1:metric_count + 1) = [real(current(1), real64), result%metrics]
      texts = result%status//result%failure_kind
      if (next(1) == 0) exit
      if (interrupting_signal() /= 0) exit      ! the case held next stays pending
      call request(message, texts)
      current = next
      call MPI_Irecv(next, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, asked)
    end do
    ! The last result (if any), and leave.
    message(message_length) = leaving
    call request(message, texts)
    call MPI_Recv(next, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
    if (allocated(integrator)) call integrator%release(release_failure)
  end subroutine work

  ! A request to rank 0: the last result (case 0: none) and whether the worker is leaving.
  subroutine request(message, texts)
    real(real64), intent(in) :: message(:)
    character(len=*), intent(in) :: texts

    call MPI_Send(message, size(message), MPI_DOUBLE_PRECISION, 0, tag_request, MPI_COMM_WORLD)
    call MPI_Send(texts, len(texts), MPI_CHARACTER, 0, tag_status, MPI_COMM_WORLD)
  end subroutine request

  ! ------------------------------------------------------------------ one case, any rank

  ! One case with the rank's integrator, reused from case to case (run_simulation replaces it
  ! when a case needs another kind), and the rank's template of its case files' root attributes
  ! (the first case's; a case writes only those that differ). Its file names its study, case
  ! number, overrides and rank. A case that eme_run would split (split_run_wanted on one rank)
  ! runs on the split path on this rank alone, with its own solver and no template: its file has
  ! other datasets, and a long case gains nothing from the template's half millisecond.
  subroutine run_case(study, c, rank, result, integrator, template, observer)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c, rank
    type(case_result), intent(out) :: result
    class(time_stepper), allocatable, intent(inout), target :: integrator
    type(file_template), intent(inout), target :: template
    class(run_observer), intent(inout), optional :: observer
    type(run_configuration) :: config
    type(run_summary) :: summary
    type(extra_attribute) :: extras(4)
    type(failure_type) :: failure
    real(real64), allocatable :: solve_seconds(:), solve_cpu_seconds(:)      ! on the heap: their size is the input's
    integer :: r
    logical :: split

    config = study%cases(c)%config
    config%output_file = case_file(study, c)
    config%overwrite = .true.          ! the index, not the file, says whether a case is done
    extras(1)%name = 'study'
    extras(1)%text = study%input_file
    extras(2)%name = 'study_case'
    extras(2)%number = c
    extras(3)%name = 'study_overrides'
    extras(3)%text = case_overrides(study, c)
    extras(4)%name = 'study_rank'
    extras(4)%number = rank
    ! With &study repeats = R the case runs R times, only the last keeping its file; the index
    ! gets the median of the time loops' durations (wall and CPU, each its own median), so timings
    ! on a shared machine do not zig-zag.
    allocate (solve_seconds(study%repeats), solve_cpu_seconds(study%repeats))
    ! The path eme_run would take for the case on one process, -eme_split and -eme_dense included
    ! (docs/performance.md, Two paths).
    split = split_run_wanted(config, 1)
    do r = 1, study%repeats
      ! An interrupted case (its file incomplete, with the same input) continues from its file
      ! (the split path from the file's last snapshot).
      if (split) then
        call run_distributed(config, MPI_COMM_SELF%MPI_VAL, summary, failure, observer=observer, &
                             keep_file=.not. study%index_only .and. r == study%repeats, extras=extras, &
                             durable=.false., resume_if_possible=study%repeats == 1)
      else
        call run_simulation(config, summary, failure, observer, integrator, &
                            keep_file=.not. study%index_only .and. r == study%repeats, extras=extras, durable=.false., &
                            template=template, resume_if_possible=study%repeats == 1)
      end if
      solve_seconds(r) = summary%solve_seconds
      solve_cpu_seconds(r) = summary%solve_cpu_seconds
      if (failure%failed() .or. summary%status /= 'complete') exit
    end do
    if (r > study%repeats) then
      summary%solve_seconds = median(solve_seconds)
      summary%solve_cpu_seconds = median(solve_cpu_seconds)
    end if
    if (summary%failure_kind == failure_interrupted) then
      result%status = summary%status
    else if (failure%failed()) then
      result%status = 'failed: '//failure%message
    else if (summary%status == 'complete') then
      result%status = 'complete'
    else
      result%status = 'failed: '//summary%status
    end if
    result%failure_kind = summary%failure_kind
    result%metrics = [real(summary%steps_completed, real64), real(summary%steps_planned, real64), &
                      real(summary%newton_iterations, real64), summary%wall_seconds, summary%solve_seconds, &
                      summary%cpu_seconds, summary%solve_cpu_seconds, summary%energy_drift, &
                      summary%min_entropy_increment, summary%max_lyapunov_increment, &
                      summary%angular_momentum_drift, summary%min_temperature, &
                      real(summary%halved_steps, real64), real(summary%rejected_steps, real64), &
                      merge(1.0_real64, 0.0_real64, len(summary%warnings) > 0), real(rank, real64), 0.0_real64]
  end subroutine run_case

end module ensemble
