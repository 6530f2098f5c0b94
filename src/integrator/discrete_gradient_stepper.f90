!> The one-step schemes of the paper, each step one nonlinear system solved by Newton's method in
!> PETSc SNES (src/solver/snes_solver) under the retry strategies (src/solver/retry_strategies):
!> EME, whose partials are discrete gradients, and the implicit midpoint rule, whose partials are
!> the exact ones at the midpoint. The double pendulum's step, with or without its constraints, is
!> solved on the condensed unknowns by the fused kernel (src/scheme/pendulum_step_kernel); any
!> other model or constraint by the generic residual (src/scheme/step_residual), which
!> -eme_fused_kernel false also selects.
!> A step of dt whose root no strategy finds is replaced by two steps of dt/2 of the same scheme,
!> recursively, down to dt/2**6 (-eme_max_halvings changes the depth): each is a full step, so the
!> structure holds on every substep and so over the output step. The output stays on the user's
!> grid; the per-step dataset `substeps` records how many steps made each output step, and the
!> multipliers recorded are their time averages, so that dt times the recorded heat supply is the
!> heat the substeps supplied. A step that fails even in halves ends the run.
module discrete_gradient_stepper
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint
  use pendulum_step_kernel, only: pendulum_step, build_pendulum_step, condensed_offset
  use snes_solver, only: newton_solver
  use solver_options, only: step_solver_options, read_solver_options
  use retry_strategies, only: root_search, find_root
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report, step_diagnostic, solver_report
  use solver_description, only: add_setting, text_setting, number_setting
  use number_text, only: integer_text
  implicit none (type, external)
  private
  public :: step_solver, new_eme, new_midpoint

  !> What the substeps of one output step add up to.
  type :: substep_tally
    integer :: substeps = 0
    integer :: strategy = 0             !! the largest retry strategy a substep needed
    integer :: newton_iterations = 0
    integer :: solves = 0
    integer :: rejected = 0
    real(real64), allocatable :: multiplier_integral(:)   !! sum of h lambda over the substeps
    character(len=:), allocatable :: reason, last_rejection
  end type substep_tally

  !> The step's system and the solver that keeps its PETSc objects from run to run.
  type, extends(time_stepper) :: step_solver
    integer :: partials_rule = partials_discrete_gradient
    type(step_problem) :: problem          !! the generic step (kept up to date also when fused)
    type(pendulum_step) :: kernel          !! the fused, condensed step
    logical :: fused = .false.             !! the kernel solves the steps
    integer :: max_halvings = 6            !! a step is solved in halves down to dt/2**max_halvings
    type(newton_solver) :: solver
  contains
    procedure :: start
    procedure :: advance
    procedure :: release
    procedure :: diagnostics
    procedure :: describe_solver
  end type step_solver

