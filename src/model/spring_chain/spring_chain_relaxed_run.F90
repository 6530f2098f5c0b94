!> The relaxed Runge-Kutta family on the chain split over ranks (docs/integrators.md, "The
!> relaxed family on the split chain"): the dense path's relaxed steps (src/integrator/
!> relaxed_stepper) on spring_chain_dmda's DMDA, every whole-state quantity a sum of the ranks'
!> shares (spring_chain_relaxation_share):
!>  - the stages k_i = f(g_i), g_i = z + h sum_j a_ij k_j, of the chain's GENERIC field
!>    (spring_chain_dmda's field_at, the rows each rank owns) in entropy variables whatever the
!>    run's variable (each spring's tau converted at its temperature, locally);
!>  - d = h sum_i b_i k_i and e_S = h sum_i b_i sigma(g_i) = sum_a d(s_a), summed over the ranks;
!>  - the relaxation's root gamma with E(P(z + gamma d)) = E(z), found by src/solver/
!>    relaxation_root's search (the dense path's), r(gamma) the sum of the ranks' per-part
!>    differences (spring_chain_step's energy_difference: free of cancellation), P the least
!>    change of the momenta that keeps the conserved components of J (a hanging 3D chain's about
!>    the gravity axis; none with fixed-fixed ends under gravity), from global sums;
!>  - a step without a root (or with a non-finite stage, or gamma outside the band of
!>    &integrator tolerance) replaced by two halves, recursively, max_halvings deep, counted as on
!>    the dense path, and the dense path's accuracy warnings at the run's end.
!> Time is relaxed too, as on the dense path: a step of h reaches t + gamma h, so its row is
!> written at the time it reached (the run chooses its times, as every relaxed run does), and the
!> step that reaches t_end, or the next output time of &output interval, lands on it (gamma then
!> scales the update only: the dense path's landing step). From the same state the states and the
!> times are the dense path's, step by step; the order in time is the tableau's.
!> With embedded weights (relaxed_dp853) each `step` is one accepted step of the size DOP853's
!> controller chooses (src/solver/dop853_control, as the dense path's relaxed_step_control; the
!> error norm summed over the ranks); its next trial
!> step and the run's record go into the resume record (spring_chain_relaxed_control). Implicit
!> stages (relaxed_gauss6) are solved together by PETSc SNES over the split state
!> (spring_chain_stage_solve: the dense path's stage equations, s stages of a point side by side);
!> a step whose stages Newton does not solve is halved, as one without a root.
!> All ranks take the same decisions from the same summed figures (MPI_Allreduce gives every
!> rank the same sum).
!> This module holds the run's type, its start, its fixed steps (halved when rejected) and its
!> end; beside it: the relaxed step with its stages and rank sums (submodule
!> spring_chain_relaxed_step), the relaxation's root function (spring_chain_relaxed_root),
!> relaxed_dp853's step control (submodule spring_chain_relaxed_control), the run's own variable
!> in snapshot parts (submodule spring_chain_relaxed_parts) and what the run reports, its accuracy
!> warnings among it (submodule spring_chain_relaxed_report).
module spring_chain_relaxed_run
#include <petsc/finclude/petscdmda.h>
  use petscdmda
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_type, fail, fail_on_code, failure_none, failure_input, domain_overflow, failure_code_name
  use number_text, only: integer_text, fixed_text, scientific_text, reals_text
  use model_interface, only: generic_model
  use thermo_variable_kinds, only: tau_entropy
  use solver_description, only: solver_report, no_solver
  use relaxation_root, only: max_halvings, gamma_band, gamma_warning_deviation
  use dop853_control, only: landing_slack
  use butcher_tableaux, only: butcher_tableau
  use distributed_model, only: distributed_settings, distributed_step, distributed_part
  use spring_chain_spring, only: chain_spring
  use spring_chain_model, only: spring_chain
  use spring_chain_balance, only: conserved_axes
  use spring_chain_sparse_run, only: sparse_chain_run, chain_snes_report
  use spring_chain_stage_solve, only: chain_stage_solver
  implicit none
  private
  public :: relaxed_chain_run


  !> The chain stepped by a relaxed Runge-Kutta tableau; its DMDA state in entropy variables. Do
  !> not copy it after `start`: PETSc holds the address of its chain's context.
  type, extends(sparse_chain_run) :: relaxed_chain_run
    type(chain_spring), allocatable :: run_springs(:)   !! the springs in the run's own variable
    integer :: run_variable = tau_entropy
    type(butcher_tableau) :: tableau
    real(real64) :: gamma_band = huge(1.0_real64)       !! the largest |gamma - 1| accepted
    real(real64), allocatable :: axes(:, :)             !! the conserved components' axes (3 x m)
    Vec, allocatable :: k(:)                            !! the stage derivatives
    Vec :: stage, direction, start_state, step_start    !! g_i, d, z of the substep, z of the step
    Vec :: start_local                                  !! z of the substep on the ghosted points
    logical :: vectors_created = .false.
    type(chain_stage_solver) :: stage_solver            !! implicit stages (relaxed_gauss6)
    real(real64), allocatable :: momenta(:)             !! the conserved components at z
    ! What the current step did (the dense path's per-step figures), and the run's record.
    integer :: attempts = 0, rejections = 0, halvings = 0, gamma_rejections = 0, newton_iterations = 0
    real(real64) :: residual_norm = 0.0_real64          !! the stages' last |R| (implicit stages)
    real(real64) :: last_gamma = 1.0_real64, entropy_production = 0.0_real64
    character(len=:), allocatable :: last_failure
    integer :: run_rejections = 0, run_halvings = 0
    real(real64) :: max_gamma_deviation = 0.0_real64
    ! The time of the state held, where the run ends, the next trial step (adaptive steps: the
    ! tableau's embedded weights) with its tolerance, and the whole state's size.
    real(real64) :: tolerance = 0.0_real64, t = 0.0_real64, t_end = 0.0_real64, h_next = 0.0_real64
    integer :: unknowns = 0
  contains
    procedure :: start
    procedure :: step
    procedure :: part
    procedure :: restore
    procedure :: finish
    procedure :: describe_solver
    procedure :: integrator_diagnostics
    procedure :: accuracy_warnings
    procedure :: resume_state
    procedure :: restore_state
    procedure :: landing_time
  end type relaxed_chain_run

  interface
    !> One relaxed step of h from the state held at self%t, committed when ok (the state and the
    !> time reached: t + gamma h, or the landing time when `landing`); when not ok the state is z
    !> again and last_failure says why; error_norm: DOP853's (0 without embedded weights)
    !> (spring_chain_relaxed_step).
    module recursive subroutine relaxed_step(self, h, landing, ok, error_norm, failure)
      class(relaxed_chain_run), intent(inout), target :: self
      real(real64), intent(in) :: h
      logical, intent(in) :: landing
      logical, intent(out) :: ok
      real(real64), intent(out) :: error_norm
      type(failure_type), intent(out) :: failure
    end subroutine relaxed_step
    !> One accepted step of the controller's size from the state held at self%t
    !> (spring_chain_relaxed_control).
    module subroutine adaptive_step(self, ok, failure)
      class(relaxed_chain_run), intent(inout) :: self
      logical, intent(out) :: ok
      type(failure_type), intent(out) :: failure
    end subroutine adaptive_step
    !> DOP853's error norm of the step of h just relaxed (src/solver/dop853_control), its sums
    !> over the ranks (spring_chain_relaxed_control).
    module subroutine step_error_norm(self, h, error_norm, ierr)
      class(relaxed_chain_run), intent(inout) :: self
      real(real64), intent(in) :: h
      real(real64), intent(out) :: error_norm
      PetscErrorCode, intent(out) :: ierr
    end subroutine step_error_norm
    !> An adaptive run's next trial step and record, for the resume record (distributed_system).
    module subroutine resume_state(self, values)
      class(relaxed_chain_run), intent(in) :: self
      real(real64), allocatable, intent(out) :: values(:)
    end subroutine resume_state
    !> Takes back what resume_state gave, at `time` (distributed_system).
    module subroutine restore_state(self, time, values, failure)
      class(relaxed_chain_run), intent(inout) :: self
      real(real64), intent(in) :: time, values(:)
      type(failure_type), intent(out) :: failure
    end subroutine restore_state
    !> The rank's part of the state for a snapshot, tau in the run's own variable
    !> (spring_chain_relaxed_parts).
    module subroutine part(self, state, failure)
      class(relaxed_chain_run), intent(inout) :: self
      type(distributed_part), intent(out) :: state
      type(failure_type), intent(out) :: failure
    end subroutine part
    !> Makes the rank's part `state` (tau in the run's own variable) the current state, in
    !> entropy variables (spring_chain_relaxed_parts).
    module subroutine restore(self, state, failure)
      class(relaxed_chain_run), intent(inout) :: self
      type(distributed_part), intent(in) :: state
      type(failure_type), intent(out) :: failure
    end subroutine restore
    !> True: each step's outcome carries the relaxed family's per-step figures
    !> (spring_chain_relaxed_report).
    pure logical module function integrator_diagnostics(self)
      class(relaxed_chain_run), intent(in) :: self
    end function integrator_diagnostics
    !> The dense path's accuracy warnings, '' if none (spring_chain_relaxed_report).
    module function accuracy_warnings(self) result(text)
      class(relaxed_chain_run), intent(in) :: self
      character(len=:), allocatable :: text
    end function accuracy_warnings
    !> The implicit stages' SNES; none for explicit stages (spring_chain_relaxed_report).
    module function describe_solver(self) result(report)
      class(relaxed_chain_run), intent(in) :: self
      type(solver_report) :: report
    end function describe_solver
  end interface

contains

  !> Sets up the chain in entropy variables from z0 (converted spring by spring) on `comm`
  !> (sparse_chain_run's set_up, which refuses what the path cannot run) and the step's vectors.
  subroutine start(self, settings, model, z0, comm, failure)
    class(relaxed_chain_run), intent(inout), target :: self
    type(distributed_settings), intent(in) :: settings
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    class(generic_model), allocatable :: entropy_model
    real(real64) :: z(size(z0))
    integer :: stat
    PetscErrorCode :: ierr

    if (settings%tableau%stages == 0) then
      ! Not a tableau: chain_problem_of says why (set_up refuses it).
      call self%set_up(settings, model, z0, comm, failure)
      if (.not. failure%failed()) call fail(failure, failure_input, settings%input_file// &
                                            ', &integrator: scheme: '''//trim(settings%scheme)//''' has no tableau', 'scheme')
      return
    end if
    select type (model)
    type is (spring_chain)
      self%run_springs = model%springs
      self%run_variable = model%thermo_variable
      self%axes = conserved_axes(model%layout, model%gravity)
    end select
    call model%in_variable(tau_entropy, entropy_model)
    call model%convert_state(z0, entropy_model, z, stat)
    if (stat /= failure_none) then
      call fail(failure, failure_input, settings%input_file//': the initial state cannot be taken to the entropy '// &
                'variables: '//failure_code_name(stat), '&initial')
      return
    end if
    call self%set_up(settings, entropy_model, z, comm, failure)
    if (failure%failed()) return
    self%tableau = settings%tableau
    self%tolerance = settings%tolerance
    self%t = 0.0_real64
    self%t_end = settings%t_end
    self%h_next = settings%dt
    self%unknowns = size(z0)
    self%gamma_band = huge(1.0_real64)
    if (settings%tolerance_given .or. self%tableau%embedded) self%gamma_band = gamma_band(settings%tolerance, self%tableau%order)
    self%run_rejections = 0
    self%run_halvings = 0
    self%max_gamma_deviation = 0.0_real64
    call create_vectors(self, self%tableau%stages, ierr)
    if (ierr == 0 .and. self%tableau%implicit) call self%stage_solver%create(self%chain, self%tableau%a, settings%newton_tol, &
                                                                     settings%newton_max_iterations, ierr)
    call fail_on_code(failure, ierr, 'setting up the chain''s relaxed steps')
  end subroutine start

  subroutine create_vectors(self, stages, ierr)
    class(relaxed_chain_run), intent(inout) :: self
    integer, intent(in) :: stages
    PetscErrorCode, intent(out) :: ierr
    integer :: i

    allocate (self%k(stages))
    do i = 1, stages
      PetscCall(VecDuplicate(self%chain%x, self%k(i), ierr))
    end do
    PetscCall(VecDuplicate(self%chain%x, self%stage, ierr))
    PetscCall(VecDuplicate(self%chain%x, self%direction, ierr))
    PetscCall(VecDuplicate(self%chain%x, self%start_state, ierr))
    PetscCall(VecDuplicate(self%chain%x, self%step_start, ierr))
    PetscCall(VecDuplicate(self%chain%context%old_local, self%start_local, ierr))
    self%vectors_created = .true.
  end subroutine create_vectors

  !> One step of dt from the state held at self%t, to t + gamma dt (a relaxed step, or two halves of
  !> it, recursively), landing on t_end or the next output time when it reaches it; with embedded
  !> weights one accepted step of the controller's size instead (distributed_system). A step that
  !> cannot be done keeps the state and its time (outcome%converged false, outcome%failure says
  !> why).
  subroutine step(self, dt, outcome, failure)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr
    logical :: ok
    real(real64) :: t_start

    self%attempts = 0
    self%rejections = 0
    self%halvings = 0
    self%gamma_rejections = 0
    self%newton_iterations = 0
    self%entropy_production = 0.0_real64
    self%last_failure = ''
    t_start = self%t
    call self%chain%hold_old_state(ierr)
    if (ierr == 0) call VecCopy(self%chain%x, self%step_start, ierr)
    call fail_on_code(failure, ierr, 'starting the chain''s relaxed step')
    if (failure%failed()) return
    if (self%tableau%embedded) then
      call adaptive_step(self, ok, failure)
    else if (self%t + (1.0_real64 + landing_slack)*dt >= self%landing_time()) then
      call step_or_halve(self, self%landing_time() - self%t, .true., 0, ok, failure)
    else
      call step_or_halve(self, dt, .false., 0, ok, failure)
    end if
    if (failure%failed()) return
    outcome%converged = ok
    outcome%chose_time = .true.
    outcome%iterations = self%newton_iterations
    outcome%solves = self%attempts
    outcome%rejected = self%rejections
    outcome%halvings = self%halvings
    outcome%rejected_steps = self%rejections
    outcome%residual_norm = self%residual_norm
    outcome%diagnostics = [self%last_gamma, real(self%rejections, real64), real(self%halvings, real64), &
                           self%entropy_production, real(self%gamma_rejections, real64)]
    if (ok) then
      self%run_rejections = self%run_rejections + self%rejections
      self%run_halvings = self%run_halvings + self%halvings
    else
      outcome%failure = self%last_failure
      self%t = t_start
      call VecCopy(self%step_start, self%chain%x, ierr)
      call fail_on_code(failure, ierr, 'restoring the chain''s state after a failed relaxed step')
    end if
    outcome%time = self%t
  end subroutine step

  ! A step of h (landing: on the landing time), or, if it is rejected, two halves, recursively (the
  ! second half of a landing step lands); ok = .false. when halving went past max_halvings.
  recursive subroutine step_or_halve(self, h, landing, depth, ok, failure)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(in) :: h
    logical, intent(in) :: landing
    integer, intent(in) :: depth
    logical, intent(out) :: ok
    type(failure_type), intent(out) :: failure
    real(real64) :: error_norm

    call relaxed_step(self, h, landing, ok, error_norm, failure)
    if (ok .or. failure%failed()) return
    self%rejections = self%rejections + 1
    self%halvings = self%halvings + 1
    if (depth == max_halvings) then
      self%last_failure = 'a step halved '//integer_text(max_halvings)//' times still failed (last: '// &
                          self%last_failure//')'
      return
    end if
    call step_or_halve(self, 0.5_real64*h, .false., depth + 1, ok, failure)
    if (.not. ok .or. failure%failed()) return
    if (landing) then
      call step_or_halve(self, self%landing_time() - self%t, .true., depth + 1, ok, failure)
    else
      call step_or_halve(self, 0.5_real64*h, .false., depth + 1, ok, failure)
    end if
  end subroutine step_or_halve

  !> The time a step lands on when it reaches it: t_end, or the next output time of &output
  !> interval (stop_time, which the time loop sets). (Type-bound: gfortran's link-time
  !> optimisation drops a private module function that only submodules call.)
  pure real(real64) function landing_time(self)
    class(relaxed_chain_run), intent(in) :: self

    landing_time = min(self%t_end, self%stop_time)
  end function landing_time

  !> Frees the step's vectors, then the chain's PETSc objects; failure keeps the first failure.
  subroutine finish(self, failure)
    class(relaxed_chain_run), intent(inout) :: self
    type(failure_type), intent(inout) :: failure
    type(failure_type) :: freeing
    PetscErrorCode :: ierr
    integer :: i

    ierr = 0
    if (self%vectors_created) then
      do i = 1, size(self%k)
        if (ierr == 0) call VecDestroy(self%k(i), ierr)
      end do
      deallocate (self%k)
      if (ierr == 0) call VecDestroy(self%stage, ierr)
      if (ierr == 0) call VecDestroy(self%direction, ierr)
      if (ierr == 0) call VecDestroy(self%start_state, ierr)
      if (ierr == 0) call VecDestroy(self%step_start, ierr)
      if (ierr == 0) call VecDestroy(self%start_local, ierr)
    end if
    if (ierr == 0) call self%stage_solver%destroy(ierr)
    self%vectors_created = .false.
    call fail_on_code(freeing, ierr, 'freeing the chain''s relaxed steps')
    if (.not. failure%failed() .and. freeing%failed()) failure = freeing
    call self%sparse_chain_run%finish(failure)
  end subroutine finish

end module spring_chain_relaxed_run
