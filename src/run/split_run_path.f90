!> The split path through the one time loop (src/run/time_loop): a model's system spread over the
!> ranks of an MPI communicator (src/model/distributed_model), every rank running the loop in step.
!> The ranks agree on stopping (a reduction of their stop flags), every step is checked from the
!> ranks' summed figures, rank 0 records the rows of scalars, and the snapshots of the state go
!> to the file in windows that all ranks write (src/run/snapshot_windows). What the loop's steps
!> share is the path's components; src/run/distributed_simulation sets them up and closes the run.
module split_run_path
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_Bcast, MPI_IN_PLACE, MPI_INTEGER, MPI_MAX
  use model_interface, only: generic_model
  use distributed_model, only: distributed_system, distributed_step, distributed_figures
  use stepper, only: step_report
  use run_output, only: run_file
  use run_paths, only: run_path, step_taken
  use run_outcome, only: failure_none, failure_domain, failure_library, failure_balance
  use step_balances, only: balance_count, balanced_state, balance_figures
  use step_check, only: broken_balance, balance_text
  use run_signals, only: interrupting_signal
  use run_file_steps, only: name_finished_file, guard_output_lock
  use time_loop_steps, only: step_budget_spent, stop_before_step, step_status, fail_write, accumulate_step, &
                             lower_min_temperature, note_balance_figures, next_output_stop, pass_output_times
  use split_run_setup, only: report_step, balanced_state_of
  use snapshot_windows, only: held_snapshot, snapshot_window
  use filesystem, only: output_lock
  use number_text, only: integer_text, scientific_text
  use rank_agreement, only: agree
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: split_path

  !> The resume record's first four values (resume_integrator), before the integrator's own:
  !> reserved, zeros (files before 2026-11-30 held running sums of the energy's and the conserved
  !> momenta's changes there, which a continuation now ignores).
  real(real64), parameter :: reserved_record(4) = 0.0_real64

  !> The split run's path: its system, the rank's part of the output, and what the loop keeps.
  type, extends(run_path) :: split_path
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    type(output_lock), pointer :: lock => null()   !! rank 0's lock of the output, if it has one
    type(MPI_Comm) :: communicator
    integer :: rank = 0
    type(run_file) :: output                       !! rank 0's
    type(snapshot_window) :: window
    type(distributed_step) :: outcome              !! the last step's
    type(distributed_figures) :: figures_0, values !! the figures of the initial state and of the last
    type(balanced_state) :: balance_old, balance_new
    type(step_report) :: report                    !! the last step's row (rank 0)
    character(len=:), allocatable :: part          !! the output file's name while it is written
    real(real64) :: figures(balance_count) = 0.0_real64   !! the step's balance figures
    real(real64) :: dv = 0.0_real64                !! the step's change of V = E - theta_r S
    real(real64) :: step_seconds = 0.0_real64
    integer(int64) :: state_step = 0      !! the step whose end the system's state is
    integer(int64) :: snapshot_step = 0   !! the step of the last snapshot held
    real(real64) :: state_time = 0.0_real64   !! the time of the system's state (the end of step state_step)
    !> the integrator's state after the last accepted step (a continued run's, at its snapshot)
    real(real64), allocatable :: control_state(:)
    integer :: every = 0                  !! &output snapshot_every
    integer :: outputs_passed = 0         !! output times (&output interval) reached so far
    logical :: row_due = .false.          !! the step reached the next output time
    logical :: resolved = .false.         !! the last step was solved again (step_stands)
    logical :: checked(balance_count) = .false., has_balance(balance_count) = .false.
    logical :: writing = .false.          !! the run writes its file (from the first write on)
    logical :: lock_lost = .false.        !! rank 0's lock of the output (guard_output_lock)
  contains
    procedure :: agree_to_stop
    procedure :: take_step
    procedure :: step_stands
    procedure :: accept_step
    procedure :: record_row
    procedure :: output_held
    procedure :: observe
    procedure :: record_point
    procedure :: hold_snapshot
    procedure :: write_window
  end type split_path

