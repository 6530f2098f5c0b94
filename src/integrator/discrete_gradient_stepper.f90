!> The one-step schemes of the paper, each step one nonlinear system solved by Newton's method in
!> PETSc SNES (src/solver/snes_solver) under the retry strategies (src/solver/retry_strategies):
!> EME, whose partials are discrete gradients, and the implicit midpoint rule, whose partials are
!> the exact ones at the midpoint. A model that offers a fused step (src/scheme/condensed_step,
!> registered in src/model/model_registry; the double pendulum's, with or without its
!> constraints) has its steps solved on its condensed unknowns; any other model or constraint by
!> the generic residual (src/scheme/step_residual), which -eme_fused_kernel false also selects.
!> A step of dt whose root no strategy finds is replaced by two steps of dt/2 of the same scheme,
!> recursively, down to dt/2**6 (-eme_max_halvings changes the depth): each is a full step, so the
!> structure holds on every substep and so over the output step. The output stays on the user's
!> grid; the per-step dataset `substeps` records how many steps made each output step, and the
!> multipliers recorded are their time averages, so that dt times the recorded heat supply is the
!> heat the substeps supplied. A step that fails even in halves ends the run.
!>
!> With &integrator tolerance the schemes choose their steps instead (docs/integrators.md, Adaptive
!> steps): each step's local error is estimated from the continuous field
!> (src/integrator/local_error_estimate), a PI controller (src/integrator/step_size_control) accepts
!> the step if the estimate's weighted norm is at most tolerance * h / (1 s) (error per unit step:
!> the global error then grows like the tolerance per simulated second, tolerance-proportional)
!> and proposes the next, and a step without a physical root is a rejection like any other (no
!> halving). A rejected step is recomputed from the old state and never reported; the
!> run lands on t_end exactly, dt being the first trial step. Every accepted step is a full step of
!> the scheme, so the structure holds on each.
module discrete_gradient_stepper
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint
  use condensed_step, only: condensed_step_problem
  use model_registry, only: fused_step_of
  use snes_solver, only: newton_solver
  use solver_options, only: step_solver_options, read_solver_options, read_step_control_options
  use retry_strategies, only: root_search, find_root
  use failures, only: failure_none, failure_type, fail, failure_mismatch
  use constrained_flow, only: constrained_field
  use local_error_estimate, only: hermite_defect_estimate, weighted_rms_norm
  use step_size_control, only: step_controller
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report, step_diagnostic, solver_report
  use solver_description, only: add_setting, text_setting, number_setting, integer_setting
  use number_text, only: integer_text, scientific_text
  implicit none (type, external)
  private
  public :: step_solver, new_eme, new_midpoint
  public :: rejection_error, rejection_no_root, rejection_domain, rejection_underflow
  ! Shared with the split path's step control (src/integrator/distributed_step_control), which
  ! takes the same steps over a distributed state.
  public :: max_rejections_per_step, unit_time, rounding_level
  ! For the submodule discrete_gradient_control only: gfortran gives a module's private procedures
  ! internal linkage, which submodules, compiled apart, cannot reach.
  public :: solve_step

  !> Why an adaptive step was rejected (the counts of each step's rejections by reason, in this
  !> order, are its datasets rejected_error, rejected_no_root and rejected_domain).
  integer, parameter :: rejection_error = 1, rejection_no_root = 2, rejection_domain = 3
  !> The smallest trial step, relative to max(1 s, t): below it the run stops ('step-size underflow').
  real(real64), parameter :: rejection_underflow = 1.0e-12_real64
  integer, parameter :: max_rejections_per_step = 60
  !> The tolerance bounds the local error per this much simulated time (error per unit step).
  real(real64), parameter :: unit_time = 1.0_real64
  !> The weighted norm of an estimate that is all rounding: the Newton root is exact to its
  !> rounding, about eps |z| (docs/integrators.md), and the estimate's difference quotient takes it over.
  real(real64), parameter :: rounding_level = 64*epsilon(1.0_real64)

  !> What the substeps of one output step add up to.
  type :: substep_tally
    integer :: substeps = 0
    integer :: strategy = 0             !! the largest retry strategy a substep needed
    integer :: newton_iterations = 0
    integer :: solves = 0
    integer :: rejected = 0
    character(len=:), allocatable :: reason, last_rejection
  end type substep_tally

  !> The step's system and the solver that keeps its PETSc objects from run to run.
  type, extends(time_stepper) :: step_solver
    integer :: partials_rule = partials_discrete_gradient
    type(step_problem) :: problem          !! the generic step (kept up to date also when fused)
    class(condensed_step_problem), allocatable :: kernel   !! the model's fused step, if it offers one
    logical :: fused = .false.             !! the kernel solves the steps
    integer :: max_halvings = 6            !! a step is solved in halves down to dt/2**max_halvings
    type(newton_solver) :: solver
    !> The step check's re-solve (src/run/step_check): a solver with the defaults alone, made on
    !> the first step that needs it, and whether it solves the steps now.
    type(newton_solver) :: default_solver
    logical :: resolving = .false.
    integer :: max_iterations = 50         !! &integrator newton_max_iterations
    ! The local error estimate and the step-size control (module header).
    logical :: adaptive = .false.          !! &integrator tolerance given: the steps are chosen
    logical :: estimating = .false.        !! each step's estimate is computed (adaptive, or -eme_error_estimate)
    real(real64) :: tolerance = 0.0_real64
    real(real64) :: error_scale = 1.0_real64   !! -eme_error_scale
    real(real64) :: t_end = 0.0_real64
    type(step_controller) :: controller
    real(real64), allocatable :: z_field(:), field(:)   !! a state and the continuous field there
    real(real64), allocatable :: x_last(:), increment(:)  !! the last accepted state and step (predictor)
    !> The step's sum of h lambda over its substeps (start_tally zeroes it; kept from step to step
    !> so that no step allocates it).
    real(real64), allocatable :: multiplier_integral(:)
    real(real64) :: h_last = 0.0_real64
  contains
    procedure :: start
    procedure :: advance
    procedure :: release
    procedure :: diagnostics
    procedure :: describe_solver
    procedure :: resume_state
    procedure :: restore_state
    procedure :: resolve
  end type step_solver

  interface
    !> One accepted step of the size the controller chooses (src/integrator/discrete_gradient_control.F90).
    module subroutine adaptive_step(self, x_old, t_old, x_new, tally, report, failure)
      class(step_solver), intent(inout), target :: self
      real(real64), intent(in) :: x_old(:), t_old
      real(real64), intent(out) :: x_new(:)
      type(substep_tally), intent(inout) :: tally
      type(step_report), intent(inout) :: report
      type(failure_type), intent(out) :: failure
    end subroutine adaptive_step
    !> The weighted norm of the local error estimate of the step of h from z_old to z_new (NaN
    !> where the field is undefined) (src/integrator/discrete_gradient_control.F90).
    module subroutine estimate_step(self, z_old, z_new, h, norm)
      class(step_solver), intent(inout) :: self
      real(real64), intent(in) :: z_old(:), z_new(:), h
      real(real64), intent(out) :: norm
    end subroutine estimate_step
  end interface

