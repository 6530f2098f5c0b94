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
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint
  use condensed_step, only: condensed_step_problem
  use model_registry, only: fused_step_of
  use snes_solver, only: newton_solver
  use solver_options, only: step_solver_options, read_solver_options, read_step_control_options
  use retry_strategies, only: root_search
  use failures, only: failure_type, fail, failure_mismatch
  use step_size_control, only: step_controller
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report, step_diagnostic, solver_report
  use solver_description, only: add_setting, text_setting, number_setting, integer_setting
  implicit none (type, external)
  private
  public :: step_solver, new_eme, new_midpoint
  public :: rejection_error, rejection_no_root, rejection_domain, rejection_underflow
  ! Shared with the split path's step control (src/integrator/distributed_step_control), which
  ! takes the same steps over a distributed state.
  public :: max_rejections_per_step, unit_time, rounding_level

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

  ! Implemented in discrete_gradient_step.
  interface
    !> One step of dt from x_old, in halves where needed (module header); on acceptance, the
    !> temperatures the (last sub)step's K0 used. With step-size control, one accepted step of the
    !> controller's choosing instead (adaptive_step).
    module subroutine advance(self, x_old, t_old, dt, guess, x_new, report, failure)
      class(step_solver), intent(inout), target :: self
      real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
      real(real64), intent(out) :: x_new(:)
      type(step_report), intent(out) :: report
      type(failure_type), intent(out) :: failure
    end subroutine advance

    !> The step of h from x_old solved again by a solver with the defaults alone (no command-line
    !> option), to its rounding floor (newton_tol 0: only the rounding and stagnation tests of
    !> retry_strategies accept), in halves where needed; for an adaptive run too, at the step it
    !> accepted (no estimate).
    module subroutine resolve(self, x_old, t_old, h, guess, x_new, report, failure)
      class(step_solver), intent(inout), target :: self
      real(real64), intent(in) :: x_old(:), t_old, h, guess(:)
      real(real64), intent(out) :: x_new(:)
      type(step_report), intent(out) :: report
      type(failure_type), intent(out) :: failure
    end subroutine resolve

    ! One search for the root of the step of h from x_old (no halving); with continuation in s if
    ! `continuing`.
    module subroutine solve_step(self, x_old, h, guess, x_new, continuing, search, failure)
      class(step_solver), intent(inout), target :: self
      real(real64), intent(in) :: x_old(:), h, guess(:)
      real(real64), intent(out) :: x_new(:)
      logical, intent(in) :: continuing
      type(root_search), intent(out) :: search
      type(failure_type), intent(out) :: failure
    end subroutine solve_step
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
