!> Where a continued run starts (docs/faults.md, Continuing a run): the resume record, the state
!> of a run after its last completed row with the loop's counts and figures, which every write of
!> the run file stores as root attributes (src/run/run_output) and a continuation reads back
!> (src/run/run_continuation).
module resume_records
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use hdf5_files, only: hdf5_file
  use run_outcome, only: run_summary, failure_io, failure_interrupted, failure_step_budget
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: resume_record, read_resume_record, write_resume_attributes

  !> The state of a run after its last completed row (docs/faults.md, Continuing a run): what the
  !> time loop needs to go on from there as if it had not stopped. Stored with every write of the
  !> file as the root attributes resume_numbers (the scalars below, in order), resume_x and
  !> resume_x_previous.
  type :: resume_record
    logical :: held = .false.
    !> the run stopped early in a way that continuing can remedy: a signal, a kill (status
    !> 'incomplete: running'), the step budget, a failed write; not a complete run, nor a step
    !> that could not be solved
    logical :: stopped_early = .false.
    integer(int64) :: step = 0                   !! steps taken
    real(real64) :: time = 0.0_real64            !! the time reached
    integer :: outputs_passed = 0                !! output times (&output interval) reached
    !> jz_0: the first conserved momentum component's initial value (the time loop takes them all
    !> from the initial state, which the same input builds again)
    real(real64) :: energy_0 = 0.0_real64, jz_0 = 0.0_real64, boundary_heat = 0.0_real64
    integer(int64) :: point_rows = 0, step_rows = 0   !! the rows of the two tables up to that step
    type(run_summary) :: summary                 !! its counts and figures (not its texts or times)
    real(real64), allocatable :: x(:)            !! the unknowns: state and multipliers
    real(real64), allocatable :: x_previous(:)   !! those of the step before (the predictor's base)
    real(real64), allocatable :: integrator_state(:)   !! the integrator's own (time_stepper's resume_state)
    character(len=:), allocatable :: history     !! the file's CF history, which a continuation extends
  contains
    procedure :: keep_summary
    procedure :: restore_summary
  end type resume_record