contains

  !> Every rank stops at the same step: a signal to any, the budget, a lost lock on rank 0 (after
  !> which the file is written once more only if rank 0 took the lock again).
  logical function agree_to_stop(self) result(stop)
    class(split_path), intent(inout) :: self
    integer :: stop_flags(4)
    logical :: may_write

    stop_flags = [interrupting_signal(), merge(1, 0, step_budget_spent(self%n, self%config%integrator%max_steps)), 0, 0]
    if (self%rank == 0 .and. associated(self%lock)) then
      call guard_output_lock(self%lock, self%config, self%part, self%n, self%summary, self%failure, self%lock_lost, &
                             may_write)
      stop_flags(3:4) = [merge(1, 0, self%lock_lost), merge(1, 0, .not. may_write)]
    end if
    call MPI_Allreduce(MPI_IN_PLACE, stop_flags, 4, MPI_INTEGER, MPI_MAX, self%communicator)
    if (stop_flags(3) /= 0) self%writing = self%writing .and. stop_flags(4) == 0
    stop = stop_before_step(stop_flags(1), stop_flags(2) /= 0, self%n, self%time, self%t_end, self%summary)
    if (.not. stop) stop = stop_flags(3) /= 0
  end function agree_to_stop

  !> The system's step; with &output interval a chosen step lands on the next output time when it
  !> reaches it (one within rounding of t_end is t_end), as on the dense path.
  subroutine take_step(self, taken)
    class(split_path), intent(inout) :: self
    type(step_taken), intent(out) :: taken
    type(failure_type) :: step_failure
    integer(int64) :: step_start, step_end

    if (self%config%output_interval > 0.0_real64) &
      self%system%stop_time = next_output_stop(self%outputs_passed, self%config%output_interval, self%t_end)
    call system_clock(step_start)
    call self%system%step(self%dt, self%outcome, step_failure)
    call system_clock(step_end)
    self%step_seconds = real(step_end - step_start, real64)/real(self%timer%rate, real64)
    taken%library_failed = step_failure%failed()
    if (taken%library_failed) then
      taken%library_text = step_failure%message
      return
    end if
    taken%chose_time = self%outcome%chose_time
    taken%reached = self%outcome%time
    taken%accepted = self%outcome%converged
    if (taken%accepted) return
    if (.not. allocated(self%outcome%failure)) self%outcome%failure = ''
    if (len(self%outcome%failure) == 0) self%outcome%failure = 'no root: Newton did not converge (SNES reason '// &
      integer_text(self%outcome%reason)//', |R| = '//scientific_text(self%outcome%residual_norm, 3)//')'
    taken%reason = self%outcome%failure
  end subroutine take_step

  !> The step's balance figures, from the summed differences of its parts (over its halves, if
  !> halved: their rounding bounds add up). A step that breaks a guaranteed balance is solved
  !> again with tighter linear solves where the system has them (a chain's fixed steps on several
  !> ranks: distributed_system's step_again_tightly; then `resolved`), as the dense path
  !> solves it again with its default settings; one that still breaks it ends the run, as does a
  !> state whose figures cannot be taken (failure_domain).
  logical function step_stands(self) result(goes_on)
    class(split_path), intent(inout) :: self
    type(failure_type) :: step_failure
    type(distributed_step) :: again_outcome
    integer :: broken
    logical :: again

    goes_on = .false.
    self%resolved = .false.
    self%state_step = self%n
    self%state_time = self%time
    if (.not. figures_taken(self)) return
    call self%observe(self%values)
    broken = measured_break(self)
    if (broken /= 0 .and. .not. self%outcome%chose_time) then
      call self%system%step_again_tightly(again_outcome, again, step_failure)
      if (step_failure%failed()) then
        call self%fail(failure_library, step_failure%message)
        return
      end if
      if (again .and. again_outcome%converged) then
        again_outcome%iterations = again_outcome%iterations + self%outcome%iterations
        self%outcome = again_outcome
        self%resolved = .true.
        self%summary%resolved_steps = self%summary%resolved_steps + 1
        if (.not. figures_taken(self)) return
        self%balance_new = balanced_state_of(self%values)
        broken = measured_break(self)
      end if
    end if
    if (broken == 0) then
      call note_balance_figures(self%summary, self%has_balance, self%figures)
    else
      self%summary%status = step_status(self%n, self%time, balance_text(broken, self%figures))
      self%summary%failure_kind = failure_balance
    end if
    goes_on = self%summary%failure_kind == failure_none
  end function step_stands

  ! The figures of the state and the step (into self%values); a state whose figures cannot be
  ! taken ends the run (failure_domain).
  logical function figures_taken(self) result(taken)
    class(split_path), intent(inout) :: self
    type(failure_type) :: step_failure

    call self%system%figures(self%values, step_failure)
    taken = .not. step_failure%failed()
    if (taken) return
    self%summary%status = step_status(self%n, self%time, step_failure%message)
    self%summary%failure_kind = failure_domain
  end function figures_taken

  ! The step's balance figures (into self%figures) and the first guaranteed balance they break.
  integer function measured_break(self) result(broken)
    class(split_path), intent(inout) :: self

    self%figures = balance_figures(self%has_balance, self%balance_old, self%balance_new, 0.0_real64, &
                                   self%config%theta_r, [self%values%delta_energy, self%values%delta_entropy], &
                                   self%values%delta_conserved)
    broken = broken_balance(self%figures, self%checked, self%outcome%halvings + 1)
  end function measured_break

  !> The integrator's state and the running sums after the step; the summary counts it.
  subroutine accept_step(self)
    class(split_path), intent(inout) :: self

    integer :: count

    call self%system%resume_state(self%control_state)
    self%dv = self%values%delta_energy - self%config%theta_r*self%values%delta_entropy
    ! The drifts as the file's rows give them (|E_n - E_0|/|E_0|, J_n - J_0 along the conserved
    ! axes), which a study's restart recomputes from them to trust a finished file.
    count = self%values%conserved_count
    call accumulate_step(self%summary, self%n, self%outcome%iterations, self%outcome%halvings, &
                         self%outcome%rejected_steps, &
                         abs(self%values%energy - self%figures_0%energy)/abs(self%figures_0%energy), &
                         self%values%delta_entropy, self%dv, &
                         abs(self%values%conserved(1:count) - self%figures_0%conserved(1:count)))
    if (self%model%temperature_count() > 0) call lower_min_temperature(self%summary, [self%values%min_temperature])
  end subroutine accept_step

  !> The step's row and point of scalars (rank 0).
  subroutine record_row(self)
    class(split_path), intent(inout) :: self

    call pass_output_times(self%time, self%config%output_interval, self%outputs_passed, self%row_due)
    if (self%rank /= 0) return
    call report_step(self%outcome, self%values, self%report)
    call self%output%record_step(self%n, self%time, self%report, [real(real64) ::], self%step_seconds, &
                                 self%values%delta_entropy, self%dv, self%figures, self%has_balance, self%resolved)
    call self%record_point(self%time, self%row_due)
  end subroutine record_row

  !> A snapshot held at the last step, at an output time, or every snapshot_every-th step, and the
  !> window written when one is due (a failed write ends the run on every rank).
  logical function output_held(self) result(goes_on)
    class(split_path), intent(inout) :: self

    if (self%finished .or. self%row_due) then
      call self%hold_snapshot()
    else if (self%every > 0) then
      if (mod(self%n, int(self%every, int64)) == 0) call self%hold_snapshot()
    end if
    call self%write_window(.false.)
    goes_on = .not. self%failure%failed()
  end function output_held

  !> The balances' state of the figures `values` (into balance_new; balance_old takes the last).
  subroutine observe(self, values)
    class(split_path), intent(inout) :: self
    type(distributed_figures), intent(in) :: values

    self%balance_old = self%balance_new
    self%balance_new = balanced_state_of(values)
  end subroutine observe

  !> One point row (rank 0): the state's scalars, from `values`; the model's momenta are J's last
  !> momentum_count() components (J in 3D, J_z in 2D, none in 1D). The rows follow &output every
  !> (of accepted steps when the integrator chooses them), or the output times (`row_due`).
  subroutine record_point(self, time, row_due)
    class(split_path), intent(inout) :: self
    real(real64), intent(in) :: time
    logical, intent(in) :: row_due

    call self%output%record_point(time, [real(real64) ::], [real(real64) ::], self%values%energy, &
                                  self%values%entropy, self%values%energy - self%config%theta_r*self%values%entropy, &
                                  self%values%angular_momentum(4 - self%model%momentum_count():), 0.0_real64, &
                                  [real(real64) ::], row_due)
  end subroutine record_point

  !> The rank's part of the state (the end of step state_step, at self%time), held for the next
  !> window, which also stores the resume record that stands at it (rank 0: its row is recorded).
  subroutine hold_snapshot(self)
    class(split_path), intent(inout) :: self
    type(held_snapshot) :: snapshot
    type(failure_type) :: reading

    if (.not. self%writing) return          ! no file (keep_file = .false.)
    snapshot%time = self%time
    self%snapshot_step = self%state_step
    call self%system%part(snapshot%state, reading)
    if (reading%failed()) then
      call self%fail(failure_library, 'cannot read the state for a snapshot: '//reading%message)
      return
    end if
    call self%window%hold(snapshot)
    if (self%rank == 0) call self%output%note_snapshot_point(self%state_step, self%time, self%figures_0%energy, &
                                                             self%summary, [reserved_record, self%control_state])
  end subroutine hold_snapshot

  !> A write of the file when one is due (rank 0's clock, or a rank's full snapshot buffer), or
  !> the last one (`final`): rank 0 writes the rows and attributes, and every rank joins its
  !> window to add the snapshots (snapshot_window).
  subroutine write_window(self, final)
    class(split_path), intent(inout) :: self
    logical, intent(in) :: final
    type(failure_type) :: io_failure
    integer :: flags(2), outcome_code

    flags = 0
    if (self%rank == 0 .and. .not. final) flags(1) = merge(1, 0, self%output%write_due())
    flags(2) = merge(1, 0, self%window%full())
    if (.not. final) then
      call MPI_Allreduce(MPI_IN_PLACE, flags, 2, MPI_INTEGER, MPI_MAX, self%communicator)
      if (all(flags == 0)) return
    end if
    self%window%added = .false.
    if (self%rank == 0) then
      call self%timer%note_times(self%summary, .not. final)
      if (final) then
        call self%output%finish(self%summary, io_failure, self%window)
      else
        call self%output%write_rows(self%summary, io_failure, self%window)
      end if
      ! A window that did not reach its addition (deferred, or failed before) releases the others.
      if (.not. self%window%added) then
        outcome_code = 0
        call MPI_Bcast(outcome_code, 1, MPI_INTEGER, 0, self%communicator)
      end if
    else
      call self%window%join()
    end if
    outcome_code = merge(1, 0, self%window%added .and. .not. io_failure%failed())
    call MPI_Bcast(outcome_code, 1, MPI_INTEGER, 0, self%communicator)
    if (outcome_code == 1) call self%window%written()
    if (self%rank == 0 .and. io_failure%failed()) then
      call fail_write(self%failure, self%summary, self%part, self%config%input_file, io_failure%message, &
                      self%output%kept_words(self%part))
    end if
    call agree(self%failure, self%summary, self%communicator, self%config%input_file)
    ! The last write reached the file (a run stopped by a failure too, marked incomplete): it
    ! takes the output's name, as on the dense path.
    if (final .and. self%rank == 0 .and. .not. io_failure%failed()) &
      call name_finished_file(self%config, self%part, self%output%store%durable, self%summary, self%failure)
  end subroutine write_window

end module split_run_path
