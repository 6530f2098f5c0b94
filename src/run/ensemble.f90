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
  use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_COMM_WORLD, MPI_Bcast, MPI_INTEGER, MPI_Wtime
  use, intrinsic :: iso_fortran_env, only: real64
  use study_config, only: study_definition
  use study_index, only: case_index, case_result, metric_count
  use run_signals, only: install_interrupt_handlers
  use simulation, only: run_observer, line_reporter
  use stepper, only: time_stepper
  use hdf5_files, only: file_template
  use number_text, only: integer_text
  use filesystem, only: output_lock, lock_output, unlock_output, lock_held_elsewhere, lock_not_offered
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

  ! Implemented in ensemble_workers.
  interface
    ! A worker holds its next case while it computes one: it asks for the next before it starts a
    ! case, so that it never waits for rank 0, which answers between its own steps.
    module subroutine work(study, rank)
      type(study_definition), intent(in) :: study
      integer, intent(in) :: rank
    end subroutine work

    ! One case with the rank's integrator, reused from case to case (run_simulation replaces it
    ! when a case needs another kind), and the rank's template of its case files' root attributes
    ! (the first case's; a case writes only those that differ). Its file names its study, case
    ! number, overrides and rank. A case that eme_run would split (split_run_wanted on one rank)
    ! runs on the split path on this rank alone, with its own solver and no template: its file has
    ! other datasets, and a long case gains nothing from the template's half millisecond.
    module subroutine run_case(study, c, rank, result, integrator, template, observer)
      type(study_definition), intent(in) :: study
      integer, intent(in) :: c, rank
      type(case_result), intent(out) :: result
      class(time_stepper), allocatable, intent(inout), target :: integrator
      type(file_template), intent(inout), target :: template
      class(run_observer), intent(inout), optional :: observer
    end subroutine run_case
  end interface

  ! Implemented in ensemble_manager.
  interface
    module subroutine manage(manager, outcome)
      type(study_manager), intent(inout) :: manager
      type(study_outcome), intent(inout) :: outcome
    end subroutine manage

    ! Observer hook: between two of rank 0's own steps, answer every waiting request.
    module subroutine serve_requests(self)
      class(study_manager), intent(inout) :: self
    end subroutine serve_requests

    ! Hands a line to the driver's reporter, if it gave one.
    module subroutine say(manager, text)
      type(study_manager), intent(in) :: manager
      character(len=*), intent(in) :: text
    end subroutine say
  end interface

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

  ! ------------------------------------------------------------------ workers

  ! ------------------------------------------------------------------ one case, any rank

end module ensemble
