!> The one-step schemes of the paper, each step one nonlinear system (src/scheme/step_residual)
!> solved by Newton's method in PETSc SNES (src/solver/snes_solver) under the retry strategies
!> (src/solver/retry_strategies): EME, whose partials are discrete gradients, and the implicit
!> midpoint rule, whose partials are the exact ones at the midpoint. The step size never changes;
!> a step that no strategy solves ends the run.
module discrete_gradient_stepper
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint
  use snes_solver, only: newton_solver
  use retry_strategies, only: root_search, find_root
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report
  implicit none (type, external)
  private
  public :: step_solver, new_eme, new_midpoint

  !> The step's system and the solver that keeps its PETSc objects from run to run.
  type, extends(time_stepper) :: step_solver
    integer :: partials_rule = partials_discrete_gradient
    type(step_problem) :: problem
    type(newton_solver) :: solver
  contains
    procedure :: start
    procedure :: advance
    procedure :: release
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

    if (allocated(self%problem%model)) deallocate (self%problem%model)
    allocate (self%problem%model, source=model)
    self%problem%constraints = constraints
    self%problem%partials_rule = self%partials_rule
    self%problem%gradient = choice%discrete_gradient
    self%problem%metric = choice%metric
    self%problem%dt = choice%dt
    self%problem%z_old = z0
    call self%solver%prepare(self%problem, choice%newton_tol, choice%newton_max_iterations, ierr)
  end subroutine start

  !> One step of dt from x_old; on acceptance, the temperatures the step's K0 used.
  subroutine advance(self, x_old, t_old, dt, guess, x_new, report, ierr)
    class(step_solver), intent(inout), target :: self
    real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
    real(real64), intent(out) :: x_new(:)
    type(step_report), intent(out) :: report
    integer, intent(out) :: ierr
    type(root_search) :: search
    real(real64) :: start(size(guess))
    integer :: stat

    associate (n => self%problem%model%state_size)
      self%problem%z_old = x_old(1:n)
      self%problem%dt = dt
      ! The old state (with the guessed multipliers) is a root of the step of length 0.
      start = guess
      start(1:n) = x_old(1:n)
    end associate
    call find_root(self%solver, self%problem, start, guess, x_new, search, ierr)
    report%accepted = search%accepted
    report%strategy = search%strategy
    report%newton_iterations = search%newton_iterations
    report%solves = search%solves
    report%rejected = search%rejected_roots
    report%reason = search%reason
    report%last_rejection = search%last_rejection
    allocate (report%scheme_temperature(self%problem%model%subsystem_count()))
    report%scheme_temperature = 0.0_real64
    if (ierr /= 0 .or. .not. report%accepted) return
    call self%problem%scheme_temperatures(x_new, report%scheme_temperature, stat)
    if (stat /= 0) then    ! check_root has accepted the root, so this does not happen
      report%accepted = .false.
      report%reason = 'the scheme temperatures of the root are undefined'
    end if
  end subroutine advance

  !> Frees the SNES objects.
  subroutine release(self, ierr)
    class(step_solver), intent(inout) :: self
    integer, intent(out) :: ierr

    ierr = 0
    if (self%solver%created) call self%solver%destroy(ierr)
  end subroutine release

end module discrete_gradient_stepper
