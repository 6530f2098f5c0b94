!> Rank 0's part of a study (src/run/ensemble): its queue of cases handed out on request, between its
!> own time steps, each result recorded in the study's index as it comes, the study's lock guarded,
!> and the progress lines. (A .F90 file: docs/development.md, Modules that grow.)
submodule (ensemble) ensemble_manager
  use mpi_f08, only: MPI_Send, MPI_Recv, MPI_Iprobe, MPI_Probe, MPI_Status, MPI_ANY_SOURCE, &
                     MPI_DOUBLE_PRECISION, MPI_CHARACTER, MPI_STATUS_IGNORE
  use study_index, only: status_length, kind_length, m_warned
  use run_outcome, only: failure_io
  use run_signals, only: interrupting_signal, signal_name
  use number_text, only: fixed_text
  use filesystem, only: recheck_lock
  implicit none

contains

  module procedure manage
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
  end procedure manage

  module procedure serve_requests

    if (self%active_workers > 0) call serve_one(self, blocking=.false.)
    call progress(self, final=.false.)
  end procedure serve_requests

  module procedure say

    if (associated(manager%report)) call manager%report(text)
  end procedure say

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

end submodule ensemble_manager
