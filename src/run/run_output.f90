!> The HDF5 file of one run (docs/output.md): the datasets of src/run/run_schema (and the
!> integrator's own), fed a point and a step at a time, the root attributes of src/run/run_attributes,
!> the solver's settings as used, provenance (command line, PETSc options, the effective namelist,
!> versions, host, dates), and the run's outcome (status, failure kind, figures, times); and when
!> and how it reaches the disk (below, run_file). `/time` and `/step` are the dimension scales of
!> the per-point and per-step datasets.
module run_output
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use hdf5_files, only: check_run_file, file_template
  use crash_safe_file, only: safe_file, spare_addition
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry
  use run_config, only: run_configuration
  use run_outcome, only: run_summary, failure_io
  use resume_records, only: resume_record, write_resume_attributes
  use stepper, only: time_stepper, step_report, step_diagnostic, solver_report
  use failures, only: failure_type, fail, code_io => failure_io, failure_mismatch
  use number_text, only: integer_text
  implicit none (type, external)
  private
  public :: run_file, extra_attribute, spare_addition

  !> A root attribute a caller adds to the file (an ensemble case names its study and case): a
  !> text if `text` is allocated, else the integer `number`.
  type :: extra_attribute
    character(len=32) :: name = ''
    character(len=:), allocatable :: text
    integer :: number = 0
  end type extra_attribute

  !> Rows held in memory between writes, at most. Each write copies a dataset's columns of them
  !> to a temporary on the stack (-fstack-arrays; faster per case file than a heap copy or a
  !> strided HDF5 selection, measured): keep it well below the 8 MiB default stack (48 MiB
  !> overflowed it).
  integer, parameter :: buffer_bytes = 4*1024*1024
  integer, parameter :: point_rows = 1, step_rows = 2      !! the file's two tables

  !> A run's file (src/io/crash_safe_file) and its two tables of rows, points and steps. It is
  !> built in memory and reaches the disk when the run ends or after a second (or a full buffer),
  !> whichever comes first; from then on, buffered rows are appended in a window at least every
  !> second. `path` always names a closed, readable file whose points and steps agree in length
  !> (step_rows says how many step rows, steps_completed how many steps they stand for). With
  !> every = N, a point row is kept every N steps (and the last), and a step row stands for the
  !> steps since the previous point row.
  type :: run_file
    type(safe_file) :: store
    logical :: enabled = .false.        !! .false.: nothing is recorded (an index-only study)
    integer :: every = 1                !! steps per row (&output every)
    logical :: by_interval = .false.    !! rows at output times instead (&output interval)
    logical :: thermal = .true.         !! the model has temperatures and an entropy (the thermal datasets)
    !> the state is in rows (/state, /temperature, /scheme_temperature); .false. for a state split
    !> over ranks, which /snapshots holds instead (src/run/distributed_simulation)
    logical :: state_rows = .true.
    integer(int64) :: last_step = 0            !! the last step recorded
    integer(int64) :: newton_pending = 0       !! Newton iterations of the steps not yet in a row
    integer(int64) :: committed_steps = 0, committed_newton = 0   !! of the steps in rows (buffered or written)
    integer(int64) :: disk_steps = 0, disk_newton = 0             !! of the steps in rows on disk
    type(resume_record) :: resume        !! the state after the last completed row (note_resume_state)
    character(len=:), allocatable :: history   !! a continued run's history, written with every write
    !> a continued run's effective namelist, &integrator t_end and max_steps (those that applied),
    !> written with every write as its history is
    character(len=:), allocatable :: continued_namelist
    real(real64) :: continued_t_end = 0.0_real64
    integer :: continued_max_steps = 0
  contains
    procedure :: create
    procedure :: record_solver
    procedure :: record_point
    procedure :: record_step
    procedure :: write_due
    procedure :: write_rows
    procedure :: finish
    procedure :: note_resume_state
    procedure :: note_snapshot_point
    procedure :: continue_file
    procedure :: kept_words
  end type run_file

  ! Made in memory (src/run/run_output_layout), noted for continuing (src/run/run_output_resume),
  ! and the outcome's attributes (src/run/run_output_attributes).
  interface
    !> Prepares the run file for `path` in memory with its attributes and the datasets' layout:
    !> the schema's, then one per step for each of the integrator's own diagnostics (attribute
    !> source = integrator). `petsc_options` are the options in force (the database's text).
    !> Nothing is written to `path` yet. With `template` (a study rank's, kept from case to case),
    !> the root attributes start from those of the first file made with it, and only those that
    !> differ are written (src/io/hdf5_files, file_template). A failure if HDF5 failed.
    module subroutine create(self, path, config, entry, model, constraints, diagnostics, extras, petsc_options, failure, template, &
                      state_rows)
      class(run_file), intent(inout) :: self
      character(len=*), intent(in) :: path
      type(run_configuration), intent(in), target :: config
      type(integrator_entry), intent(in) :: entry
      class(generic_model), intent(in) :: model
      type(constraint_slot), intent(in) :: constraints(:)
      type(step_diagnostic), intent(in) :: diagnostics(:)
      type(extra_attribute), intent(in) :: extras(:)
      character(len=*), intent(in) :: petsc_options
      type(failure_type), intent(out) :: failure
      type(file_template), intent(inout), target, optional :: template
      logical, intent(in), optional :: state_rows    !! .false.: no state in rows (run_file's state_rows)
    end subroutine create

    !> Notes the state after step n when record_point has just completed a row with it (call it after
    !> every step, and after the initial point, with the summary updated): every later write of the
    !> file stores it, as the state its rows end at.
    module subroutine note_resume_state(self, n, time, outputs_passed, energy_0, jz_0, boundary_heat, summary, x, x_previous, &
                                 integrator)
      class(run_file), intent(inout) :: self
      class(time_stepper), intent(in) :: integrator
      integer(int64), intent(in) :: n
      real(real64), intent(in) :: time, energy_0, jz_0, boundary_heat, x(:), x_previous(:)
      integer, intent(in) :: outputs_passed
      type(run_summary), intent(in) :: summary
    end subroutine note_resume_state

    !> Notes the point after step n of a run whose state is not in rows (a state split over ranks,
    !> whose snapshot of that step the file's next write adds: src/run/distributed_simulation), as
    !> note_resume_state does, with no state of its own (resume_x is not written) and the loop's
    !> `running_sums` as the integrator's state.
    module subroutine note_snapshot_point(self, n, time, energy_0, summary, running_sums)
      class(run_file), intent(inout) :: self
      integer(int64), intent(in) :: n
      real(real64), intent(in) :: time, energy_0, running_sums(:)
      type(run_summary), intent(in) :: summary
    end subroutine note_snapshot_point

    !> Goes on with the file that record came from, now at this file's path (a copy of it), with the
    !> input `config`: the file made by `create` in memory is dropped, and the next write appends the
    !> rows after record's to the file's, and stores config's effective namelist, t_end and max_steps
    !> (which alone may differ from the file's: docs/faults.md, Continuing a run). A failure: the
    !> OS's words or HDF5's.
    module subroutine continue_file(self, record, config, failure)
      class(run_file), intent(inout) :: self
      type(resume_record), intent(in) :: record
      type(run_configuration), intent(in), target :: config
      type(failure_type), intent(out) :: failure
    end subroutine continue_file

    ! A continued run's history and the input it was continued with: its effective namelist and the
    ! attributes t_end and max_steps, the only fields that may differ from the file's.
    module subroutine continued_attributes(self, failure)
      type(run_file), intent(inout) :: self
      type(failure_type), intent(out) :: failure
    end subroutine continued_attributes

    ! The root attributes of the run's outcome: steps_completed counts the steps the file's rows
    ! stand for, step_rows the step rows, newton_iterations_total the Newton iterations of those
    ! steps; `final` adds end_time. numbers_only: the texts (status, failure_kind) are as the file
    ! holds them, and numbers are written in place.
    module subroutine summary_attributes(self, status, summary, failure, numbers_only, final)
      type(run_file), intent(inout) :: self
      character(len=*), intent(in) :: status
      type(run_summary), intent(in) :: summary
      type(failure_type), intent(out) :: failure
      logical, intent(in), optional :: numbers_only, final
    end subroutine summary_attributes
  end interface

contains

  !> The solver the integrator used (after its `start`): each setting as a root attribute
  !> solver_<name> (numbers with solver_<name>_units), and the legend of /converged_reason.
  subroutine record_solver(self, report, failure)
    class(run_file), intent(inout) :: self
    type(solver_report), intent(in) :: report
    type(failure_type), intent(out) :: failure
    integer :: k
    if (.not. self%enabled) return
    do k = 1, size(report%settings)
      associate (item => report%settings(k))
        if (allocated(item%text)) then
          call self%store%file%set_text('solver_'//trim(item%name), item%text, failure)
        else if (item%integer_valued) then
          call self%store%file%set_integer('solver_'//trim(item%name), nint(item%value), failure, &
                                           units=trim(item%units))
        else
          call self%store%file%set_real('solver_'//trim(item%name), item%value, failure, units=trim(item%units))
        end if
      end associate
      if (failure%failed()) return
    end do
    call self%store%tables(step_rows)%set_flags('converged_reason', report%reason_codes, report%reason_names)
  end subroutine record_solver

  !> Records the point after step n (or the initial point) for every per-point dataset, in the
  !> schema's order. The rows of steps not yet in the file are completed every `every` steps, or
  !> with &output interval when `row_due` (the initial point at once).
  subroutine record_point(self, time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals, row_due)
    class(run_file), intent(inout) :: self
    real(real64), intent(in) :: time, z(:), theta(:), energy, entropy, lyapunov, momentum(:), heat, residuals(:)
    logical, intent(in) :: row_due
    real(real64) :: row(5 + size(z) + size(theta) + size(momentum) + size(residuals))
    integer :: filled
    logical :: due

    if (.not. self%enabled) return
    filled = 0
    call put(row, filled, [time])
    call put(row, filled, z)
    call put(row, filled, theta)
    if (self%thermal) then
      call put(row, filled, [energy, entropy, lyapunov, momentum, heat])
    else
      call put(row, filled, [energy, momentum, heat])
    end if
    call put(row, filled, residuals)
    call self%store%tables(point_rows)%accumulate(row(:filled))
    if (self%by_interval) then
      due = row_due
    else
      due = self%store%tables(step_rows)%pending_count >= self%every
    end if
    if (self%store%tables(step_rows)%pending_count == 0 .or. due) call commit_rows(self)
  end subroutine record_point

  !> Records step n, ending at `time`, for every per-step dataset, in the schema's order, then the
  !> integrator's diagnostics: `step_seconds` its wall-clock time, `entropy_increment` S_n - S_(n-1) and
  !> `lyapunov_increment` V_n - V_(n-1). Call it before the step's record_point.
  subroutine record_step(self, n, time, report, multipliers, step_seconds, entropy_increment, lyapunov_increment, &
                         balances, has_balance, resolved)
    class(run_file), intent(inout) :: self
    integer(int64), intent(in) :: n
    real(real64), intent(in) :: time      !! the step's end time
    type(step_report), intent(in) :: report
    real(real64), intent(in) :: multipliers(:), step_seconds, entropy_increment, lyapunov_increment
    real(real64), intent(in) :: balances(:)   !! the balance figures (step_balances' order)
    logical, intent(in) :: has_balance(:)     !! which of them the model has (the dataset's columns)
    logical, intent(in) :: resolved           !! solved again with the default solver settings

    if (.not. self%enabled) return
    block
      real(real64) :: row(self%store%tables(step_rows)%row_width)    ! the schema's datasets, then the diagnostics
      integer :: filled, k

      filled = 0
      call put(row, filled, [real(n, real64), time, real(report%newton_iterations, real64)])
      if (self%state_rows) call put(row, filled, report%scheme_temperature)
      call put(row, filled, [real(report%strategy, real64), real(report%solves, real64), real(report%rejected, real64), &
                             report%residual_norm, real(report%converged_reason, real64), step_seconds])
      if (self%thermal) call put(row, filled, [entropy_increment, lyapunov_increment])
      do k = 1, size(balances)
        if (.not. has_balance(k)) cycle
        filled = filled + 1
        row(filled) = balances(k)
      end do
      filled = filled + 1
      row(filled) = merge(1.0_real64, 0.0_real64, resolved)
      call put(row, filled, multipliers)
      if (allocated(report%diagnostics)) call put(row, filled, report%diagnostics)
      call self%store%tables(step_rows)%accumulate(row(:filled))
    end block
    self%last_step = n
    self%newton_pending = self%newton_pending + report%newton_iterations
  end subroutine record_step

  ! values into row after its first `filled` entries (a row is built on the stack: the step loop
  ! allocates nothing).
  pure subroutine put(row, filled, values)
    real(real64), intent(inout) :: row(:)
    integer, intent(inout) :: filled
    real(real64), intent(in) :: values(:)

    row(filled + 1:filled + size(values)) = values
    filled = filled + size(values)
  end subroutine put

  ! Completes the pending point row and the step row of the steps since the last one.
  subroutine commit_rows(self)
    type(run_file), intent(inout) :: self

    call self%store%tables(point_rows)%commit()
    if (self%store%tables(step_rows)%pending_count == 0) return
    call self%store%tables(step_rows)%commit()
    self%committed_steps = self%last_step
    self%committed_newton = self%committed_newton + self%newton_pending
    self%newton_pending = 0
  end subroutine commit_rows

  ! After both tables' buffers reached the file: the steps its rows stand for.
  subroutine rows_on_disk(self)
    type(run_file), intent(inout) :: self

    self%disk_steps = self%committed_steps
    self%disk_newton = self%committed_newton
  end subroutine rows_on_disk

  !> Whether buffered rows are due on disk: a second since the last write, or a full buffer.
  !> Call it after a whole step (its step row and end point) was recorded.
  logical function write_due(self)
    class(run_file), intent(in) :: self

    write_due = .false.
    if (self%enabled) write_due = self%store%write_due()
  end function write_due

  !> Writes the buffered rows and the run's attributes so far (`summary`, status 'incomplete:
  !> running'): the first time the whole file, later in a window that appends them; a window
  !> whose spare a reader holds open waits for a later step, until the buffer is full. A failure:
  !> the OS's words (nothing new reached the file; it holds what it held), or HDF5's.
  subroutine write_rows(self, summary, failure, addition)
    class(run_file), intent(inout) :: self
    type(run_summary), intent(in) :: summary
    type(failure_type), intent(out) :: failure
    class(spare_addition), intent(inout), optional :: addition   !! for a window's spare (crash_safe_file)
    if (.not. self%enabled) return
    call write_file(self, summary%status, summary, .false., failure, addition)
  end subroutine write_rows

  !> Writes what is buffered and the final attributes: status, failure_kind, steps_planned,
  !> steps_completed (the step rows in the file), the summary's figures and times. The file is
  !> then closed and synced (unless not durable) and checked: a file written whole from memory by
  !> its size on disk, one grown in windows by reading it back (every dataset's length against
  !> steps_completed, and the status). A failure: the OS's words (failure_io), HDF5's, or
  !> failure_mismatch (the disk does not hold what was written).
  !> If the rows cannot be written for want of space, the file keeps the rows of its last
  !> window, and its status says why if that much can still be written.
  subroutine finish(self, summary, failure, addition)
    class(run_file), intent(inout) :: self
    type(run_summary), intent(in) :: summary
    type(failure_type), intent(out) :: failure
    class(spare_addition), intent(inout), optional :: addition   !! for the last window's spare
    type(run_summary) :: stopped
    character(len=:), allocatable :: status_read
    integer :: steps_read
    type(failure_type) :: check, ignored
    logical :: whole
    if (.not. self%enabled) return
    if (self%store%tables(step_rows)%pending_count > 0) call commit_rows(self)
    whole = .not. self%store%on_disk
    ! An incomplete run may be continued: its datasets must be able to grow.
    self%store%extendible = summary%status /= 'complete'

    call write_file(self, summary%status, summary, .true., failure, addition)
    if (whole) return                   ! written whole from memory: store checked every byte
    if (failure%code == code_io) then
      ! No room for the rows: keep those of the last window, and say why in the status.
      stopped = summary
      stopped%failure_kind = failure_io
      call self%store%open_in_place(check)
      if (.not. check%failed()) call summary_attributes(self, 'incomplete: cannot write the output file: '// &
                                                        failure%message, stopped, check, final=.true.)
      call self%store%file%close(ignored)
      return
    end if
    if (failure%failed()) return
    call check_run_file(self%store%path, status_read, steps_read, check)
    if (check%failed() .or. status_read /= summary%status .or. steps_read /= self%disk_steps) &
      call fail(failure, failure_mismatch, 'the file did not read back as written', self%store%path)
  end subroutine finish

  !> What a failed write leaves, for its message: '; PART keeps the N steps written before', or
  !> '; nothing was kept' when no write reached the disk (the partial file is removed).
  function kept_words(self, part) result(words)
    class(run_file), intent(in) :: self
    character(len=*), intent(in) :: part
    character(len=:), allocatable :: words

    if (self%store%on_disk) then
      words = '; '//part//' keeps the '//integer_text(self%disk_steps)//' steps written before'
    else
      words = '; nothing was kept'
    end if
  end function kept_words

  ! One write of the file: the buffered rows, then the attributes of the outcome so far (all of
  ! them the first time and at the end, else the numbers, written in place). After a failed
  ! window the counts of the steps on disk are those the file still holds.
  subroutine write_file(self, status, summary, final, failure, addition)
    type(run_file), intent(inout) :: self
    character(len=*), intent(in) :: status
    type(run_summary), intent(in) :: summary
    logical, intent(in) :: final
    type(failure_type), intent(out) :: failure
    class(spare_addition), intent(inout), optional :: addition
    integer(int64) :: steps_before, newton_before
    logical :: whole, deferred

    steps_before = self%disk_steps
    newton_before = self%disk_newton
    whole = .not. self%store%on_disk
    call self%store%begin_rows(final, failure, defer=.not. (final .or. self%store%buffers_full()), deferred=deferred)
    if (deferred .and. .not. final) then    ! tried again 50 ms later
      return
    end if
    if (.not. failure%failed()) call rows_on_disk(self)
    ! A continued run (its history held) writes its status with every write: the file and its spare
    ! held the status of the run that stopped ('incomplete: the step budget is spent', ...).
    if (.not. failure%failed()) call summary_attributes(self, status, summary, failure, &
                                                        numbers_only=.not. (whole .or. final .or. &
                                                                            allocated(self%history)), final=final)
    if (.not. failure%failed() .and. self%resume%held) call write_resume_attributes(self%resume, self%store%file, failure, &
                                                                 with_units=whole .or. final)
    ! (at every write: the spare, one write behind, holds the old history until written again)
    if (.not. failure%failed() .and. allocated(self%history)) call continued_attributes(self, failure)
    call self%store%end_rows(failure, addition)
    if (failure%failed() .and. .not. whole) then       ! a failed window leaves the file as it was
      self%disk_steps = steps_before
      self%disk_newton = newton_before
    end if
  end subroutine write_file

end module run_output
