!> The dense path through the one time loop (src/run/time_loop): the whole state and the active
!> constraints' multipliers in one process, stepped by an integrator of the registry, every step
!> checked (src/run/step_check) and recorded with its state (src/run/run_output). What the loop's
!> steps share (the state before, after and at the step's end, the step's figures, the output)
!> are the path's components; src/run/simulation sets them up and closes the run.
module dense_run_path
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use stepper, only: time_stepper, step_report
  use run_output, only: run_file
  use run_paths, only: run_path, step_taken
  use time_loop_steps, only: step_budget_spent, stop_before_step, step_status, note_petsc_error, fail_write, &
                             accumulate_step, note_balance_figures, next_output_stop, pass_output_times
  use run_outcome, only: failure_none, failure_library, failure_balance
  use run_signals, only: interrupting_signal
  use run_file_steps, only: guard_output_lock
  use step_balances, only: balance_count
  use dense_observation, only: state_observation
  use step_check, only: broken_balance, balance_text
  use command_line, only: petsc_error_text
  use filesystem, only: output_lock
  use failures, only: failure_type, stat_none => failure_none
  implicit none (type, external)
  private
  public :: dense_path

  !> The dense run's path: its model, integrator, unknowns and output.
  type, extends(run_path) :: dense_path
    class(time_stepper), pointer :: integrator => null()
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    type(output_lock), pointer :: lock => null()   !! eme_run's lock of the output, if it has one
    type(run_file) :: output
    type(step_report) :: report                    !! the last step's
    !> how many figures of each step the integrator and the model add to the rows (set up once)
    integer :: integrator_figures = 0, model_figures = 0
    type(state_observation) :: seen                !! the step check's states before and after the step
    character(len=:), allocatable :: part          !! the output file's name while it is written
    !> the unknowns (the state, then the active constraints' multipliers) before the last step, at
    !> its start and at its end; the constraints' g at the last point
    real(real64), allocatable :: x_previous(:), x(:), x_new(:), residuals(:)
    real(real64), allocatable :: conserved_0(:)    !! the conserved momentum components at the initial state
    real(real64) :: energy_0 = 0.0_real64, entropy_old = 0.0_real64, lyapunov_old = 0.0_real64
    real(real64) :: boundary_heat = 0.0_real64, time_old = 0.0_real64, step_heat = 0.0_real64
    real(real64) :: figures(balance_count) = 0.0_real64   !! the step's balance figures
    logical :: checked(balance_count) = .false., has_balance(balance_count) = .false.
    logical :: resolved = .false.       !! the step was solved again with the default solver settings
    integer(int64) :: step_start = 0, step_end = 0   !! the monotonic clock around the step
    integer :: n_state = 0
    integer :: outputs_passed = 0       !! output times (&output interval) reached so far
    logical :: writing = .true.         !! the run writes its file
    logical :: chooses_time = .false.   !! the integrator chooses its steps' times
    logical :: lock_lost = .false.      !! the output's lock was removed or replaced (guard_lock)
  contains
    procedure :: agree_to_stop
    procedure :: take_step
    procedure :: step_stands
    procedure :: accept_step
    procedure :: record_row
    procedure :: output_held
    procedure :: observe
    procedure :: record_point
    procedure :: guard_lock
    procedure :: set_times
    procedure :: first_conserved_0
  end type dense_path

contains

  !> A signal or a spent step budget ends the run before the next step (this process alone decides).
  logical function agree_to_stop(self) result(stop)
    class(dense_path), intent(inout) :: self

    stop = stop_before_step(interrupting_signal(), step_budget_spent(self%n, self%config%integrator%max_steps), &
                            self%n, self%time, self%t_end, self%summary)
  end function agree_to_stop

  !> The step from x, with a predictor that extrapolates the last step linearly (the old state on
  !> the first step); with &output interval the step lands on the next output time when it reaches it.
  subroutine take_step(self, taken)
    class(dense_path), intent(inout) :: self
    type(step_taken), intent(out) :: taken
    type(failure_type) :: step_failure

    if (.not. self%chooses_time) self%time = (self%n - 1)*self%dt
    self%time_old = self%time
    if (self%config%output_interval > 0.0_real64) &
      self%integrator%stop_time = next_output_stop(self%outputs_passed, self%config%output_interval, self%t_end)
    call system_clock(self%step_start)
    call self%integrator%advance(self%x, self%time, self%dt, 2*self%x - self%x_previous, self%x_new, self%report, &
                                 step_failure)
    call system_clock(self%step_end)
    taken%library_failed = step_failure%failed()
    if (taken%library_failed) then
      taken%library_text = petsc_error_text()
      return
    end if
    taken%chose_time = self%report%chose_time
    taken%reached = self%report%time
    taken%accepted = self%report%accepted
    if (.not. taken%accepted) taken%reason = self%report%reason
  end subroutine take_step

  !> The check of the step the integrator just accepted, from x to x_new (src/run/step_check):
  !> its heat through the constraints (step_heat; a multiplier is the step's mean rate, lambda_2 a
  !> heat power, so the heat is rate times the step), its balance figures, and, where it breaks a
  !> guaranteed balance, the step solved again with the model's default solver settings (then
  !> `resolved`). A step that still breaks one ends the run (failure_balance), as does a re-solve
  !> without a root; a library failure ends it with `failure`.
  logical function step_stands(self) result(goes_on)
    class(dense_path), intent(inout) :: self
    integer :: broken, first_iterations
    type(failure_type) :: resolving

    self%resolved = .false.
    broken = measured_break(self)
    goes_on = broken == 0 .and. .not. self%failure%failed() .and. self%summary%failure_kind == failure_none
    if (broken == 0) return
    self%resolved = .true.
    self%summary%resolved_steps = self%summary%resolved_steps + 1
    first_iterations = self%report%newton_iterations
    call self%integrator%resolve(self%x, self%time_old, self%time - self%time_old, 2*self%x - self%x_previous, &
                                 self%x_new, self%report, resolving)
    self%report%newton_iterations = self%report%newton_iterations + first_iterations
    if (resolving%failed()) then
      call self%fail(failure_library, 'PETSc failed during the solve: '//petsc_error_text())
      call note_petsc_error(self%summary, self%n)
      return
    end if
    if (.not. self%report%accepted) then
      self%summary%status = step_status(self%n, self%time, balance_text(broken, self%figures)// &
                                        '; solved again with the default solver settings: '//self%report%reason)
      self%summary%failure_kind = failure_balance
      return
    end if
    broken = measured_break(self)
    goes_on = broken == 0 .and. .not. self%failure%failed() .and. self%summary%failure_kind == failure_none
    if (broken == 0) return
    self%summary%status = step_status(self%n, self%time, balance_text(broken, self%figures)// &
                                      ', also when solved again with the default solver settings')
    self%summary%failure_kind = failure_balance
  end function step_stands

  ! The balance the step from x to x_new breaks (step_check's number; 0: none), its figures noted
  ! in the summary when it breaks none.
  integer function measured_break(self) result(broken)
    class(dense_path), intent(inout) :: self

    call self%seen%measure(self%model, self%constraints, self%x_new, self%time - self%time_old, self%has_balance, &
                           self%config%theta_r, self%step_heat, self%figures)
    broken = broken_balance(self%figures, self%checked, self%report%halvings + 1)
    if (broken == 0) call note_balance_figures(self%summary, self%has_balance, self%figures)
  end function measured_break

  !> The step's end becomes the state (x_previous takes x, x takes x_new), its E, S and V the
  !> observed ones, and the summary counts it (Newton's iterations, the drifts from the check's values).
  subroutine accept_step(self)
    class(dense_path), intent(inout) :: self

    self%boundary_heat = self%boundary_heat + self%step_heat
    self%entropy_old = self%seen%entropy
    self%lyapunov_old = self%seen%lyapunov
    self%x_previous = self%x
    self%x = self%x_new
    call self%seen%take(self%summary, self%config%theta_r)
    call accumulate_step(self%summary, self%n, self%report%newton_iterations, self%report%halvings, &
                         self%report%rejected_steps, &
                         abs(self%seen%energy - self%energy_0 - self%boundary_heat)/abs(self%energy_0), &
                         self%seen%entropy - self%entropy_old, self%seen%lyapunov - self%lyapunov_old, &
                         abs(self%seen%new%conserved(1:size(self%conserved_0)) - self%conserved_0))
  end subroutine accept_step

  !> The step's row and its point (written if &output every or an output time asks), and the
  !> resume record that stands after it.
  subroutine record_row(self)
    class(dense_path), intent(inout) :: self
    logical :: row_due

    call add_model_figures(self)
    call self%output%record_step(self%n, self%time, self%report, self%x(self%n_state + 1:), &
                                 real(self%step_end - self%step_start, real64)/real(self%timer%rate, real64), &
                                 self%seen%entropy - self%entropy_old, self%seen%lyapunov - self%lyapunov_old, &
                                 self%figures, self%has_balance, self%resolved)
    call pass_output_times(self%time, self%config%output_interval, self%outputs_passed, row_due)
    call self%record_point(self%time, self%x(1:self%n_state), row_due)
    call self%output%note_resume_state(self%n, self%time, self%outputs_passed, self%energy_0, self%first_conserved_0(), &
                                       self%boundary_heat, self%summary, self%x, self%x_previous, self%integrator)
  end subroutine record_row

  ! The model's own figures of the step from x_previous to x (generic_model's step_figures; a
  ! chain's production minima) after the integrator's in the row; NaN where they cannot be taken.
  subroutine add_model_figures(self)
    class(dense_path), intent(inout) :: self
    real(real64), allocatable :: values(:)
    integer :: stat, k

    if (self%model_figures == 0) return
    call self%model%step_figures(self%config%integrator%scheme, self%config%integrator%discrete_gradient, &
                                 self%config%integrator%metric, self%x_previous(1:self%n_state), &
                                 self%x(1:self%n_state), values, stat)
    if (stat /= stat_none .or. size(values) /= self%model_figures) &
      values = [(ieee_value(1.0_real64, ieee_quiet_nan), k = 1, self%model_figures)]
    if (.not. allocated(self%report%diagnostics)) allocate (self%report%diagnostics(0))
    associate (own => min(self%integrator_figures, size(self%report%diagnostics)))   ! the integrator's come first
      self%report%diagnostics = [self%report%diagnostics(1:own), values]
    end associate
  end subroutine add_model_figures

  !> The rows held so far written when a write is due (a lost lock or a failed write ends the run).
  logical function output_held(self) result(goes_on)
    class(dense_path), intent(inout) :: self
    type(failure_type) :: io_failure

    goes_on = .true.
    if (.not. self%output%write_due()) return
    call self%guard_lock()
    goes_on = .not. self%lock_lost
    if (.not. goes_on) return
    call self%set_times(.true.)
    call self%output%write_rows(self%summary, io_failure)
    if (io_failure%failed()) then
      call fail_write(self%failure, self%summary, self%part, self%config%input_file, io_failure%message, &
                      self%output%kept_words(self%part))
      goes_on = .false.
    end if
  end function output_held

  !> Looks at the state z and takes it (its E, S, V into `seen`).
  subroutine observe(self, z)
    class(dense_path), intent(inout) :: self
    real(real64), intent(in) :: z(:)

    call self%seen%look(self%model, z)
    call self%seen%take(self%summary, self%config%theta_r)
  end subroutine observe

  !> One point: the state `observe` saw last, with what it is judged by (its temperatures, energy,
  !> entropy, V and momentum, kept by observe), and the active constraints' g.
  subroutine record_point(self, time, z, row_due)
    class(dense_path), intent(inout) :: self
    real(real64), intent(in) :: time, z(:)
    logical, intent(in) :: row_due     !! an output time (&output interval): the point is written
    integer :: k, domain

    do k = 1, size(self%constraints)
      call self%constraints(k)%item%value(self%model, z, self%residuals(k), domain)
    end do
    call self%output%record_point(time, z, self%seen%theta, self%seen%energy, self%seen%entropy, self%seen%lyapunov, &
                                  self%seen%momentum, self%boundary_heat, self%residuals, row_due)
  end subroutine record_point

  !> Before a write: whether the output's lock (eme_run's) is still this process's
  !> (run_file_steps' guard_output_lock: a lost one stops the run, which writes nothing more
  !> unless it took the lock again).
  subroutine guard_lock(self)
    class(dense_path), intent(inout) :: self
    logical :: may_write

    if (.not. associated(self%lock) .or. self%lock_lost) return
    call guard_output_lock(self%lock, self%config, self%part, self%n, self%summary, self%failure, self%lock_lost, &
                           may_write)
    self%writing = self%writing .and. may_write
  end subroutine guard_lock

  !> The whole run's seconds so far, and the time loop's while it runs (src/run/run_clock).
  subroutine set_times(self, in_loop)
    class(dense_path), intent(inout) :: self
    logical, intent(in) :: in_loop

    call self%timer%note_times(self%summary, in_loop)
  end subroutine set_times

  !> The first conserved component's initial value, which the resume record keeps (0 if none).
  real(real64) function first_conserved_0(self)
    class(dense_path), intent(in) :: self

    first_conserved_0 = 0.0_real64
    if (size(self%conserved_0) > 0) first_conserved_0 = self%conserved_0(1)
  end function first_conserved_0

end module dense_run_path
