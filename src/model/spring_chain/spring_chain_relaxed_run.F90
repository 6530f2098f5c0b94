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
!> One `step(dt)` lands on t + dt, as the split time loop steps: every step is what the dense
!> path calls a landing step (no relaxation in time: gamma scales the update, not the time), so
!> from the same state the states are the dense path's, step by step, while the times of the
!> dense path's rows advance by gamma h; the order in time drops by one (gamma = 1 + O(h^(p-1))).
!> With embedded weights (relaxed_dp853) each `step` is one accepted step of the size DOP853's
!> controller chooses (src/solver/dop853_control, as the dense path's relaxed_step_control; the
!> error norm summed over the ranks), landing on t_end or the next output time; its next trial
!> step and the run's record go into the resume record (spring_chain_relaxed_control). Implicit
!> stages (relaxed_gauss6) are refused at input (spring_chain_sparse_run's chain_problem_of).
!> All ranks take the same decisions from the same summed figures (MPI_Allreduce gives every
!> rank the same sum).
module spring_chain_relaxed_run
#include <petsc/finclude/petscdmda.h>
  use petscdmda
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_type, fail, fail_on_code, failure_none, failure_input, domain_overflow, failure_code_name
  use number_text, only: integer_text, fixed_text, scientific_text, reals_text
  use model_interface, only: generic_model
  use thermo_variable_kinds, only: tau_entropy
  use solver_description, only: solver_report, no_solver
  use relaxation_root, only: relaxation_function, find_relaxation_root, max_halvings, gamma_band_factor, &
                             gamma_warning_deviation
  use dop853_control, only: accepted_step_factor, rejected_step_factor, max_error_rejections, landing_slack
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use distributed_model, only: distributed_settings, distributed_step, distributed_part
  use spring_chain_spring, only: chain_spring
  use spring_chain_model, only: spring_chain
  use spring_chain_balance, only: conserved_axes
  use spring_chain_sparse_run, only: sparse_chain_run
  use spring_chain_relaxation_share, only: rounding_floor_share, momentum_share, projection_coefficients, &
                                           project_momenta, converted_taus
  implicit none
  private
  public :: relaxed_chain_run

  !> The chain stepped by a relaxed Runge-Kutta tableau; its DMDA state in entropy variables. Do
  !> not copy it after `start`: PETSc holds the address of its chain's context.
  type, extends(sparse_chain_run) :: relaxed_chain_run
    type(chain_spring), allocatable :: run_springs(:)   !! the springs in the run's own variable
    integer :: run_variable = tau_entropy
    real(real64), allocatable :: a(:, :), b(:)          !! the tableau
    integer :: order = 0
    real(real64) :: gamma_band = huge(1.0_real64)       !! the largest |gamma - 1| accepted
    real(real64), allocatable :: axes(:, :)             !! the conserved components' axes (3 x m)
    Vec, allocatable :: k(:)                            !! the stage derivatives
    Vec :: stage, direction, start_state, step_start    !! g_i, d, z of the substep, z of the step
    Vec :: start_local                                  !! z of the substep on the ghosted points
    logical :: vectors_created = .false.
    real(real64), allocatable :: momenta(:)             !! the conserved components at z
    ! What the current step did (the dense path's per-step figures), and the run's record.
    integer :: attempts = 0, rejections = 0, halvings = 0, gamma_rejections = 0
    real(real64) :: last_gamma = 1.0_real64, entropy_production = 0.0_real64
    character(len=:), allocatable :: last_failure
    integer :: run_rejections = 0, run_halvings = 0
    real(real64) :: max_gamma_deviation = 0.0_real64
    ! Adaptive steps (embedded weights): the error estimates' weights, the tolerance, the time of
    ! the state held, where the run ends, the next trial step and the whole state's size.
    logical :: adaptive = .false.
    real(real64), allocatable :: e5(:), e3(:)
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
  end type relaxed_chain_run

  !> A relaxed step's relaxation as src/solver/relaxation_root searches it: the run it relaxes.
  type, extends(relaxation_function) :: split_relaxation
    class(relaxed_chain_run), pointer :: run => null()
  contains
    procedure :: move
    procedure :: scaled_residual
  end type split_relaxation

  interface
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

    if (.not. allocated(settings%weights)) then
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
    self%a = settings%stage_matrix
    self%b = settings%weights
    self%order = settings%order
    self%adaptive = settings%embedded_weights
    if (self%adaptive) then
      self%e5 = settings%error_weights5
      self%e3 = settings%error_weights3
    end if
    self%tolerance = settings%tolerance
    self%t = 0.0_real64
    self%t_end = settings%t_end
    self%h_next = settings%dt
    self%unknowns = size(z0)
    self%gamma_band = huge(1.0_real64)
    if (settings%tolerance_given .or. self%adaptive) self%gamma_band = gamma_band_factor* &
      settings%tolerance**(real(self%order - 1, real64)/real(self%order + 1, real64))
    self%run_rejections = 0
    self%run_halvings = 0
    self%max_gamma_deviation = 0.0_real64
    call create_vectors(self, size(self%b), ierr)
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

  !> One step of dt from the state held, landing on t + dt: a relaxed step, or two halves of it,
  !> recursively; with embedded weights one accepted step of the controller's size instead
  !> (distributed_system). A step that cannot be done keeps the state (outcome%converged false,
  !> outcome%failure says why).
  subroutine step(self, dt, outcome, failure)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(in) :: dt
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr
    logical :: ok
    real(real64) :: h

    self%attempts = 0
    self%rejections = 0
    self%halvings = 0
    self%gamma_rejections = 0
    self%entropy_production = 0.0_real64
    self%last_failure = ''
    call self%chain%hold_old_state(ierr)
    if (ierr == 0) call VecCopy(self%chain%x, self%step_start, ierr)
    call fail_on_code(failure, ierr, 'starting the chain''s relaxed step')
    if (failure%failed()) return
    if (self%adaptive) then
      call adaptive_step(self, h, ok, failure)
      outcome%chose_time = .true.
      outcome%time = self%t
      outcome%dt_taken = h
    else
      call step_or_halve(self, dt, 0, ok, failure)
    end if
    if (failure%failed()) return
    outcome%converged = ok
    outcome%iterations = 0
    outcome%solves = self%attempts
    outcome%rejected = self%rejections
    outcome%halvings = self%halvings
    outcome%rejected_steps = self%rejections
    outcome%residual_norm = 0.0_real64
    outcome%diagnostics = [self%last_gamma, real(self%rejections, real64), real(self%halvings, real64), &
                           self%entropy_production, real(self%gamma_rejections, real64)]
    if (ok) then
      self%run_rejections = self%run_rejections + self%rejections
      self%run_halvings = self%run_halvings + self%halvings
    else
      outcome%failure = self%last_failure
      call VecCopy(self%step_start, self%chain%x, ierr)
      call fail_on_code(failure, ierr, 'restoring the chain''s state after a failed relaxed step')
    end if
  end subroutine step

  ! A step of h, or, if it is rejected, two halves, recursively; ok = .false. when halving went
  ! past max_halvings.
  recursive subroutine step_or_halve(self, h, depth, ok, failure)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(in) :: h
    integer, intent(in) :: depth
    logical, intent(out) :: ok
    type(failure_type), intent(out) :: failure

    call relaxed_step(self, h, ok, failure)
    if (ok .or. failure%failed()) return
    self%rejections = self%rejections + 1
    self%halvings = self%halvings + 1
    if (depth == max_halvings) then
      self%last_failure = 'a step halved '//integer_text(max_halvings)//' times still failed (last: '// &
                          self%last_failure//')'
      return
    end if
    call step_or_halve(self, 0.5_real64*h, depth + 1, ok, failure)
    if (ok .and. .not. failure%failed()) call step_or_halve(self, 0.5_real64*h, depth + 1, ok, failure)
  end subroutine step_or_halve

  ! One accepted step of h from the state held at self%t, as the dense path's relaxed_step_control
  ! takes it: h the next trial step, shortened to land on t_end or the next output time when it
  ! (nearly) reaches it; a step relaxed but refused by the error norm is undone and retried
  ! smaller, one without a relaxation root halved. ok = .false. after max_error_rejections, or
  ! when h falls to round-off (last_failure says why).
  subroutine adaptive_step(self, h, ok, failure)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(out) :: h
    logical, intent(out) :: ok
    type(failure_type), intent(out) :: failure
    real(real64) :: error_norm, landing_time, production, gamma, deviation
    logical :: landing
    integer :: tries
    PetscErrorCode :: ierr

    ok = .false.
    h = self%h_next
    landing_time = min(self%t_end, self%stop_time)
    do tries = 1, max_error_rejections
      landing = self%t + (1.0_real64 + landing_slack)*h >= landing_time
      if (landing) h = landing_time - self%t
      production = self%entropy_production
      gamma = self%last_gamma
      deviation = self%max_gamma_deviation
      call relaxed_step(self, h, ok, failure)
      if (failure%failed()) return
      if (ok) then
        call step_error_norm(self, h, error_norm, ierr)
        call fail_on_code(failure, ierr, 'the error norm of the chain''s relaxed step')
        if (failure%failed()) return
        if (error_norm <= 1.0_real64) then
          if (.not. landing) self%h_next = h*accepted_step_factor(error_norm, tries > 1)
          self%t = self%t + h
          if (landing) self%t = landing_time
          return
        end if
        ! Relaxed, but not accepted by the error test: undone, and retried smaller.
        self%rejections = self%rejections + 1
        ok = .false.
        self%entropy_production = production
        self%last_gamma = gamma
        self%max_gamma_deviation = deviation
        self%last_failure = 'the error norm '//scientific_text(error_norm)//' exceeded 1'
        call VecCopy(self%start_state, self%chain%x, ierr)
        call fail_on_code(failure, ierr, 'restoring the chain''s state after a rejected relaxed step')
        if (failure%failed()) return
        h = h*rejected_step_factor(error_norm)
      else
        self%rejections = self%rejections + 1
        self%halvings = self%halvings + 1
        h = 0.5_real64*h
      end if
      if (h <= 1.0e-14_real64*max(1.0_real64, abs(self%t))) exit
    end do
    self%last_failure = 'the adaptive step shrank below round-off or was rejected '//integer_text(max_error_rejections)// &
                        ' times (last: '//self%last_failure//')'
  end subroutine adaptive_step

  ! One relaxed step of h from the state held, committed when ok: the stages, d and e_S, the
  ! rounding floor and the conserved components at z (one sum over the ranks), then the
  ! relaxation. When not ok the state is z again and last_failure says why.
  subroutine relaxed_step(self, h, ok, failure)
    class(relaxed_chain_run), intent(inout), target :: self
    real(real64), intent(in) :: h
    logical, intent(out) :: ok
    type(failure_type), intent(out) :: failure
    type(split_relaxation) :: relaxation
    real(real64) :: sums(2 + size(self%axes, 2)), gamma, resolution, largest
    integer :: evaluations, stat, failed_stage
    PetscErrorCode :: ierr

    ok = .false.
    self%attempts = self%attempts + 1
    call stages_petsc(self, h, failed_stage, largest, ierr)
    if (ierr == 0 .and. failed_stage == 0 .and. largest <= huge(largest)) call sums_petsc(self, sums, stat, ierr)
    call fail_on_code(failure, ierr, 'evaluating the chain''s relaxed stages')
    if (failure%failed()) return
    if (failed_stage > 0) then
      self%last_failure = 'stage '//integer_text(failed_stage)//' left the model''s domain or is not finite'
      return
    else if (.not. (largest <= huge(largest))) then
      self%last_failure = 'a non-finite stage'
      return
    else if (stat /= failure_none) then
      self%last_failure = 'the state left the model''s domain'
      return
    end if
    associate (entropy_estimate => sums(1), floor => sums(2))
      if (any(self%b < 0.0_real64) .and. entropy_estimate < 0.0_real64) then
        self%last_failure = 'the entropy guard: the step''s entropy estimate is negative'
        return
      end if
      self%momenta = sums(3:)
      relaxation%run => self
      call find_relaxation_root(relaxation, max(floor, tiny(1.0_real64)), gamma, ok, evaluations, resolution)
      if (ok .and. abs(gamma - 1.0_real64) > max(self%gamma_band, resolution)) then
        ok = .false.
        self%gamma_rejections = self%gamma_rejections + 1
        self%last_failure = 'gamma = '//fixed_text(gamma, 6)//' outside the band |gamma - 1| <= '// &
                            scientific_text(self%gamma_band)//' of the tolerance'
      else if (.not. ok) then
        self%last_failure = 'no relaxation root gamma in [0.2, 2]'
      end if
      if (.not. ok) then
        call VecCopy(self%start_state, self%chain%x, ierr)
        call fail_on_code(failure, ierr, 'restoring the chain''s state after a rejected relaxed step')
        return
      end if
      self%last_gamma = gamma
      self%entropy_production = self%entropy_production + gamma*entropy_estimate
      if (abs(gamma - 1.0_real64) > resolution) self%max_gamma_deviation = max(self%max_gamma_deviation, &
                                                                                 abs(gamma - 1.0_real64))
    end associate
  end subroutine relaxed_step

  ! z of the substep kept (start_state, start_local), the stages k_i = f(g_i) in turn and
  ! d = h sum_i b_i k_i; failed_stage: the first stage outside a spring's domain on any rank
  ! (0: none); largest: max |d_j| over the ranks (not finite if a stage was not).
  subroutine stages_petsc(self, h, failed_stage, largest, ierr)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(in) :: h
    integer, intent(out) :: failed_stage
    real(real64), intent(out) :: largest
    PetscErrorCode, intent(out) :: ierr
    integer :: i, j, stat
    MPI_Comm :: comm

    failed_stage = 0
    largest = 0.0_real64
    PetscCall(PetscObjectGetComm(self%chain%context%da, comm, ierr))
    PetscCall(VecCopy(self%chain%x, self%start_state, ierr))
    PetscCall(DMGlobalToLocalBegin(self%chain%context%da, self%start_state, INSERT_VALUES, self%start_local, ierr))
    PetscCall(DMGlobalToLocalEnd(self%chain%context%da, self%start_state, INSERT_VALUES, self%start_local, ierr))
    do i = 1, size(self%b)
      PetscCall(VecCopy(self%start_state, self%stage, ierr))
      do j = 1, i - 1
        ! (explicit tableaux have many zeros below the diagonal)
        if (abs(self%a(i, j)) > 0.0_real64) then
          PetscCall(VecAXPY(self%stage, h*self%a(i, j), self%k(j), ierr))
        end if
      end do
      PetscCall(self%chain%field_at(self%stage, self%k(i), stat, ierr))
      if (stat /= failure_none) failed_stage = i
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, failed_stage, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      if (failed_stage > 0) return
    end do
    PetscCall(VecSet(self%direction, 0.0_real64, ierr))
    do i = 1, size(self%b)
      PetscCall(VecAXPY(self%direction, h*self%b(i), self%k(i), ierr))
    end do
    PetscCall(VecNorm(self%direction, NORM_INFINITY, largest, ierr))
  end subroutine stages_petsc

  ! Summed over the ranks: e_S = sum_a d(s_a), the rounding floor 8 eps sum_j |z_j| |dE/dz_j| and
  ! the conserved components at z, into sums(1), sums(2) and sums(3:); stat: a domain code.
  subroutine sums_petsc(self, sums, stat, ierr)
    class(relaxed_chain_run), intent(inout) :: self
    real(real64), intent(out) :: sums(:)
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: d(:), z(:)
    real(real64) :: gram(size(self%axes, 2), size(self%axes, 2))
    integer :: a, shift
    MPI_Comm :: comm

    sums = 0.0_real64
    associate (c => self%chain%context, layout => self%chain%context%problem%layout, &
               points => [self%chain%first_point, self%chain%last_point])
      shift = c%first_row - 1
      PetscCall(borrow_read(self%direction, c%last_row - shift, d, ierr))
      if (layout%invariant_count >= 2) then
        do a = points(1), min(layout%springs, points(2))
          sums(1) = sums(1) + d(layout%tau_index(a) - shift)
        end do
      end if
      PetscCall(give_back_read(self%direction, d, ierr))
      PetscCall(borrow_read(self%start_local, c%local_size, z, ierr))
      call rounding_floor_share(c%problem, z, c%base, points, sums(2), stat)
      call momentum_share(layout, self%axes, z, c%base, [points(1), min(layout%masses, points(2))], gram, sums(3:))
      PetscCall(give_back_read(self%start_local, z, ierr))
      sums(2) = 8*epsilon(1.0_real64)*sums(2)
      PetscCall(PetscObjectGetComm(c%da, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, size(sums), MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
    end associate
  end subroutine sums_petsc

  !> z_new = P(z + gamma d) as the state held: the least change of the momenta that gives the
  !> conserved components their values at z (relaxation_function).
  subroutine move(self, gamma, stat)
    class(split_relaxation), intent(inout) :: self
    real(real64), intent(in) :: gamma
    integer, intent(out) :: stat
    PetscErrorCode :: ierr

    call move_petsc(self%run, gamma, ierr)
    stat = failure_none
    if (ierr /= 0) stat = domain_overflow
  end subroutine move

  subroutine move_petsc(run, gamma, ierr)
    class(relaxed_chain_run), intent(inout) :: run
    real(real64), intent(in) :: gamma
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: owned(:)
    real(real64) :: sums(size(run%axes, 2)*(size(run%axes, 2) + 1)), gram(size(run%axes, 2), size(run%axes, 2))
    integer :: m, shift
    MPI_Comm :: comm

    PetscCall(VecWAXPY(run%chain%x, gamma, run%direction, run%start_state, ierr))
    m = size(run%axes, 2)
    if (m == 0) return
    associate (c => run%chain%context, layout => run%chain%context%problem%layout, &
               masses => [run%chain%first_point, min(run%chain%context%problem%layout%masses, run%chain%last_point)])
      shift = c%first_row - 1
      PetscCall(borrow(run%chain%x, c%last_row - shift, owned, ierr))
      call momentum_share(layout, run%axes, owned, shift, masses, gram, sums(m*m + 1:))
      sums(1:m*m) = reshape(gram, [m*m])
      PetscCall(PetscObjectGetComm(c%da, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, size(sums), MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
      call project_momenta(layout, run%axes, projection_coefficients(reshape(sums(1:m*m), [m, m]), &
                                                                     sums(m*m + 1:) - run%momenta), shift, masses, owned)
      PetscCall(give_back(run%chain%x, owned, ierr))
    end associate
  end subroutine move_petsc

  !> q = r(gamma)/gamma = [E(P(z + gamma d)) - E(z)]/gamma, the energy difference the sum of the
  !> ranks' per-part differences (relaxation_function).
  subroutine scaled_residual(self, gamma, q, stat)
    class(split_relaxation), intent(inout) :: self
    real(real64), intent(in) :: gamma
    real(real64), intent(out) :: q
    integer, intent(out) :: stat
    real(real64) :: change(2)
    PetscErrorCode :: ierr

    q = 0.0_real64
    call self%move(gamma, stat)
    if (stat /= failure_none) return
    call energy_change_petsc(self%run, change, stat, ierr)
    if (ierr /= 0) stat = domain_overflow
    if (stat /= failure_none) return
    q = change(1)/gamma
    if (.not. (abs(q) <= huge(q))) stat = domain_overflow
  end subroutine scaled_residual

  ! E and S of the state held minus those at z (start_local), summed over the ranks; stat: a
  ! domain code (the same on every rank).
  subroutine energy_change_petsc(run, change, stat, ierr)
    class(relaxed_chain_run), intent(inout) :: run
    real(real64), intent(out) :: change(2)
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    MPI_Comm :: comm

    associate (c => run%chain%context)
      PetscCall(DMGlobalToLocalBegin(c%da, run%chain%x, INSERT_VALUES, c%new_local, ierr))
      PetscCall(DMGlobalToLocalEnd(c%da, run%chain%x, INSERT_VALUES, c%new_local, ierr))
      PetscCall(borrow_read(run%start_local, c%local_size, old, ierr))
      PetscCall(borrow_read(c%new_local, c%local_size, new, ierr))
      call c%problem%energy_difference(old, new, change(1), change(2), stat, c%base, &
                                       [run%chain%first_point, run%chain%last_point])
      PetscCall(give_back_read(c%new_local, new, ierr))
      PetscCall(give_back_read(run%start_local, old, ierr))
      PetscCall(PetscObjectGetComm(c%da, comm, ierr))
      ! (a share outside its domain still takes part in the sums, so that no rank waits alone)
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, change, 2, MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
    end associate
  end subroutine energy_change_petsc

  !> The rank's part of the state for a snapshot, tau in the run's own variable
  !> (distributed_system).
  subroutine part(self, state, failure)
    class(relaxed_chain_run), intent(inout) :: self
    type(distributed_part), intent(out) :: state
    type(failure_type), intent(out) :: failure

    call self%sparse_chain_run%part(state, failure)
    if (failure%failed() .or. size(state%tau) == 0 .or. self%run_variable == tau_entropy) return
    call convert_held_taus(self, .true., state%tau, failure)
  end subroutine part

  !> Makes the rank's part `state` (tau in the run's own variable) the current state, in entropy
  !> variables (distributed_system).
  subroutine restore(self, state, failure)
    class(relaxed_chain_run), intent(inout) :: self
    type(distributed_part), intent(in) :: state
    type(failure_type), intent(out) :: failure
    real(real64) :: taus(size(state%tau))

    call self%sparse_chain_run%restore(state, failure)
    if (failure%failed() .or. size(state%tau) == 0 .or. self%run_variable == tau_entropy) return
    call convert_held_taus(self, .false., taus, failure)
    if (failure%failed()) return
    call self%sparse_chain_run%restore(distributed_part(masses=state%masses, springs=state%springs, &
                                                        dimension=state%dimension, first_mass=state%first_mass, &
                                                        first_spring=state%first_spring, &
                                                        spring_count=state%spring_count, positions=state%positions, &
                                                        momenta=state%momenta, gamma=state%gamma, tau=taus, &
                                                        theta=state%theta), failure)
  end subroutine restore

  ! The rank's springs' tau of the state held, from entropy variables to the run's (to_run) or
  ! from the run's to entropy variables.
  subroutine convert_held_taus(self, to_run, taus, failure)
    class(relaxed_chain_run), intent(inout) :: self
    logical, intent(in) :: to_run
    real(real64), intent(out) :: taus(:)
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: z(:)
    integer :: stat
    PetscErrorCode :: ierr

    stat = failure_none
    associate (c => self%chain%context, springs => [self%chain%first_point, &
                                                    min(self%chain%context%problem%layout%springs, self%chain%last_point)])
      call DMGlobalToLocalBegin(c%da, self%chain%x, INSERT_VALUES, c%new_local, ierr)
      if (ierr == 0) call DMGlobalToLocalEnd(c%da, self%chain%x, INSERT_VALUES, c%new_local, ierr)
      if (ierr == 0) call borrow_read(c%new_local, c%local_size, z, ierr)
      if (ierr == 0) then
        if (to_run) then
          call converted_taus(c%problem%layout, c%problem%springs, self%run_springs, z, c%base, springs, taus, stat)
        else
          call converted_taus(c%problem%layout, self%run_springs, c%problem%springs, z, c%base, springs, taus, stat)
        end if
        call give_back_read(c%new_local, z, ierr)
      end if
    end associate
    call fail_on_code(failure, ierr, 'converting the chain''s thermodynamic variable')
    if (.not. failure%failed() .and. stat /= failure_none) &
      call fail(failure, stat, 'a spring''s tau cannot be converted between thermodynamic variables: '// &
                failure_code_name(stat))
  end subroutine convert_held_taus

  !> True: each step's outcome carries the relaxed family's per-step figures (gamma, rejected and
  !> halved attempts, gamma e_S, attempts outside the gamma band), as the dense path declares them.
  pure logical function integrator_diagnostics(self)
    class(relaxed_chain_run), intent(in) :: self

    integrator_diagnostics = .true.
  end function integrator_diagnostics

  !> The dense path's warnings (src/integrator/relaxed_stepper's accuracy_warnings): a run
  !> without a tolerance that halved a step, or whose gamma moved more than
  !> gamma_warning_deviation from 1; '' otherwise.
  function accuracy_warnings(self) result(text)
    class(relaxed_chain_run), intent(in) :: self
    character(len=:), allocatable :: text
    logical :: uncontrolled

    text = ''
    uncontrolled = .not. self%gamma_band < huge(1.0_real64)
    if (uncontrolled .and. self%run_rejections > 0) &
      text = integer_text(self%run_rejections)//' trial steps rejected ('//integer_text(self%run_halvings)//' halved)'
    if (self%max_gamma_deviation > gamma_warning_deviation) then
      if (len(text) > 0) text = text//' and '
      text = text//'|gamma - 1| up to '//fixed_text(self%max_gamma_deviation, 3)//' (over '// &
             fixed_text(gamma_warning_deviation, 1)//')'
    end if
    if (len(text) == 0) return
    if (.not. uncontrolled) then
      text = text//': the steps of '//trim(self%settings%scheme)//' at this tolerance are long for its accuracy (E, '// &
             'the momenta and dS >= 0 hold all the same); a smaller &integrator tolerance is the remedy (docs/integrators.md)'
    else
      text = text//': dt = '//reals_text([self%settings%dt])//' s is too long for '//trim(self%settings%scheme)// &
             '''s accuracy, which nothing controlled (E, the momenta and dS >= 0 hold all the same); '// &
             '&integrator tolerance is the remedy (docs/integrators.md)'
    end if
  end function accuracy_warnings

  !> None: explicit stages (distributed_system).
  function describe_solver(self) result(report)
    class(relaxed_chain_run), intent(in) :: self
    type(solver_report) :: report

    report = no_solver('explicit stages of the chain''s field on a DMDA split over the ranks')
  end function describe_solver

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
    self%vectors_created = .false.
    call fail_on_code(freeing, ierr, 'freeing the chain''s relaxed steps')
    if (.not. failure%failed() .and. freeing%failed()) failure = freeing
    call self%sparse_chain_run%finish(failure)
  end subroutine finish

end module spring_chain_relaxed_run