contains

  !> EME (eq. (15)): discrete gradients of the subsystems' potentials.
  subroutine new_eme(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=step_solver(partials_rule=partials_discrete_gradient))
  end subroutine new_eme

  !> The implicit midpoint rule (FORMULATION section 6).
  subroutine new_midpoint(integrator)
    class(time_stepper), allocatable, intent(out) :: integrator

    allocate (integrator, source=step_solver(partials_rule=partials_midpoint))
  end subroutine new_midpoint

  !> The step problem of the run; the SNES objects are reused when the size is the same.
  subroutine start(self, choice, model, constraints, z0, ierr)
    class(step_solver), intent(inout), target :: self
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    integer, intent(out) :: ierr
    type(step_solver_options) :: options

    if (allocated(self%problem%model)) deallocate (self%problem%model)
    allocate (self%problem%model, source=model)
    self%problem%constraints = constraints
    self%problem%partials_rule = self%partials_rule
    self%problem%gradient = choice%discrete_gradient
    self%problem%metric = choice%metric
    self%problem%dt = choice%dt
    self%problem%z_old = z0
    call read_solver_options(options, ierr)
    if (ierr /= 0) return
    self%max_halvings = options%max_halvings
    self%fused = .false.
    if (options%fused_kernel) call build_pendulum_step(self%problem, self%kernel, self%fused)
    if (self%fused) then
      call self%solver%prepare(self%kernel, choice%newton_tol, choice%newton_max_iterations, ierr)
    else
      call self%solver%prepare(self%problem, choice%newton_tol, choice%newton_max_iterations, ierr)
    end if
  end subroutine start

  !> The per-step dataset of these schemes: the substeps of each output step.
  function diagnostics(self) result(specs)
    class(step_solver), intent(in) :: self
    type(step_diagnostic), allocatable :: specs(:)

    specs = [step_diagnostic('substeps', '1', 'steps of the scheme in the output step: 1, or more where halves '// &
                             'replaced a step without a root (-eme_max_halvings deep); multipliers are then the '// &
                             'substeps'' time averages', 'sum')]
  end function diagnostics

  !> The step's SNES as it was set up (command-line options applied), with the kernel it solves
  !> and the halving depth.
  function describe_solver(self) result(report)
    class(step_solver), intent(in) :: self
    type(solver_report) :: report
    integer :: ierr

    call self%solver%describe(report, ierr)
    if (ierr /= 0) call add_setting(report, text_setting('error', 'PETSc could not describe the SNES'))
    call add_setting(report, text_setting('eme_fused_kernel', merge('true ', 'false', self%fused)))
    call add_setting(report, number_setting('eme_max_halvings', real(self%max_halvings, real64)))
  end function describe_solver

  !> One step of dt from x_old, in halves where needed (module header); on acceptance, the
  !> temperatures the (last sub)step's K0 used.
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, ierr)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    integer, intent(out) :: ierr
    type(substep_tally) :: tally
    integer :: stat, n

    n = self%problem%model%state_size
    allocate (tally%multiplier_integral(size(x_old) - n))
    tally%multiplier_integral = 0.0_real64
    tally%reason = ''
    tally%last_rejection = ''
    call step_or_halve(self, x_old, dt, guess, x_new, 0, tally, report%accepted, ierr)
    report%strategy = tally%strategy
    report%newton_iterations = tally%newton_iterations
    report%solves = tally%solves
    report%rejected = tally%rejected
    report%reason = tally%reason
    report%last_rejection = tally%last_rejection
    report%diagnostics = [real(tally%substeps, real64)]
    report%halvings = max(0, tally%substeps - 1)     ! each halving adds one substep
    report%residual_norm = self%solver%last_residual_norm
    report%converged_reason = self%solver%last_reason
    allocate (report%scheme_temperature(self%problem%model%subsystem_count()))
    report%scheme_temperature = 0.0_real64
    if (ierr /= 0 .or. .not. report%accepted) return
    if (tally%substeps > 1) x_new(n + 1:) = tally%multiplier_integral/dt
    if (self%fused) then
      call self%kernel%scheme_temperatures(x_new(condensed_offset + 1:), report%scheme_temperature, stat)
    else
      call self%problem%scheme_temperatures(x_new, report%scheme_temperature, stat)
    end if
    if (stat /= 0) then    ! check_root has accepted the root, so this does not happen
      report%accepted = .false.
      report%reason = 'the scheme temperatures of the root are undefined'
    end if
  end subroutine advance

  ! The step of h from x_old, or, if no strategy finds its root, its two halves (each in halves
  ! where needed) from the predictors interpolated and extrapolated from `guess`; `depth` halvings
  ! made h. The last substep leaves its problem set up (scheme_temperatures).
  recursive subroutine step_or_halve(self, x_old, h, guess, x_new, depth, tally, accepted, ierr)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    integer, intent(in) :: depth
    type(substep_tally), intent(inout) :: tally
    logical, intent(out) :: accepted
    integer, intent(out) :: ierr
    type(root_search) :: search
    real(real64) :: x_half(size(x_old))

    call solve_step(self, x_old, h, guess, x_new, depth == 0, search, ierr)
    tally%newton_iterations = tally%newton_iterations + search%newton_iterations
    tally%solves = tally%solves + search%solves
    tally%rejected = tally%rejected + search%rejected_roots
    if (len(search%last_rejection) > 0) tally%last_rejection = search%last_rejection
    accepted = search%accepted .and. ierr == 0
    if (accepted) then
      tally%substeps = tally%substeps + 1
      tally%strategy = max(tally%strategy, search%strategy)
      tally%multiplier_integral = tally%multiplier_integral + h*x_new(size(x_old) - size(tally%multiplier_integral) + 1:)
      return
    end if
    if (ierr /= 0) return
    if (depth == self%max_halvings) then
      tally%reason = search%reason
      if (depth > 0) tally%reason = search%reason//' (also in steps of dt/'//integer_text(2**depth)//')'
      return
    end if
    call step_or_halve(self, x_old, 0.5_real64*h, x_old + 0.5_real64*(guess - x_old), x_half, depth + 1, tally, &
                       accepted, ierr)
    if (.not. accepted) return
    call step_or_halve(self, x_half, 0.5_real64*h, 2*x_half - x_old, x_new, depth + 1, tally, accepted, ierr)
  end subroutine step_or_halve

  ! One search for the root of the step of h from x_old (no halving); with continuation in s if
  ! `continuing`.
  subroutine solve_step(self, x_old, h, guess, x_new, continuing, search, ierr)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), h, guess(:)
    real(real64), intent(out) :: x_new(:)
    logical, intent(in) :: continuing
    type(root_search), intent(out) :: search
    integer, intent(out) :: ierr
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
        real(real64) :: y_new(size(guess) - condensed_offset)

        call find_root(self%solver, self%kernel, start(condensed_offset + 1:), self%kernel%condense(guess), y_new, &
                       search, ierr, continuing)
        x_new = self%kernel%expand(y_new)
      end block
    else
      call find_root(self%solver, self%problem, start, guess, x_new, search, ierr, continuing)
    end if
  end subroutine solve_step

  !> Frees the SNES objects.
  subroutine release(self, ierr)
    class(step_solver), intent(inout) :: self
    integer, intent(out) :: ierr

    ierr = 0
    if (self%solver%created) call self%solver%destroy(ierr)
  end subroutine release

end module discrete_gradient_stepper