contains

  !> EME (eq. (15)): discrete gradients of the subsystems' potentials.
  subroutine new_eme(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=step_solver(partials_rule=partials_discrete_gradient))
  end subroutine new_eme

  !> The implicit midpoint rule (docs/formulation.md section 6).
  subroutine new_midpoint(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=step_solver(partials_rule=partials_midpoint))
  end subroutine new_midpoint

  !> The step problem of the run; the SNES objects are reused when the size is the same.
  subroutine start(self, choice, model, constraints, z0, failure)
    class(step_solver), intent(inout), target :: self
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    type(failure_type), intent(out) :: failure
    type(step_solver_options) :: options

    if (allocated(self%problem%model)) deallocate (self%problem%model)
    allocate (self%problem%model, source=model)
    self%problem%constraints = constraints
    self%problem%partials_rule = self%partials_rule
    self%problem%gradient = choice%discrete_gradient
    self%problem%metric = choice%metric
    self%problem%dt = choice%dt
    self%problem%z_old = z0
    call read_solver_options(options, failure)
    if (failure%failed()) return
    self%max_halvings = options%max_halvings
    call read_step_control_options(self%estimating, self%error_scale, failure)
    if (failure%failed()) return
    self%adaptive = choice%tolerance_given
    self%estimating = self%estimating .or. self%adaptive
    self%tolerance = choice%tolerance
    self%t_end = choice%t_end
    ! The estimate is O(h**3); per unit step, O(h**2).
    call self%controller%restart(choice%dt, 2.0_real64)
    if (allocated(self%z_field)) deallocate (self%z_field, self%field)
    if (allocated(self%x_last)) deallocate (self%x_last, self%increment)
    self%h_last = 0.0_real64
    self%fused = .false.
    self%resolving = .false.
    self%max_iterations = choice%newton_max_iterations
    if (allocated(self%kernel)) deallocate (self%kernel)
    if (options%fused_kernel) call fused_step_of(self%problem, self%kernel, self%fused)
    if (self%fused) then
      call self%solver%prepare(self%kernel, choice%newton_tol, choice%newton_max_iterations, failure)
    else
      call self%solver%prepare(self%problem, choice%newton_tol, choice%newton_max_iterations, failure)
    end if
  end subroutine start

  !> The per-step datasets of these schemes: the substeps of each output step; with an estimate,
  !> its norm; with step-size control, the accepted step and the rejections by reason.
  function diagnostics(self) result(specs)
    class(step_solver), intent(in) :: self
    type(step_diagnostic), allocatable :: specs(:)

    specs = [step_diagnostic('substeps', '1', 'steps of the scheme in the output step: 1, or more where halves '// &
                             'replaced a step without a root (-eme_max_halvings deep); multipliers are then the '// &
                             'substeps'' time averages', 'sum')]
    if (self%estimating) specs = [specs, step_diagnostic('error_estimate', '1', 'the local error estimate''s '// &
                                  'weighted RMS norm (times -eme_error_scale); adaptive steps keep it <= tolerance h/(1 s)', &
                                  'max')]
    if (self%adaptive) specs = [specs, &
      step_diagnostic('step_size', 's', 'the accepted step (with &output every, the sum of the row''s steps)', 'sum'), &
      step_diagnostic('rejected_steps', '1', 'trial steps rejected before the accepted one, for any reason', 'sum'), &
      step_diagnostic('rejected_error', '1', 'trial steps rejected because the error estimate exceeded tolerance', &
                      'sum'), &
      step_diagnostic('rejected_no_root', '1', 'trial steps rejected because Newton found no root', 'sum'), &
      step_diagnostic('rejected_domain', '1', 'trial steps rejected because every root (or the field) left the '// &
                      'model''s domain', 'sum')]
  end function diagnostics

  !> The step's SNES as it was set up (command-line options applied), with the kernel it solves,
  !> the halving depth and the step-size control.
  function describe_solver(self) result(report)
    class(step_solver), intent(in) :: self
    type(solver_report) :: report
    type(failure_type) :: failure

    call self%solver%describe(report, failure)
    if (failure%failed()) call add_setting(report, text_setting('error', 'PETSc could not describe the SNES'))
    call add_setting(report, text_setting('eme_fused_kernel', merge('true ', 'false', self%fused)))
    call add_setting(report, integer_setting('eme_max_halvings', self%max_halvings))
    call add_setting(report, text_setting('step_control', merge('PI controller on the local error estimate  ', &
                                                                'fixed steps (halved where no root is found)', &
                                                                self%adaptive)))
    if (self%estimating) call add_setting(report, number_setting('eme_error_scale', self%error_scale))
  end function describe_solver

  !> One step of dt from x_old, in halves where needed (module header); on acceptance, the
  !> temperatures the (last sub)step's K0 used. With step-size control, one accepted step of the
  !> controller's choosing instead (adaptive_step).
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    type(failure_type), intent(out) :: failure
    type(substep_tally) :: tally
    real(real64) :: estimate_norm
    integer :: n

    n = self%problem%model%state_size
    call start_tally(self, tally, size(x_old) - n)
    if (self%adaptive) then
      call adaptive_step(self, x_old, t_old, x_new, tally, report, failure)
      call finish_report(self, tally, x_new, report, failure)
      return
    end if
    call halved_step(self, x_old, dt, guess, x_new, tally, report, failure)
    report%diagnostics = [real(tally%substeps, real64)]
    if (.not. self%estimating .or. failure%failed() .or. .not. report%accepted) return
    call estimate_step(self, x_old(1:n), x_new(1:n), dt, estimate_norm)
    report%diagnostics = [report%diagnostics, estimate_norm]
  end subroutine advance

  ! A tally of substeps with no substep yet, for a step with n_multipliers multipliers, and the
  ! solver's multiplier integral zeroed.
  subroutine start_tally(self, tally, n_multipliers)
    class(step_solver), intent(inout) :: self
    type(substep_tally), intent(out) :: tally
    integer, intent(in) :: n_multipliers

    if (allocated(self%multiplier_integral)) then
      if (size(self%multiplier_integral) /= n_multipliers) deallocate (self%multiplier_integral)
    end if
    if (.not. allocated(self%multiplier_integral)) allocate (self%multiplier_integral(n_multipliers))
    self%multiplier_integral = 0.0_real64
    tally%reason = ''
    tally%last_rejection = ''
  end subroutine start_tally

  ! The step of h from x_old in halves where needed (step_or_halve), its multipliers the
  ! substeps' time averages, and its report.
  subroutine halved_step(self, x_old, h, guess, x_new, tally, report, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(substep_tally), intent(inout) :: tally
    type(step_report), intent(inout) :: report
    type(failure_type), intent(out) :: failure
    integer :: n

    n = self%problem%model%state_size
    call step_or_halve(self, x_old, h, guess, x_new, 0, tally, report%accepted, failure)
    if (.not. failure%failed() .and. report%accepted .and. tally%substeps > 1) x_new(n + 1:) = self%multiplier_integral/h
    call finish_report(self, tally, x_new, report, failure)
  end subroutine halved_step

  ! The report of a step from what its (sub)steps did; on acceptance the temperatures the (last
  ! sub)step's K0 used. The tally's reason and last rejection move into the report.
  subroutine finish_report(self, tally, x_new, report, failure)
    class(step_solver), intent(inout) :: self
    type(substep_tally), intent(inout) :: tally
    real(real64), intent(in) :: x_new(:)
    type(step_report), intent(inout) :: report
    type(failure_type), intent(in) :: failure
    integer :: stat

    report%strategy = tally%strategy
    report%newton_iterations = tally%newton_iterations
    report%solves = tally%solves
    report%rejected = tally%rejected
    ! Moved, not copied: the tally's texts end here (a copy and a free fewer each, every step).
    call move_alloc(tally%reason, report%reason)
    call move_alloc(tally%last_rejection, report%last_rejection)
    report%halvings = max(0, tally%substeps - 1)     ! each halving adds one substep
    if (self%resolving) then
      report%residual_norm = self%default_solver%last_residual_norm
      report%converged_reason = self%default_solver%last_reason
    else
      report%residual_norm = self%solver%last_residual_norm
      report%converged_reason = self%solver%last_reason
    end if
    allocate (report%scheme_temperature(self%problem%model%temperature_count()))
    report%scheme_temperature = 0.0_real64
    if (failure%failed() .or. .not. report%accepted) return
    if (self%fused) then
      call self%kernel%scheme_temperatures(x_new(self%kernel%eliminated + 1:), report%scheme_temperature, stat)
    else
      call self%problem%scheme_temperatures(x_new, report%scheme_temperature, stat)
    end if
    if (stat /= 0) then    ! check_root has accepted the root, so this does not happen
      report%accepted = .false.
      report%reason = 'the scheme temperatures of the root are undefined'
    end if
  end subroutine finish_report

  ! The step of h from x_old, or, if no strategy finds its root, its two halves (each in halves
  ! where needed) from the predictors interpolated and extrapolated from `guess`; `depth` halvings
  ! made h. The last substep leaves its problem set up (scheme_temperatures).
  recursive subroutine step_or_halve(self, x_old, h, guess, x_new, depth, tally, accepted, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    integer, intent(in) :: depth
    type(substep_tally), intent(inout) :: tally
    logical, intent(out) :: accepted
    type(failure_type), intent(out) :: failure
    type(root_search) :: search
    real(real64) :: x_half(size(x_old))

    call solve_step(self, x_old, h, guess, x_new, depth == 0, search, failure)
    tally%newton_iterations = tally%newton_iterations + search%newton_iterations
    tally%solves = tally%solves + search%solves
    tally%rejected = tally%rejected + search%rejected_roots
    if (len(search%last_rejection) > 0) tally%last_rejection = search%last_rejection
    accepted = search%accepted .and. .not. failure%failed()
    if (accepted) then
      tally%substeps = tally%substeps + 1
      tally%strategy = max(tally%strategy, search%strategy)
      self%multiplier_integral = self%multiplier_integral + h*x_new(size(x_old) - size(self%multiplier_integral) + 1:)
      return
    end if
    if (failure%failed()) return
    if (depth == self%max_halvings) then
      tally%reason = search%reason
      if (depth > 0) tally%reason = search%reason//' (also in steps of dt/'//integer_text(2**depth)//')'
      return
    end if
    call step_or_halve(self, x_old, 0.5_real64*h, x_old + 0.5_real64*(guess - x_old), x_half, depth + 1, tally, &
                       accepted, failure)
    if (.not. accepted) return
    call step_or_halve(self, x_half, 0.5_real64*h, 2*x_half - x_old, x_new, depth + 1, tally, accepted, failure)
  end subroutine step_or_halve

  ! One search for the root of the step of h from x_old (no halving); with continuation in s if
  ! `continuing`.
  subroutine solve_step(self, x_old, h, guess, x_new, continuing, search, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    logical, intent(in) :: continuing
    type(root_search), intent(out) :: search
    type(failure_type), intent(out) :: failure
    real(real64) :: start(size(guess))

    associate (n => self%problem%model%state_size)
      self%problem%z_old = x_old(1:n)
      self%problem%dt = h
      ! The old state (with the guessed multipliers) is a root of the step of length 0.
      start = guess
      start(1:n) = x_old(1:n)
    end associate
    if (self%fused) then
      ! The same search on the condensed unknowns y = x(7:); q' follows from y.
      call self%kernel%set_old_state(x_old)
      self%kernel%dt = h
      block
        real(real64) :: y_new(size(guess) - self%kernel%eliminated)

        if (self%resolving) then
          call find_root(self%default_solver, self%kernel, start(self%kernel%eliminated + 1:), &
                         self%kernel%condense(guess), y_new, search, failure, continuing)
        else
          call find_root(self%solver, self%kernel, start(self%kernel%eliminated + 1:), self%kernel%condense(guess), &
                         y_new, search, failure, continuing)
        end if
        x_new = self%kernel%expand(y_new)
      end block
    else if (self%resolving) then
      call find_root(self%default_solver, self%problem, start, guess, x_new, search, failure, continuing)
    else
      call find_root(self%solver, self%problem, start, guess, x_new, search, failure, continuing)
    end if
  end subroutine solve_step

  !> The step of h from x_old solved again by a solver with the defaults alone (no command-line
  !> option), to its rounding floor (newton_tol 0: only the rounding and stagnation tests of
  !> retry_strategies accept), in halves where needed; for an adaptive run too, at the step it
  !> accepted (no estimate).
  subroutine resolve(self, x_old, t_old, h, guess, x_new, report, failure)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, h, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    type(failure_type), intent(out) :: failure
    type(substep_tally) :: tally
    real(real64) :: estimate_norm
    integer :: n

    if (self%fused) then
      call self%default_solver%prepare(self%kernel, 0.0_real64, max(self%max_iterations, 50), failure, &
                                       from_options=.false.)
    else
      call self%default_solver%prepare(self%problem, 0.0_real64, max(self%max_iterations, 50), failure, &
                                       from_options=.false.)
    end if
    if (failure%failed()) return
    n = self%problem%model%state_size
    call start_tally(self, tally, size(x_old) - n)
    self%resolving = .true.
    call halved_step(self, x_old, h, guess, x_new, tally, report, failure)
    self%resolving = .false.
    report%chose_time = self%adaptive
    report%time = t_old + h
    ! The datasets of diagnostics(): substeps, then the estimate, then the adaptive step's figures.
    report%diagnostics = [real(tally%substeps, real64)]
    if (.not. self%estimating) return
    estimate_norm = ieee_value(1.0_real64, ieee_quiet_nan)
    if (.not. failure%failed() .and. report%accepted) call estimate_step(self, x_old(1:n), x_new(1:n), h, estimate_norm)
    report%diagnostics = [report%diagnostics, estimate_norm]
    if (self%adaptive) report%diagnostics = [report%diagnostics, h, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64]
  end subroutine resolve

  !> Frees the SNES objects.
  subroutine release(self, failure)
    class(step_solver), intent(inout) :: self
    type(failure_type), intent(out) :: failure

    if (self%solver%created) call self%solver%destroy(failure)
    if (self%default_solver%created .and. .not. failure%failed()) call self%default_solver%destroy(failure)
  end subroutine release

  !> What a step leaves for the next (a continued run restores it, bit for bit): the step-size
  !> controller's next trial step and error history, the last step's length (the adaptive
  !> predictor's scale), and the LU factors of the last Newton iteration (the chord refinement of
  !> the next predictor). Layout: h, err_old, has_history, h_last, x_last given, then the
  !> factors as lu_factors' as_values.
  subroutine resume_state(self, values)
    class(step_solver), intent(in) :: self
    real(real64), allocatable, intent(inout) :: values(:)
    integer :: n

    ! Kept from call to call (a record is noted after every row): nothing is allocated per step.
    n = 5 + self%solver%context%lu%value_count()
    if (allocated(values)) then
      if (size(values) /= n) deallocate (values)
    end if
    if (.not. allocated(values)) allocate (values(n))
    values(1) = self%controller%h
    values(2) = self%controller%err_old
    values(3) = merge(1.0_real64, 0.0_real64, self%controller%has_history)
    values(4) = self%h_last
    values(5) = merge(1.0_real64, 0.0_real64, allocated(self%x_last))
    call self%solver%context%lu%put_values(values(6:))
  end subroutine resume_state

  !> Takes back what resume_state gave (after `start`); a failure (failure_mismatch) if `values`
  !> do not fit its layout.
  !> Factors of another system size (another -eme_fused_kernel) are not this solver's: the next
  !> predictor then goes without the chord refinement.
  subroutine restore_state(self, values, x, x_previous, failure)
    class(step_solver), intent(inout) :: self
    real(real64), intent(in) :: values(:), x(:), x_previous(:)
    type(failure_type), intent(out) :: failure
    logical :: ok

    call fail(failure, failure_mismatch, 'the stored integrator state does not fit the step solver''s layout', &
              'step_solver%restore_state')
    if (size(values) < 5) return
    call self%solver%context%lu%from_values(values(6:), self%solver%n, ok)
    if (.not. ok) return
    self%controller%h = values(1)
    self%controller%err_old = values(2)
    self%controller%has_history = nint(values(3)) == 1
    self%h_last = values(4)
    if (nint(values(5)) == 1) then
      self%x_last = x
      self%increment = x - x_previous
    end if
    failure = failure_type()
  end subroutine restore_state

end module discrete_gradient_stepper
