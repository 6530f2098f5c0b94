!> EME's and the midpoint rule's steps on a model split over ranks (src/model/distributed_model:
!> the spring chain's sparse path) with the dense path's semantics
!> (src/integrator/discrete_gradient_stepper; docs/integrators.md, Adaptive steps):
!>  - a fixed step of dt whose Newton fails (or meets a state outside the model's domain) is
!>    replaced by two steps of dt/2 of the same scheme, recursively, down to dt/2**6
!>    (-eme_max_halvings); each is a full step, and the step still lands on t + dt;
!>  - with &integrator tolerance each step is one accepted step of the size the PI controller
!>    (src/integrator/step_size_control) chooses: a trial step is rejected when Newton finds no
!>    root, when the field leaves the domain, or when the local error estimate
!>    (src/integrator/local_error_estimate, from the continuous field f at the step's ends and
!>    middle) exceeds tolerance h/(1 s); it is recomputed from the old state and never
!>    reported. The run lands on t_end exactly, and stops, with the dense path's words, after
!>    more than 60 rejections of one step or a trial step below 1e-12 max(1 s, t).
!> The estimate's norm is the dense path's weighted RMS norm over the whole state: each rank
!> sums its rows' squares, MPI_Allreduce adds them (a result independent of the rank count up to
!> the rounding of that sum). The wrapped system solves the steps and evaluates the field on its
!> rows (distributed_system's step, state_rows, set_state_rows, field_rows).
module distributed_step_control
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_IN_PLACE, MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_SUM, MPI_MAX
  use model_interface, only: generic_model
  use failures, only: failure_type, failure_none, fail, failure_mismatch
  use number_text, only: integer_text, scientific_text
  use solver_description, only: solver_report, add_setting, text_setting, number_setting, integer_setting
  use solver_options, only: step_solver_options, read_solver_options, read_step_control_options
  use distributed_model, only: distributed_system, distributed_settings, distributed_step, distributed_figures, &
                               distributed_part
  use step_size_control, only: step_controller
  use local_error_estimate, only: hermite_middle, hermite_defect, weighted_square_sum
  use discrete_gradient_stepper, only: step_solver, rejection_error, rejection_no_root, rejection_domain, &
                                       rejection_underflow, max_rejections_per_step, unit_time, rounding_level
  use stepper, only: step_diagnostic
  implicit none
  private
  public :: controlled_system, controlled_diagnostics

  !> SNES's converged reason for a residual evaluated outside the model's domain
  !> (SNES_DIVERGED_FUNCTION_DOMAIN, petscsnes.h): such a trial step is a domain rejection.
  integer, parameter :: snes_diverged_function_domain = -1

  !> A split system whose steps are halved where needed, or chosen by the controller.
  type, extends(distributed_system) :: controlled_system
    class(distributed_system), allocatable :: inner
    type(MPI_Comm) :: comm
    integer :: unknowns = 0                 !! the whole state's (the RMS norm's count)
    logical :: adaptive = .false.           !! &integrator tolerance given
    logical :: estimating = .false.         !! each step's estimate computed (adaptive, or -eme_error_estimate)
    integer :: max_halvings = 6             !! -eme_max_halvings
    real(real64) :: tolerance = 0.0_real64, error_scale = 1.0_real64, t_end = 0.0_real64
    real(real64) :: time = 0.0_real64       !! the time of the state held (adaptive steps)
    type(step_controller) :: controller
    !> the field at the state held, once computed (an accepted step's end is the next's start)
    logical :: field_held = .false.
    real(real64), allocatable :: field(:)
    !> the last fixed step's start and size (its rows; step_again_tightly solves it again)
    real(real64), allocatable :: step_start(:)
    real(real64) :: step_dt = 0.0_real64
  contains
    procedure :: start
    procedure :: step
    procedure :: step_again_tightly
    procedure :: figures
    procedure :: part
    procedure :: restore
    procedure :: finish
    procedure :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
  end type controlled_system

contains

  !> The per-step datasets of `system`'s steps: the dense path's (substeps; the estimate; the
  !> adaptive step's size and rejections) for a controlled system, none for another.
  function controlled_diagnostics(system) result(specs)
    class(distributed_system), intent(in) :: system
    type(step_diagnostic), allocatable :: specs(:)
    type(step_solver) :: dense

    allocate (specs(0))
    select type (system)
    class is (controlled_system)
      dense%estimating = system%estimating
      dense%adaptive = system%adaptive
      specs = dense%diagnostics()
    end select
  end function controlled_diagnostics

  !> Sets the wrapped system up (distributed_system's start) and the control: -eme_max_halvings,
  !> -eme_error_estimate and -eme_error_scale as on the dense path, the controller from dt.
  subroutine start(self, settings, model, z0, comm, failure)
    class(controlled_system), intent(inout), target :: self
    type(distributed_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    type(step_solver_options) :: options

    call read_solver_options(options, failure)
    if (failure%failed()) return
    self%max_halvings = options%max_halvings
    call read_step_control_options(self%estimating, self%error_scale, failure)
    if (failure%failed()) return
    self%adaptive = settings%tolerance_given
    self%estimating = self%estimating .or. self%adaptive
    self%tolerance = settings%tolerance
    self%t_end = settings%t_end
    self%time = 0.0_real64
    self%unknowns = size(z0)
    self%comm%MPI_VAL = comm
    self%field_held = .false.
    ! The estimate is O(h**3); per unit step, O(h**2) (discrete_gradient_stepper's start).
    call self%controller%restart(settings%dt, 2.0_real64)
    call self%inner%start(settings, model, z0, comm, failure)
  end subroutine start

  !> One step (module header): of dt, in halves where needed; with a tolerance, one accepted step
  !> of the controller's choosing toward t_end.
  subroutine step(self, dt, outcome, failure)
    class(controlled_system), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure

    if (self%adaptive) then
      call adaptive_step(self, outcome, failure)
    else
      call halved_step(self, dt, outcome, failure)
    end if
  end subroutine step

  !> The last fixed step solved again from its start, in halves where needed, with the wrapped
  !> system's linear solves tightened (distributed_system's tighten_linear_solves) for it alone:
  !> a step that broke a guaranteed balance (src/run/split_run_path). `again` is .false.
  !> (nothing done) with adaptive steps or where the wrapped system has no tighter settings.
  subroutine step_again_tightly(self, outcome, again, failure)
    class(controlled_system), intent(inout) :: self
    type(distributed_step), intent(out) :: outcome
    logical, intent(out) :: again
    type(failure_type), intent(out) :: failure
    type(failure_type) :: loosening
    logical :: loosened

    again = .false.
    if (self%adaptive .or. .not. allocated(self%step_start)) return
    call self%inner%tighten_linear_solves(.true., again, failure)
    if (failure%failed() .or. .not. again) return
    call self%inner%set_state_rows(self%step_start, self%step_start, failure)
    if (.not. failure%failed()) call halved_step(self, self%step_dt, outcome, failure)
    call self%inner%tighten_linear_solves(.false., loosened, loosening)
    if (.not. failure%failed() .and. loosening%failed()) failure = loosening
  end subroutine step_again_tightly

  ! The step of dt from the state held, in halves where Newton finds no root (step_or_halve); the
  ! figures then span the whole step. With -eme_error_estimate, the step's estimate.
  subroutine halved_step(self, dt, outcome, failure)
    type(controlled_system), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    real(real64), allocatable :: z_start(:), z_end(:), f_start(:), f_end(:)
    real(real64) :: estimate_norm
    integer :: substeps, stat

    call self%inner%state_rows(z_start, failure)
    if (failure%failed()) return
    self%step_start = z_start
    self%step_dt = dt
    substeps = 0
    outcome%solves = 0
    outcome%failure = ''
    call step_or_halve(self, dt, 0, substeps, outcome, failure)
    if (failure%failed()) return
    outcome%halvings = max(0, substeps - 1)
    outcome%diagnostics = [real(max(substeps, 1), real64)]
    if (.not. outcome%converged) then
      ! Halves taken before a failing one are undone: the state is the step's start again.
      if (substeps > 0) call self%inner%set_state_rows(z_start, z_start, failure)
      return
    end if
    outcome%failure = ''
    if (substeps > 1 .or. self%estimating) call self%inner%state_rows(z_end, failure)
    if (.not. failure%failed() .and. substeps > 1) call self%inner%set_state_rows(z_end, z_start, failure)
    self%field_held = .false.
    if (failure%failed() .or. .not. self%estimating) return
    allocate (f_start(size(z_start)), f_end(size(z_start)))
    estimate_norm = ieee_value(1.0_real64, ieee_quiet_nan)
    call field_of(self, z_start, f_start, stat, failure)
    if (.not. failure%failed() .and. stat == failure_none) &
      call estimate_norm_of(self, z_start, f_start, z_end, dt, estimate_norm, f_end, stat, failure)
    outcome%diagnostics = [outcome%diagnostics, estimate_norm]
  end subroutine halved_step

  ! The step of h, or, if Newton finds no root, its two halves (each in halves where needed),
  ! `depth` halvings having made h; substeps counts the steps taken. The wrapped system keeps its
  ! state where a solve fails.
  recursive subroutine step_or_halve(self, h, depth, substeps, outcome, failure)
    type(controlled_system), intent(inout) :: self
    real(real64), intent(in) :: h
    integer, intent(in) :: depth
    integer, intent(inout) :: substeps
    type(distributed_step), intent(inout) :: outcome
    type(failure_type), intent(out) :: failure
    type(distributed_step) :: solve

    call self%inner%step(h, solve, failure)
    if (failure%failed()) return
    call add_solve(outcome, solve)
    if (solve%converged) then
      substeps = substeps + 1
      outcome%converged = .true.
      return
    end if
    outcome%converged = .false.
    if (depth == self%max_halvings) then
      outcome%failure = no_root_text(solve)
      if (depth > 0) outcome%failure = outcome%failure//' (also in steps of dt/'//integer_text(2**depth)//')'
      return
    end if
    call step_or_halve(self, 0.5_real64*h, depth + 1, substeps, outcome, failure)
    if (failure%failed() .or. .not. outcome%converged) return
    call step_or_halve(self, 0.5_real64*h, depth + 1, substeps, outcome, failure)
  end subroutine step_or_halve

  ! One accepted step from the state held at self%time, of the size the controller proposes
  ! (discrete_gradient_control's adaptive_step, over the ranks' rows): trial steps from the old
  ! state, each rejected when it has no root, leaves the domain or misses the tolerance.
  subroutine adaptive_step(self, outcome, failure)
    type(controlled_system), intent(inout) :: self
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    type(distributed_step) :: solve
    real(real64), allocatable :: z_old(:), z_new(:), f_new(:)
    real(real64) :: h, h_unshortened, err, estimate_norm
    integer :: attempt, stat, rejected(3)
    logical :: landing
    character(len=:), allocatable :: reason

    rejected = 0
    h = 0.0_real64
    estimate_norm = ieee_value(1.0_real64, ieee_quiet_nan)
    reason = ''
    outcome%solves = 0
    outcome%converged = .false.
    call self%inner%state_rows(z_old, failure)
    if (failure%failed()) return
    if (.not. self%field_held) then
      if (allocated(self%field)) deallocate (self%field)
      allocate (self%field(size(z_old)))
      call field_of(self, z_old, self%field, stat, failure)
      if (failure%failed()) return
      if (stat /= failure_none) then
        reason = 'the continuous vector field is undefined at the step''s start (the state left the model''s domain)'
        call finish_outcome()
        return
      end if
      self%field_held = .true.
    end if
    allocate (f_new(size(z_old)))
    do attempt = 1, max_rejections_per_step + 1
      call self%controller%trial_step(self%time, min(self%t_end, self%stop_time), h, landing)
      if (h < rejection_underflow*max(1.0_real64, abs(self%time))) then
        reason = 'step-size underflow: the trial step fell below '//scientific_text(h)//' s (last rejection: '// &
                 reason//')'
        exit
      else if (attempt > max_rejections_per_step) then
        reason = 'more than '//integer_text(max_rejections_per_step)//' trial steps rejected (last: '//reason//')'
        exit
      end if
      call self%inner%step(h, solve, failure)
      if (failure%failed()) return
      call add_solve(outcome, solve)
      if (.not. solve%converged) then
        if (solve%reason == snes_diverged_function_domain) then
          rejected(rejection_domain) = rejected(rejection_domain) + 1
        else
          rejected(rejection_no_root) = rejected(rejection_no_root) + 1
        end if
        reason = no_root_text(solve)
        call self%controller%reject_failure(h)
        cycle
      end if
      call self%inner%state_rows(z_new, failure)
      if (.not. failure%failed()) call estimate_norm_of(self, z_old, self%field, z_new, h, estimate_norm, f_new, stat, &
                                                        failure)
      if (failure%failed()) return
      if (stat /= failure_none) then
        rejected(rejection_domain) = rejected(rejection_domain) + 1
        reason = 'the continuous vector field is undefined at the step''s end or middle'
        call self%controller%reject_failure(h)
        call self%inner%set_state_rows(z_old, z_old, failure)
        if (failure%failed()) return
        cycle
      end if
      ! Error per unit step, or at the estimate's rounding level (discrete_gradient_control).
      err = estimate_norm/(self%tolerance*h/unit_time + rounding_level)
      if (err > 1.0_real64) then
        rejected(rejection_error) = rejected(rejection_error) + 1
        reason = 'the error estimate per second '//scientific_text(err*self%tolerance)//' exceeded the tolerance'
        call self%controller%reject_error(h, err)
        call self%inner%set_state_rows(z_old, z_old, failure)
        if (failure%failed()) return
        cycle
      end if
      h_unshortened = self%controller%h
      call self%controller%accept(h, err)
      ! A step shortened to land on t_end (or an output time) does not shrink the next one.
      if (landing) self%controller%h = max(self%controller%h, h_unshortened)
      outcome%converged = .true.
      reason = ''
      self%field = f_new
      self%time = self%time + h
      if (landing) self%time = min(self%t_end, self%stop_time)
      exit
    end do
    call finish_outcome()

  contains

    ! The step's time and datasets (discrete_gradient_stepper's diagnostics: substeps, estimate,
    ! step size, rejections by reason); a failed step's end is where its last trial would have been.
    subroutine finish_outcome()
      outcome%chose_time = .true.
      outcome%rejected_steps = sum(rejected)
      outcome%failure = reason
      outcome%diagnostics = [1.0_real64, estimate_norm, h, real(sum(rejected), real64), real(rejected, real64)]
      if (outcome%converged) then
        outcome%time = self%time
      else
        outcome%time = self%time + h
        outcome%diagnostics(2:3) = ieee_value(1.0_real64, ieee_quiet_nan)
      end if
    end subroutine finish_outcome
  end subroutine adaptive_step

  ! A solve's counts added to the step's; its reason and residual become the step's last.
  pure subroutine add_solve(outcome, solve)
    type(distributed_step), intent(inout) :: outcome
    type(distributed_step), intent(in) :: solve

    outcome%iterations = outcome%iterations + solve%iterations
    outcome%solves = outcome%solves + solve%solves
    outcome%reason = solve%reason
    outcome%residual_norm = solve%residual_norm
  end subroutine add_solve

  ! Why a solve found no root, in the split path's words.
  pure function no_root_text(solve) result(text)
    type(distributed_step), intent(in) :: solve
    character(len=:), allocatable :: text

    if (allocated(solve%failure)) then
      if (len(solve%failure) > 0) then
        text = solve%failure
        return
      end if
    end if
    text = 'no root: Newton did not converge (SNES reason '//integer_text(solve%reason)//', |R| = '// &
           scientific_text(solve%residual_norm, 3)//')'
  end function no_root_text

  ! The continuous field's rows at the state of rows z; stat the worst rank's domain code.
  subroutine field_of(self, z, f, stat, failure)
    type(controlled_system), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    type(failure_type), intent(out) :: failure

    call self%inner%field_rows(z, f, stat, failure)
    call MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, self%comm)
  end subroutine field_of

  ! The weighted RMS norm (times -eme_error_scale) of the local error estimate of the step of h
  ! from the rows z_old (field f_old) to z_new, over the whole state (the ranks' sums added), and
  ! the field f_new at z_new; stat /= failure_none where the field is undefined.
  subroutine estimate_norm_of(self, z_old, f_old, z_new, h, norm, f_new, stat, failure)
    type(controlled_system), intent(inout) :: self
    real(real64), intent(in) :: z_old(:), f_old(:), z_new(:), h
    real(real64), intent(out) :: norm, f_new(:)
    integer, intent(out) :: stat
    type(failure_type), intent(out) :: failure
    real(real64) :: f_middle(size(z_old)), total

    norm = ieee_value(1.0_real64, ieee_quiet_nan)
    call field_of(self, z_new, f_new, stat, failure)
    if (failure%failed() .or. stat /= failure_none) return
    call field_of(self, hermite_middle(z_old, f_old, z_new, f_new, h), f_middle, stat, failure)
    if (failure%failed() .or. stat /= failure_none) return
    total = weighted_square_sum(hermite_defect(z_old, f_old, z_new, f_new, f_middle, h), z_old, z_new)
    call MPI_Allreduce(MPI_IN_PLACE, total, 1, MPI_DOUBLE_PRECISION, MPI_SUM, self%comm)
    norm = self%error_scale*sqrt(total/self%unknowns)
  end subroutine estimate_norm_of

  !> The wrapped system's figures (distributed_system).
  subroutine figures(self, values, failure)
    class(controlled_system), intent(inout) :: self
    type(distributed_figures), intent(out) :: values
    type(failure_type), intent(out) :: failure

    call self%inner%figures(values, failure)
  end subroutine figures

  !> The wrapped system's part of the state (distributed_system).
  subroutine part(self, state, failure)
    class(controlled_system), intent(inout) :: self
    type(distributed_part), intent(out) :: state
    type(failure_type), intent(out) :: failure

    call self%inner%part(state, failure)
  end subroutine part

  !> A continued run's state into the wrapped system (distributed_system).
  subroutine restore(self, state, failure)
    class(controlled_system), intent(inout) :: self
    type(distributed_part), intent(in) :: state
    type(failure_type), intent(out) :: failure

    self%field_held = .false.
    call self%inner%restore(state, failure)
  end subroutine restore

  !> Frees the wrapped system (distributed_system).
  subroutine finish(self, failure)
    class(controlled_system), intent(inout) :: self
    type(failure_type), intent(inout) :: failure

    call self%inner%finish(failure)
  end subroutine finish

  !> The wrapped system's solver, with the halving depth and the step-size control, as the
  !> dense path records them (distributed_system).
  function describe_solver(self) result(report)
    class(controlled_system), intent(in) :: self
    type(solver_report) :: report

    report = self%inner%describe_solver()
    call add_setting(report, integer_setting('eme_max_halvings', self%max_halvings))
    call add_setting(report, text_setting('step_control', merge('PI controller on the local error estimate  ', &
                                                                'fixed steps (halved where no root is found)', &
                                                                self%adaptive)))
    if (self%estimating) call add_setting(report, number_setting('eme_error_scale', self%error_scale))
  end function describe_solver

  !> The controller's state after the last accepted step, as the dense path keeps it for a
  !> continued run: its next trial step, err_old and whether err_old is an accepted step's.
  subroutine resume_state(self, values)
    class(controlled_system), intent(in) :: self
    real(real64), allocatable, intent(out) :: values(:)

    if (.not. self%adaptive) then
      allocate (values(0))
      return
    end if
    values = [self%controller%h, self%controller%err_old, merge(1.0_real64, 0.0_real64, self%controller%has_history)]
  end subroutine resume_state

  !> Takes back what resume_state gave, at `time` (a continued run's), bit for bit.
  subroutine restore_state(self, time, values, failure)
    class(controlled_system), intent(inout) :: self
    real(real64), intent(in) :: time, values(:)
    type(failure_type), intent(out) :: failure
    real(real64), allocatable :: expected(:)

    call self%resume_state(expected)
    if (size(values) /= size(expected)) then
      call fail(failure, failure_mismatch, 'the stored step control ('//integer_text(size(values))//' values) does '// &
                'not fit this run''s ('//integer_text(size(expected))//')', 'controlled_system%restore_state')
      return
    end if
    self%time = time
    if (.not. self%adaptive) return
    self%controller%h = values(1)
    self%controller%err_old = values(2)
    self%controller%has_history = nint(values(3)) == 1
    self%controller%rejected = .false.
  end subroutine restore_state

end module distributed_step_control
