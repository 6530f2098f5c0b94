!> The chain's step on the sparse, distributed path (docs/formulation.md section 10, "Sparse and
!> distributed"): the state in a PETSc DMDA of one point per mass and its spring (dof = the
!> layout's point size; 'fixed-fixed' ends add a point for spring N + 1, whose unused slots are
!> identity rows), split over the ranks of a communicator, with the SNES of its steps. This module
!> holds the distributed_chain, makes and frees its PETSc objects and takes its steps; the parts
!> sit beside it: what the callbacks see (spring_chain_dmda_context), the Jacobian's sparse pattern
!> and matrix (spring_chain_dmda_pattern), the residual and Jacobian callbacks
!> (spring_chain_dmda_assembly), the default linear solver (spring_chain_linear_solver), and in
!> submodules the state in and out with the snapshot parts (spring_chain_dmda_state) and the rank
!> sums (spring_chain_dmda_sums). SNES solves each step with the KSP and PC the options choose; the
!> default is full Newton steps with a direct factorisation on one rank (PETSc's LU, RCM order) and
!> on several GMRES on block Jacobi with each rank's block so factored. Newton stops at the step's
!> tolerance or at the rounding floor (an update below 16 eps |z|), whichever comes first. For
!> PETSc TS (spring_chain_ts_run) the same DMDA, matrix and assembly give the chain's field f(z)
!> and df/dz (rule partials_exact: field_at, jacobian_at), without the SNES.
!>
!> Errors: each public procedure returns a failure_type; its PETSc calls sit in a private twin
!> with PETSc's own ierr. The helpers of a TS's callbacks and step (field_at, jacobian_at,
!> hold_old_state, set_default_linear_solver) keep PETSc's ierr.
module spring_chain_dmda
#include <petsc/finclude/petscsnes.h>
#include <petsc/finclude/petscdmda.h>
  use petscsnes
  use petscdmda
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_type, failure_none, fail_on_code
  use vector_arrays, only: borrow, give_back
  use spring_chain_step, only: chain_step_problem
  use spring_chain_partials, only: partials_exact
  use distributed_model, only: distributed_figures, distributed_step
  use spring_chain_dmda_context, only: chain_context, slice_points
  use spring_chain_dmda_pattern, only: hold_pattern, create_jacobian_matrix
  use spring_chain_dmda_assembly, only: field_into, jacobian_into, chain_residual, chain_jacobian, converged_or_rounding
  use spring_chain_linear_solver, only: set_default_linear_solver, set_rounding_tolerance, settings_in_code
  implicit none
  private
  public :: distributed_chain, set_default_linear_solver, stencil_width

  !> The DMDA's stencil width in points (a spring's field reads the points two away): PETSc needs
  !> as many points on every rank, so a chain split over P ranks needs at least 2 P points.
  integer, parameter :: stencil_width = 2

  !> A chain on a DMDA with its SNES. Do not copy it after `create`: PETSc holds the address of
  !> `context`.
  type :: distributed_chain
    type(chain_context) :: context
    SNES :: snes
    Vec :: x                       !! the state (global vector)
    Vec :: r
    Vec :: work                    !! a state given as rows (field_of, set_rows)
    Mat :: jacobian
    integer :: first_point = 1     !! the rank's points, first .. last (1-based)
    integer :: last_point = 0
    logical :: created = .false.
    logical :: snes_created = .false.
    !> the linear solves without their rounding floor (set_rounding_tolerance): a step solved
    !> again after it broke a balance (src/model/distributed_model's tighten_linear_solves)
    logical :: tight = .false.
  contains
    procedure :: create
    procedure :: create_snes
    procedure :: field_at
    procedure :: jacobian_at
    procedure :: hold_old_state
    procedure :: set_state
    procedure :: owned_state
    procedure :: set_rows
    procedure :: field_of
    procedure :: step
    procedure :: linear_floor_in_use
    procedure :: sums
    procedure :: state_part
    procedure :: set_part
    procedure :: destroy
    procedure :: figures
  end type distributed_chain

  interface
    !> Sets the state from z (every unknown of the layout; each rank copies its own rows; the
    !> unused slots of a 'fixed-fixed' chain's last point are 0). (spring_chain_dmda_state)
    module subroutine set_state(self, z, failure)
      class(distributed_chain), intent(inout) :: self
      real(real64), intent(in) :: z(:)
      type(failure_type), intent(out) :: failure
    end subroutine set_state

    !> The rank's rows of the state: unknowns first_row .. last_row (a copy).
    module subroutine owned_state(self, z, first_row, failure)
      class(distributed_chain), intent(inout) :: self
      real(real64), allocatable, intent(out) :: z(:)
      integer, intent(out) :: first_row
      type(failure_type), intent(out) :: failure
    end subroutine owned_state

    !> Makes the rank's rows z the state held and z_old the old state of its step. Collective.
    module subroutine set_rows(self, z, z_old, failure)
      class(distributed_chain), intent(inout) :: self
      real(real64), intent(in) :: z(:), z_old(:)
      type(failure_type), intent(out) :: failure
    end subroutine set_rows

    !> The rank's part of the state as a snapshot holds it (spring_chain_dmda_state).
    module subroutine state_part(self, positions, momenta, gamma, tau, theta, failure)
      class(distributed_chain), intent(inout) :: self
      real(real64), allocatable, intent(out) :: positions(:, :), momenta(:, :), gamma(:), tau(:), theta(:)
      type(failure_type), intent(out) :: failure
    end subroutine state_part

    !> Sets the rank's rows of the state from its part as state_part gives it.
    module subroutine set_part(self, positions, momenta, gamma, tau, failure)
      class(distributed_chain), intent(inout) :: self
      real(real64), intent(in) :: positions(:, :), momenta(:, :), gamma(:), tau(:)
      type(failure_type), intent(out) :: failure
    end subroutine set_part

    !> The balances of the last step, summed over the ranks (spring_chain_dmda_sums).
    module subroutine sums(self, energy, entropy, delta_energy, delta_entropy, failure)
      class(distributed_chain), intent(inout) :: self
      real(real64), intent(out) :: energy, entropy, delta_energy, delta_entropy
      type(failure_type), intent(out) :: failure
    end subroutine sums

    !> The figures of the state held and of the last step to it, summed over the ranks.
    module subroutine figures(self, values, failure)
      class(distributed_chain), intent(inout) :: self
      type(distributed_figures), intent(out) :: values
      type(failure_type), intent(out) :: failure
    end subroutine figures
  end interface

contains

  !> Makes the DMDA, the vectors and the Jacobian's matrix for `problem` (its z_old is not used)
  !> on `comm` (PETSc's MPI communicator); a step needs create_snes, or a TS of the caller's that
  !> calls field_at and jacobian_at (the field, rule partials_exact).
  subroutine create(self, problem, comm, failure)
    class(distributed_chain), intent(inout), target :: self
    type(chain_step_problem), intent(in) :: problem
    MPI_Comm, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call create_petsc(self, problem, comm, ierr)
    call fail_on_code(failure, ierr, 'setting up the chain''s DMDA')
  end subroutine create

  subroutine create_petsc(self, problem, comm, ierr)
    class(distributed_chain), intent(inout), target :: self
    type(chain_step_problem), intent(in) :: problem
    MPI_Comm, intent(in) :: comm
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: points, dof, width, xs, ys, zs, xm, ym, zm, gxs, gxm
    PetscBool :: check_pattern

    self%context%problem = problem
    points = problem%layout%points()
    dof = problem%layout%point_size()
    width = stencil_width
    PetscCall(DMDACreate1d(comm, DM_BOUNDARY_NONE, points, dof, width, PETSC_NULL_INTEGER, self%context%da, ierr))
    PetscCall(DMSetUp(self%context%da, ierr))
    PetscCall(DMDAGetCorners(self%context%da, xs, ys, zs, xm, ym, zm, ierr))
    PetscCall(DMDAGetGhostCorners(self%context%da, gxs, ys, zs, gxm, ym, zm, ierr))
    self%first_point = int(xs) + 1
    self%last_point = int(xs + xm)
    self%context%first_row = int(xs*dof) + 1
    self%context%last_row = int((xs + xm)*dof)
    self%context%base = int(gxs*dof)
    self%context%local_size = int(gxm*dof)
    self%context%total = int(points*dof)
    call hold_pattern(self%context, int(dof))
    associate (slice => min(self%context%last_row - self%context%first_row + 1, slice_points*int(dof)), &
               half => problem%band_half_width())
      allocate (self%context%rows(slice), self%context%band(2*half + 1, slice))
      allocate (self%context%columns(size(self%context%pattern(1, :, :))), self%context%values(size(self%context%pattern(1, :, :))))
    end associate
    PetscCall(DMCreateGlobalVector(self%context%da, self%x, ierr))
    PetscCall(VecDuplicate(self%x, self%r, ierr))
    PetscCall(VecDuplicate(self%x, self%work, ierr))
    PetscCall(DMCreateLocalVector(self%context%da, self%context%old_local, ierr))
    PetscCall(VecDuplicate(self%context%old_local, self%context%new_local, ierr))
    PetscCall(create_jacobian_matrix(self%context, comm, self%jacobian, ierr))
    PetscCall(PetscOptionsHasName(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, '-chain_check_pattern', check_pattern, ierr))
    self%context%check_pattern = check_pattern
    self%created = .true.
  end subroutine create_petsc

  !> Makes the SNES of the steps (after `create`): Newton stops at |R| <= newton_tol or at the
  !> rounding floor, within max_iterations.
  subroutine create_snes(self, newton_tol, max_iterations, failure)
    class(distributed_chain), intent(inout), target :: self
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call create_snes_petsc(self, newton_tol, max_iterations, ierr)
    call fail_on_code(failure, ierr, 'setting up the chain''s SNES')
  end subroutine create_snes

  subroutine create_snes_petsc(self, newton_tol, max_iterations, ierr)
    class(distributed_chain), intent(inout), target :: self
    real(real64), intent(in) :: newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: max_evaluations, iterations
    KSP :: ksp
    SNESLineSearch :: line_search
    MPI_Comm :: comm

    PetscCall(PetscObjectGetComm(self%context%da, comm, ierr))
    PetscCall(SNESCreate(comm, self%snes, ierr))
    self%snes_created = .true.
    PetscCall(SNESSetDM(self%snes, self%context%da, ierr))
    PetscCall(SNESSetFunction(self%snes, self%r, chain_residual, self%context, ierr))
    PetscCall(SNESSetJacobian(self%snes, self%jacobian, self%jacobian, chain_jacobian, self%context, ierr))
    max_evaluations = 10000
    iterations = max_iterations
    PetscCall(SNESSetTolerances(self%snes, newton_tol, 0.0_real64, 0.0_real64, iterations, max_evaluations, ierr))
    self%context%newton_tol = newton_tol
    PetscCall(SNESSetConvergenceTest(self%snes, converged_or_rounding, self%context, PETSC_NULL_FUNCTION, ierr))
    ! Full Newton steps, as on the dense path: backtracking on the 2-norm of rows in different
    ! units stalls at the rounding floor (-snes_linesearch_type bt chooses it).
    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    PetscCall(SNESLineSearchSetType(line_search, SNESLINESEARCHBASIC, ierr))
    PetscCall(SNESGetKSP(self%snes, ksp, ierr))
    PetscCall(set_default_linear_solver(ksp, comm, ierr))
    PetscCall(SNESSetFromOptions(self%snes, ierr))
  end subroutine create_snes_petsc

  !> The rank's rows of the chain's continuous field f(z) (the exact partials: docs/formulation.md
  !> section 10) at the state whose rows are z; stat a domain code if a spring of z is outside
  !> its domain. The step's own rule is kept. Collective.
  subroutine field_of(self, z, f, stat, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: values(:)
    integer :: ierr, rule

    stat = failure_none
    call borrow(self%work, size(z), values, ierr)
    if (ierr == 0) then
      values = z
      call give_back(self%work, values, ierr)
    end if
    rule = self%context%problem%rule
    self%context%problem%rule = partials_exact
    if (ierr == 0) call field_into(self%context, self%work, f, stat, ierr)
    self%context%problem%rule = rule
    call fail_on_code(failure, ierr, 'evaluating the chain''s field')
  end subroutine field_of

  !> One step of length h from the state held: Newton from the old state. On failure to
  !> converge the old state is kept (outcome%converged false).
  subroutine step(self, h, outcome, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: h
    type(distributed_step), intent(out) :: outcome
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    call step_petsc(self, h, outcome, ierr)
    call fail_on_code(failure, ierr, 'solving the chain''s step with SNES')
  end subroutine step

  !> Whether the linear solves have the rounding floor of set_rounding_tolerance (several
  !> ranks, -ksp_atol not given), which `tight` lifts (src/model/distributed_model's
  !> tighten_linear_solves).
  subroutine linear_floor_in_use(self, in_use, failure)
    class(distributed_chain), intent(in) :: self
    logical, intent(out) :: in_use
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: ordering
    PetscErrorCode :: ierr
    KSP :: ksp

    in_use = .false.
    call SNESGetKSP(self%snes, ksp, ierr)
    if (ierr == 0) call settings_in_code(ksp, ordering, in_use, ierr)
    call fail_on_code(failure, ierr, 'reading the chain''s linear solver settings')
  end subroutine linear_floor_in_use

  subroutine step_petsc(self, h, outcome, ierr)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: h
    type(distributed_step), intent(out) :: outcome
    PetscErrorCode, intent(out) :: ierr
    PetscErrorCode :: solve_ierr
    PetscInt :: iterations
    SNESConvergedReason :: reason
    PetscReal :: old_norm, residual_norm
    KSP :: ksp

    self%context%problem%dt = h
    self%context%problem%fraction = 1.0_real64
    PetscCall(self%hold_old_state(ierr))
    PetscCall(VecNorm(self%x, NORM_2, old_norm, ierr))
    self%context%update_floor = 16.0_real64*epsilon(1.0_real64)*old_norm
    PetscCall(SNESGetKSP(self%snes, ksp, ierr))
    ! `tight` (set only where the floor is in use): GMRES to its relative tolerance alone, as
    ! -ksp_atol 1e-30 would.
    PetscCall(set_rounding_tolerance(ksp, merge(0.0_real64, epsilon(1.0_real64)*old_norm, self%tight), ierr))
    ! A failed library call inside the solve leaves x at an iterate: the old state is put back
    ! before the error goes up (the run ends there, keeping the snapshots it wrote).
    call SNESSolve(self%snes, PETSC_NULL_VEC, self%x, solve_ierr)
    if (solve_ierr /= 0) then
      call restore_old_state(self, ierr)
      ierr = solve_ierr
      return
    end if
    PetscCall(SNESGetConvergedReason(self%snes, reason, ierr))
    PetscCall(SNESGetIterationNumber(self%snes, iterations, ierr))
    PetscCall(SNESGetFunctionNorm(self%snes, residual_norm, ierr))
    outcome%reason = reason
    outcome%iterations = int(iterations)
    outcome%residual_norm = residual_norm
    outcome%converged = reason > 0
    if (.not. outcome%converged) then
      PetscCall(restore_old_state(self, ierr))
    end if
  end subroutine step_petsc

  !> x becomes the state held by hold_old_state again (the rank's own points of its ghosted
  !> copy: no communication).
  subroutine restore_old_state(self, ierr)
    class(distributed_chain), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    PetscCall(DMLocalToGlobalBegin(self%context%da, self%context%old_local, INSERT_VALUES, self%x, ierr))
    PetscCall(DMLocalToGlobalEnd(self%context%da, self%context%old_local, INSERT_VALUES, self%x, ierr))
  end subroutine restore_old_state

  !> The state held becomes the old state of the step to come (its ghosted part: the step's
  !> figures, and EME's residual, read it).
  subroutine hold_old_state(self, ierr)
    class(distributed_chain), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    PetscCall(DMGlobalToLocalBegin(self%context%da, self%x, INSERT_VALUES, self%context%old_local, ierr))
    PetscCall(DMGlobalToLocalEnd(self%context%da, self%x, INSERT_VALUES, self%context%old_local, ierr))
  end subroutine hold_old_state

  !> Frees the PETSc objects (the SNES too, if made).
  subroutine destroy(self, failure)
    class(distributed_chain), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr

    ierr = 0
    if (self%created) call destroy_petsc(self, ierr)
    self%created = .false.
    call fail_on_code(failure, ierr, 'freeing the chain''s DMDA and SNES')
  end subroutine destroy

  subroutine destroy_petsc(self, ierr)
    class(distributed_chain), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    if (self%snes_created) then
      PetscCall(SNESDestroy(self%snes, ierr))
    end if
    self%snes_created = .false.
    PetscCall(MatDestroy(self%jacobian, ierr))
    PetscCall(VecDestroy(self%x, ierr))
    PetscCall(VecDestroy(self%r, ierr))
    PetscCall(VecDestroy(self%work, ierr))
    PetscCall(VecDestroy(self%context%old_local, ierr))
    PetscCall(VecDestroy(self%context%new_local, ierr))
    PetscCall(DMDestroy(self%context%da, ierr))
  end subroutine destroy_petsc

  !> The rank's rows of the field f(x) (the problem's rule partials_exact: the chain's GENERIC
  !> field, docs/formulation.md section 10) into the vector f, as PETSc TS's right-hand side
  !> wants it; stat: a domain code if a spring at x is outside its domain (f is then partial).
  subroutine field_at(self, x, f, stat, ierr)
    class(distributed_chain), intent(inout) :: self
    Vec, intent(in) :: x
    Vec, intent(in) :: f
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: rows(:)

    stat = failure_none
    PetscCall(borrow(f, self%context%last_row - self%context%first_row + 1, rows, ierr))
    PetscCall(field_into(self%context, x, rows, stat, ierr))
    PetscCall(give_back(f, rows, ierr))
  end subroutine field_at

  !> The rank's rows of df/dz at x (rule partials_exact: the field's exact Jacobian) into
  !> `matrix` (the chain's Jacobian matrix, or one of its pattern), assembled, as PETSc TS's
  !> right-hand side Jacobian wants it; stat as field_at's.
  subroutine jacobian_at(self, x, matrix, stat, ierr)
    class(distributed_chain), intent(inout) :: self
    Vec, intent(in) :: x
    Mat, intent(in) :: matrix
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr

    stat = failure_none
    PetscCall(jacobian_into(self%context, x, matrix, 1.0_real64, 0.0_real64, stat, ierr))
  end subroutine jacobian_at

end module spring_chain_dmda