contains

  !> Keeps the summary's counts and figures (restore_summary gives them back).
  subroutine keep_summary(self, summary)
    class(resume_record), intent(inout) :: self
    type(run_summary), intent(in) :: summary

    self%summary%newton_iterations = summary%newton_iterations
    self%summary%energy_drift = summary%energy_drift
    self%summary%min_entropy_increment = summary%min_entropy_increment
    self%summary%max_lyapunov_increment = summary%max_lyapunov_increment
    self%summary%angular_momentum_drift = summary%angular_momentum_drift
    self%summary%min_temperature = summary%min_temperature
    self%summary%halved_steps = summary%halved_steps
    self%summary%rejected_steps = summary%rejected_steps
    self%summary%resolved_steps = summary%resolved_steps
    self%summary%max_balance = summary%max_balance
  end subroutine keep_summary

  !> The summary's counts and figures as the record holds them (the steps completed are its step).
  subroutine restore_summary(self, summary)
    class(resume_record), intent(in) :: self
    type(run_summary), intent(inout) :: summary

    summary%newton_iterations = self%summary%newton_iterations
    summary%energy_drift = self%summary%energy_drift
    summary%min_entropy_increment = self%summary%min_entropy_increment
    summary%max_lyapunov_increment = self%summary%max_lyapunov_increment
    summary%angular_momentum_drift = self%summary%angular_momentum_drift
    summary%min_temperature = self%summary%min_temperature
    summary%halved_steps = self%summary%halved_steps
    summary%rejected_steps = self%summary%rejected_steps
    summary%resolved_steps = self%summary%resolved_steps
    summary%max_balance = self%summary%max_balance
    summary%steps_completed = self%step
  end subroutine restore_summary

  !> Reads the resume record of the run file `path` with its status and the effective namelist it
  !> was run with; record%held is .false. if it has none. failure%failed() if the file cannot be read.
  subroutine read_resume_record(path, record, status, namelist_text, failure)
    character(len=*), intent(in) :: path
    type(resume_record), intent(out) :: record
    character(len=:), allocatable, intent(out) :: status, namelist_text
    type(failure_type), intent(out) :: failure
    type(hdf5_file) :: file
    real(real64), allocatable :: numbers(:)
    character(len=:), allocatable :: kind
    type(failure_type) :: ignored, reading

    status = ''
    namelist_text = ''
    call file%open_existing(path, .false., failure)
    if (failure%failed()) return
    call file%get_text('status', status, failure)
    if (.not. failure%failed()) call file%get_text('namelist', namelist_text, failure)
    if (failure%failed()) then
      call file%close(ignored)
      return
    end if
    call file%get_text('failure_kind', kind, reading)
    if (reading%failed()) kind = ''
    record%stopped_early = status == 'incomplete: running' .or. kind == failure_interrupted .or. &
                           kind == failure_step_budget .or. kind == failure_io
    call file%get_text('history', record%history, reading)
    if (reading%failed()) record%history = ''
    call file%get_reals('resume_numbers', numbers, reading)
    if (.not. reading%failed() .and. size(numbers) == 16) then
      ! A record without resume_x stands at the file's last snapshot (a state split over ranks).
      call file%get_reals('resume_x', record%x, reading)
      if (reading%failed()) then
        record%x = [real(real64) ::]
        record%x_previous = [real(real64) ::]
      else
        call file%get_reals('resume_x_previous', record%x_previous, failure)
      end if
      call file%get_reals('resume_integrator', record%integrator_state, reading)
      if (reading%failed()) record%integrator_state = [real(real64) ::]
      record%held = .not. failure%failed()
      record%step = nint(numbers(1), int64)
      record%time = numbers(2)
      record%outputs_passed = nint(numbers(3))
      record%energy_0 = numbers(4)
      record%jz_0 = numbers(5)
      record%boundary_heat = numbers(6)
      record%point_rows = nint(numbers(7), int64)
      record%step_rows = nint(numbers(8), int64)
      record%summary%newton_iterations = nint(numbers(9), int64)
      record%summary%energy_drift = numbers(10)
      record%summary%min_entropy_increment = numbers(11)
      record%summary%max_lyapunov_increment = numbers(12)
      record%summary%angular_momentum_drift = numbers(13)
      record%summary%min_temperature = numbers(14)
      record%summary%halved_steps = nint(numbers(15), int64)
      record%summary%rejected_steps = nint(numbers(16), int64)
      call file%get_reals('resume_balances', numbers, reading)
      if (.not. reading%failed() .and. size(numbers) == 1 + size(record%summary%max_balance)) then
        record%summary%resolved_steps = nint(numbers(1), int64)
        record%summary%max_balance = numbers(2:)
      end if
    end if
    call file%close(ignored)
  end subroutine read_resume_record

  !> The resume record as root attributes of `file` (read_resume_record reads them).
  subroutine write_resume_attributes(record, file, failure, with_units)
    type(resume_record), intent(in) :: record
    type(hdf5_file), intent(inout) :: file
    type(failure_type), intent(out) :: failure
    logical, intent(in) :: with_units     !! the texts too (the first and the last write)

    call file%set_reals('resume_numbers', [real(record%step, real64), record%time, real(record%outputs_passed, real64), &
                        record%energy_0, record%jz_0, record%boundary_heat, real(record%point_rows, real64), &
                        real(record%step_rows, real64), real(record%summary%newton_iterations, real64), &
                        record%summary%energy_drift, record%summary%min_entropy_increment, &
                        record%summary%max_lyapunov_increment, record%summary%angular_momentum_drift, &
                        record%summary%min_temperature, real(record%summary%halved_steps, real64), &
                        real(record%summary%rejected_steps, real64)], failure)
    if (.not. failure%failed()) call file%set_reals('resume_balances', [real(record%summary%resolved_steps, real64), &
                                                                        record%summary%max_balance], failure)
    if (.not. failure%failed() .and. size(record%x) > 0) call file%set_reals('resume_x', record%x, failure)
    if (.not. failure%failed() .and. size(record%x) > 0) &
      call file%set_reals('resume_x_previous', record%x_previous, failure)
    if (.not. failure%failed() .and. size(record%integrator_state) > 0) &
      call file%set_reals('resume_integrator', record%integrator_state, failure)
    if (failure%failed() .or. .not. with_units) return
    ! The units, entry by entry for resume_numbers; the vectors carry the units of their entries.
    call file%set_texts('resume_numbers_units', [character(len=3) :: '1', 's', '1', 'J', 'J s', 'J', '1', '1', '1', &
                                                 '1', 'J/K', 'J', 'J s', 'K', '1', '1'], failure)
    if (.not. failure%failed()) call file%set_text('resume_balances_units', '1', failure)
    if (.not. failure%failed() .and. size(record%x) > 0) &
      call file%set_text('resume_x_units', 'the units of /state''s columns, then the multipliers''', failure)
    if (.not. failure%failed() .and. size(record%x) > 0) &
      call file%set_text('resume_x_previous_units', 'as resume_x', failure)
    if (.not. failure%failed() .and. size(record%integrator_state) > 0) &
      call file%set_text('resume_integrator_units', 'mixed: the integrator''s own state (docs/faults.md)', failure)
  end subroutine write_resume_attributes

end module resume_records
