!> The one-step schemes of the paper, each step one nonlinear system solved by Newton's method in
!> PETSc SNES (src/solver/snes_solver) under the retry strategies (src/solver/retry_strategies):
!> EME, whose partials are discrete gradients, and the implicit midpoint rule, whose partials are
!> the exact ones at the midpoint. The double pendulum's step, with or without its constraints, is
!> solved on the condensed unknowns by the fused kernel (src/scheme/pendulum_step_kernel); any
!> other model or constraint by the generic residual (src/scheme/step_residual), which
!> -eme_fused_kernel false also selects. The step size never changes; a step that no strategy
!> solves ends the run.
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
  use stepper, only: time_stepper, step_report
  implicit none (type, external)
  private
  public :: step_solver, new_eme, new_midpoint

  !> The step's system and the solver that keeps its PETSc objects from run to run.
  type, extends(time_stepper) :: step_solver
    integer :: partials_rule = partials_discrete_gradient
    type(step_problem) :: problem          !! the generic step (kept up to date also when fused)
    type(pendulum_step) :: kernel          !! the fused, condensed step
    logical :: fused = .false.             !! the kernel solves the steps
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
    self%fused = .false.
    if (options%fused_kernel) call build_pendulum_step(self%problem, self%kernel, self%fused)
    if (self%fused) then
      call self%solver%prepare(self%kernel, choice%newton_tol, choice%newton_max_iterations, ierr)
    else
      call self%solver%prepare(self%problem, choice%newton_tol, choice%newton_max_iterations, ierr)
    end if
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
    if (self%fused) then
      ! The same search on the condensed unknowns y = x(7:); q' follows from y.
      call self%kernel%set_old_state(x_old)
      self%kernel%dt = dt
      block
        real(real64) :: y_new(size(guess) - condensed_offset)

        call find_root(self%solver, self%kernel, start(condensed_offset + 1:), self%kernel%condense(guess), y_new, &
                       search, ierr)
        x_new = self%kernel%expand(y_new)
      end block
    else
      call find_root(self%solver, self%problem, start, guess, x_new, search, ierr)
    end if
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

  !> Frees the SNES objects.
  subroutine release(self, ierr)
    class(step_solver), intent(inout) :: self
    integer, intent(out) :: ierr

    ierr = 0
    if (self%solver%created) call self%solver%destroy(ierr)
  end subroutine release

end module discrete_gradient_stepper
