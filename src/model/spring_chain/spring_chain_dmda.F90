!> The chain's step on the sparse, distributed path (docs/formulation.md section 10, "Sparse and
!> distributed"): the state in a PETSc DMDA of one point per mass and its spring (dof = the
!> layout's point size; 'fixed-fixed' ends add a point for spring N + 1, whose unused slots are
!> identity rows), split over the ranks of a communicator. Each rank assembles its own rows of the
!> residual R = (z - z_old)/h - f and of its Jacobian from the blocks that touch them
!> (chain_step_problem's field_rows, over the ghosted local vector of stencil width 2: a link
!> couples points a - 1 .. a + 1), in slices of slice_points points so that the springs' partials
!> and the band stay in cache; the residual computes no derivative. The Jacobian holds the
!> blocks' structural nonzeros only (coupling_pattern: 26 of the stencil's 80 entries per point
!> in 1D, 80 of 320 in 3D), preallocated exactly, so that neither the assembly nor the
!> factorisation handles the stencil's zeros. SNES solves each step
!> with the KSP and PC the options choose; the default is full Newton steps with a direct
!> factorisation on one rank (PETSc's LU, RCM order) and on several GMRES on block Jacobi with each
!> rank's block so factored. Newton stops at the step's tolerance or at the rounding floor
!> (an update below 16 eps |z|), whichever comes first. For PETSc TS (spring_chain_ts_run) the
!> same DMDA, matrix and assembly give the chain's field f(z) and df/dz (rule partials_exact:
!> field_at, jacobian_at), without the SNES.
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
  use failures, only: failure_type, failure_none, failure_input, fail_on_code, fail, domain_overflow
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use spring_chain_step, only: chain_step_problem
  use spring_chain_partials, only: partials_exact
  use spring_chain_layout, only: chain_layout
  use spring_chain_balance, only: spring_values
  use spring_chain_figures, only: share_figures
  use distributed_model, only: distributed_figures, distributed_step
  implicit none
  private
  public :: distributed_chain, set_default_linear_solver

  !> The points of a slice the callbacks evaluate at once (a few hundred kB of partials and band).
  integer, parameter :: slice_points = 128

  !> What the callbacks see (PETSc holds its address): the step's problem and the rank's part.
  type :: chain_context
    type(chain_step_problem) :: problem
    DM :: da
    Vec :: old_local               !! z_old on the rank's ghosted points
    Vec :: new_local               !! the iterate on the rank's ghosted points
    integer :: base = 0            !! the unknown before the ghosted part's first
    integer :: first_row = 1       !! the rank's rows (1-based unknowns), first .. last
    integer :: last_row = 0
    integer :: local_size = 0      !! the ghosted part's unknowns
    integer :: total = 0           !! every rank's unknowns (the DMDA's: point size x points)
    !> the step's tolerance on |R| (the input's newton_tol): options cannot loosen it, as on the
    !> dense path (a looser -snes_atol would accept the old state as the step's root)
    real(real64) :: newton_tol = 0.0_real64
    real(real64) :: update_floor = 0.0_real64   !! 16 eps |z_old|: updates below it are rounding
    !> pattern(v, w, o): unknown v of a point depends on unknown w of the point o further
    !> (coupling_pattern), v and w numbered as in a point holding a mass: (x, p, [gamma], [tau]).
    logical, allocatable :: pattern(:, :, :)
    !> What each slot of the last point holds in that numbering, 0 for an unused slot: a
    !> 'fixed-fixed' chain's point N + 1 holds spring N + 1's [gamma,] [tau] in its first slots.
    integer, allocatable :: last_point_slots(:)
    !> The pattern of a row of slot v at an interior point (two points from the first and three
    !> from the last): its interior_counts(v) columns relative to the point's first unknown,
    !> where they sit in the row's band (field_rows' storage) and which of them is the diagonal.
    integer, allocatable :: interior_columns(:, :), interior_counts(:), interior_band(:, :), interior_diagonal(:)
    !> -chain_check_pattern: the Jacobian callback fails when a block's derivative falls outside
    !> coupling_pattern (the pattern's test; it costs a pass over the band).
    logical :: check_pattern = .false.
    !> The Jacobian callback's buffers, sized once: a slice's rows of f and their band of df/dz,
    !> a row's columns and values.
    real(real64), allocatable :: rows(:), band(:, :), values(:)
    PetscInt, allocatable :: columns(:)
  end type chain_context

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
    procedure :: sums
    procedure :: state_part
    procedure :: set_part
    procedure :: destroy
    procedure :: figures
  end type distributed_chain

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
    integer :: k, o, w

    self%context%problem = problem
    points = problem%layout%points()
    dof = problem%layout%point_size()
    width = 2
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
    allocate (self%context%pattern(dof, dof, -2:2))      ! the bounds the assignment keeps
    self%context%pattern = coupling_pattern(problem%layout)
    self%context%last_point_slots = [(k, k=1, int(dof))]
    if (problem%layout%fixed_fixed) then
      self%context%last_point_slots = 0
      self%context%last_point_slots(1:problem%layout%invariant_count - 1) = [(k, k=2*problem%layout%dimension + 1, int(dof))]
    end if
    allocate (self%context%interior_columns(size(self%context%pattern(1, :, :)), dof), self%context%interior_counts(dof))
    allocate (self%context%interior_band, mold=self%context%interior_columns)
    allocate (self%context%interior_diagonal(dof))
    self%context%interior_counts = 0
    do k = 1, int(dof)
      do o = -2, 2
        do w = 1, int(dof)
          if (.not. self%context%pattern(k, w, o)) cycle
          self%context%interior_counts(k) = self%context%interior_counts(k) + 1
          associate (j => self%context%interior_counts(k))
            self%context%interior_columns(j, k) = o*int(dof) + w - 1
            ! band(c - g + half + 1, .) for row g = point start + k, column c = point start + that - 1 (1-based)
            self%context%interior_band(j, k) = o*int(dof) + w - k + problem%band_half_width() + 1
            if (o == 0 .and. w == k) self%context%interior_diagonal(k) = j
          end associate
        end do
      end do
    end do
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

  !> The chain's default linear solver on `comm` for `ksp` (a step's Newton iterations, or a
  !> TS's): on one rank a direct factorisation (PETSc's LU, RCM order), on several GMRES on
  !> block Jacobi with each rank's block so factored; the options may choose others.
  subroutine set_default_linear_solver(ksp, comm, ierr)
    KSP, intent(in) :: ksp
    MPI_Comm, intent(in) :: comm
    PetscErrorCode, intent(out) :: ierr
    PC :: pc
    PetscMPIInt :: ranks

    PetscCall(KSPGetPC(ksp, pc, ierr))
    PetscCall(MPI_Comm_size(comm, ranks, ierr))
    if (ranks == 1) then
      PetscCall(KSPSetType(ksp, KSPPREONLY, ierr))
      PetscCall(PCSetType(pc, PCLU, ierr))
      ! Reverse Cuthill-McKee keeps the chain's factors banded; PETSc's default nested dissection
      ! cost more to order (0.16 s at 4e4 unknowns) and factored 1.4 times slower.
      PetscCall(PCFactorSetMatOrderingType(pc, MATORDERINGRCM, ierr))
    else
      ! Each rank factors its own diagonal block (block Jacobi, LU in RCM order: the sub-PC's
      ! options unless given) and GMRES mends the couplings across
      ! the cuts, a few columns per cut: 6 to 8 iterations a Newton step at 4e4 unknowns on 2
      ! ranks. MUMPS on 2 ranks executed 2.1 to 2.4 times one rank's instructions per rank
      ! (its analysis, its factorisation's load messages); this 0.63 (callgrind, 2 steps).
      ! The solve is tight (1e-12 relative), so Newton takes the direct solver's iterates.
      PetscCall(KSPSetType(ksp, KSPGMRES, ierr))
      PetscCall(KSPSetTolerances(ksp, 1.0e-12_real64, 0.0_real64, PETSC_DEFAULT_REAL, PETSC_DEFAULT_INTEGER, ierr))
      PetscCall(PCSetType(pc, PCBJACOBI, ierr))
      PetscCall(default_option('-sub_pc_type', 'lu', ierr))
      PetscCall(default_option('-sub_pc_factor_mat_ordering_type', 'rcm', ierr))
    end if
  end subroutine set_default_linear_solver

  ! Sets PETSc option `name` to `value` unless the options give it.
  subroutine default_option(name, value, ierr)
    character(len=*), intent(in) :: name, value
    PetscErrorCode, intent(out) :: ierr
    PetscBool :: given

    PetscCall(PetscOptionsHasName(PETSC_NULL_OPTIONS, PETSC_NULL_CHARACTER, name, given, ierr))
    if (.not. given) then
      PetscCall(PetscOptionsSetValue(PETSC_NULL_OPTIONS, name, value, ierr))
    end if
  end subroutine default_option

  !> Sets the state from z (every unknown of the layout; each rank copies its own rows; the
  !> unused slots of a 'fixed-fixed' chain's last point are 0).
  subroutine set_state(self, z, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: values(:)
    integer :: ierr, last

    call borrow(self%x, self%context%last_row - self%context%first_row + 1, values, ierr)
    if (ierr == 0) then
      values = 0.0_real64
      last = min(self%context%last_row, size(z))
      values(1:last - self%context%first_row + 1) = z(self%context%first_row:last)
      call give_back(self%x, values, ierr)
    end if
    ! The old state of a step not yet taken is the state itself (sums before the first step).
    if (ierr == 0) call DMGlobalToLocalBegin(self%context%da, self%x, INSERT_VALUES, self%context%old_local, ierr)
    if (ierr == 0) call DMGlobalToLocalEnd(self%context%da, self%x, INSERT_VALUES, self%context%old_local, ierr)
    call fail_on_code(failure, ierr, 'setting the chain''s state')
  end subroutine set_state

  !> The rank's rows of the state: unknowns first_row .. last_row (a copy).
  subroutine owned_state(self, z, first_row, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), allocatable, intent(out) :: z(:)
    integer, intent(out) :: first_row
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: values(:)
    integer :: ierr

    first_row = self%context%first_row
    call borrow_read(self%x, self%context%last_row - first_row + 1, values, ierr)
    if (ierr == 0) then
      z = values
      call give_back_read(self%x, values, ierr)
    end if
    call fail_on_code(failure, ierr, 'reading the chain''s state')
  end subroutine owned_state

  !> Makes the rank's rows z (unknowns first_row .. last_row) the state held and z_old the old
  !> state of its step (the figures' differences start there). Collective.
  subroutine set_rows(self, z, z_old, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: z(:), z_old(:)
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: values(:)
    integer :: ierr

    call borrow(self%work, size(z_old), values, ierr)
    if (ierr == 0) then
      values = z_old
      call give_back(self%work, values, ierr)
    end if
    if (ierr == 0) call DMGlobalToLocalBegin(self%context%da, self%work, INSERT_VALUES, self%context%old_local, ierr)
    if (ierr == 0) call DMGlobalToLocalEnd(self%context%da, self%work, INSERT_VALUES, self%context%old_local, ierr)
    if (ierr == 0) call borrow(self%x, size(z), values, ierr)
    if (ierr == 0) then
      values = z
      call give_back(self%x, values, ierr)
    end if
    call fail_on_code(failure, ierr, 'setting the chain''s state from its rows')
  end subroutine set_rows

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

  subroutine step_petsc(self, h, outcome, ierr)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: h
    type(distributed_step), intent(out) :: outcome
    PetscErrorCode, intent(out) :: ierr
    Vec :: old
    PetscInt :: iterations
    SNESConvergedReason :: reason
    PetscReal :: old_norm, residual_norm

    self%context%problem%dt = h
    self%context%problem%fraction = 1.0_real64
    PetscCall(self%hold_old_state(ierr))
    PetscCall(VecNorm(self%x, NORM_2, old_norm, ierr))
    self%context%update_floor = 16.0_real64*epsilon(1.0_real64)*old_norm
    PetscCall(VecDuplicate(self%x, old, ierr))
    PetscCall(VecCopy(self%x, old, ierr))
    PetscCall(SNESSolve(self%snes, PETSC_NULL_VEC, self%x, ierr))
    PetscCall(SNESGetConvergedReason(self%snes, reason, ierr))
    PetscCall(SNESGetIterationNumber(self%snes, iterations, ierr))
    PetscCall(SNESGetFunctionNorm(self%snes, residual_norm, ierr))
    outcome%reason = reason
    outcome%iterations = int(iterations)
    outcome%residual_norm = residual_norm
    outcome%converged = reason > 0
    if (.not. outcome%converged) then
      PetscCall(VecCopy(old, self%x, ierr))
    end if
    PetscCall(VecDestroy(old, ierr))
  end subroutine step_petsc

  !> The state held becomes the old state of the step to come (its ghosted part: the step's
  !> figures, and EME's residual, read it).
  subroutine hold_old_state(self, ierr)
    class(distributed_chain), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr

    PetscCall(DMGlobalToLocalBegin(self%context%da, self%x, INSERT_VALUES, self%context%old_local, ierr))
    PetscCall(DMGlobalToLocalEnd(self%context%da, self%x, INSERT_VALUES, self%context%old_local, ierr))
  end subroutine hold_old_state

  !> The balances of the last step, summed over the ranks (each rank sums its points' masses and
  !> springs; MPI_Allreduce adds them): E and S of the state held, and E - E_old and S - S_old as
  !> sums of the parts' differences (no cancellation of the large E).
  subroutine sums(self, energy, entropy, delta_energy, delta_entropy, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(out) :: energy, entropy, delta_energy, delta_entropy
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr
    integer :: stat
    real(real64) :: total(4)

    call sums_petsc(self, total, stat, ierr)
    call fail_on_code(failure, ierr, 'summing the chain''s energy and entropy')
    if (.not. failure%failed() .and. stat /= failure_none) &
      call fail(failure, domain_overflow, 'a spring is outside its domain while summing E and S')
    energy = total(1)
    entropy = total(2)
    delta_energy = total(3)
    delta_entropy = total(4)
  end subroutine sums

  subroutine sums_petsc(self, total, stat, ierr)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(out) :: total(4)
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    real(real64) :: local(4)
    integer :: stat_values, stat_differences, points(2)
    MPI_Comm :: comm

    stat = failure_none
    total = 0.0_real64
    points = [self%first_point, self%last_point]
    associate (c => self%context)
      PetscCall(DMGlobalToLocalBegin(c%da, self%x, INSERT_VALUES, c%new_local, ierr))
      PetscCall(DMGlobalToLocalEnd(c%da, self%x, INSERT_VALUES, c%new_local, ierr))
      PetscCall(borrow_read(c%old_local, c%local_size, old, ierr))
      PetscCall(borrow_read(c%new_local, c%local_size, new, ierr))
      call c%problem%energy_entropy(new, local(1), local(2), stat_values, c%base, points)
      call c%problem%energy_difference(old, new, local(3), local(4), stat_differences, c%base, points)
      PetscCall(give_back_read(c%old_local, old, ierr))
      PetscCall(give_back_read(c%new_local, new, ierr))
      stat = max(stat_values, stat_differences)
      PetscCall(PetscObjectGetComm(c%da, comm, ierr))
      PetscCallMPI(MPI_Allreduce(local, total, 4, MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
    end associate
  end subroutine sums_petsc

  !> The rank's part of the state as a snapshot holds it: its masses' positions and momenta
  !> (dimension x masses), its springs' gamma (none without a viscous branch) and tau, and their
  !> temperatures [K] (spring a lives at point a; its temperature needs mass a - 1, a ghost).
  subroutine state_part(self, positions, momenta, gamma, tau, theta, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), allocatable, intent(out) :: positions(:, :), momenta(:, :), gamma(:), tau(:), theta(:)
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: z(:)
    real(real64) :: f(2)
    integer :: ierr, i, a, d, first_mass, last_mass, last_spring, stat

    associate (c => self%context, layout => self%context%problem%layout)
      d = layout%dimension
      first_mass = self%first_point
      last_mass = min(layout%masses, self%last_point)
      last_spring = min(layout%springs, self%last_point)
      allocate (positions(d, max(0, last_mass - first_mass + 1)), momenta(d, max(0, last_mass - first_mass + 1)))
      allocate (gamma(0), tau(0), theta(0))
      if (layout%invariant_count == 3) gamma = [(0.0_real64, a=self%first_point, last_spring)]
      if (layout%invariant_count >= 2) then
        tau = [(0.0_real64, a=self%first_point, last_spring)]
        theta = tau
      end if
      ierr = 0
      call DMGlobalToLocalBegin(c%da, self%x, INSERT_VALUES, c%new_local, ierr)
      if (ierr == 0) call DMGlobalToLocalEnd(c%da, self%x, INSERT_VALUES, c%new_local, ierr)
      if (ierr == 0) call borrow_read(c%new_local, c%local_size, z, ierr)
      if (ierr /= 0) then
        call fail_on_code(failure, ierr, 'reading the chain''s state for a snapshot')
        return
      end if
      do i = first_mass, last_mass
        associate (slots => layout%mass_indices(i) - c%base)
          positions(:, i - first_mass + 1) = z(slots(1:d))
          momenta(:, i - first_mass + 1) = z(slots(d + 1:))
        end associate
      end do
      stat = failure_none
      do a = self%first_point, last_spring
        if (layout%invariant_count == 3) gamma(a - self%first_point + 1) = z(layout%gamma_index(a) - c%base)
        if (layout%invariant_count == 1) cycle
        tau(a - self%first_point + 1) = z(layout%tau_index(a) - c%base)
        call spring_values(c%problem%springs(a), d, layout%gather_spring(z, a, c%base), f, theta(a - self%first_point + 1), &
                           stat)
        if (stat /= failure_none) exit
      end do
      call give_back_read(c%new_local, z, ierr)
    end associate
    call fail_on_code(failure, ierr, 'reading the chain''s state for a snapshot')
    if (.not. failure%failed() .and. stat /= failure_none) &
      call fail(failure, domain_overflow, 'a spring is outside its domain while writing a snapshot')
  end subroutine state_part

  !> Sets the rank's rows of the state from its part as state_part gives it (positions and
  !> momenta (dimension, its masses), gamma and tau per spring of its points); the old state of the
  !> next step is this state, as after set_state.
  subroutine set_part(self, positions, momenta, gamma, tau, failure)
    class(distributed_chain), intent(inout) :: self
    real(real64), intent(in) :: positions(:, :), momenta(:, :), gamma(:), tau(:)
    type(failure_type), intent(out) :: failure
    real(real64), pointer :: values(:)
    integer :: ierr, i, a, d, first_mass, last_mass, last_spring

    associate (c => self%context, layout => self%context%problem%layout)
      d = layout%dimension
      first_mass = self%first_point
      last_mass = min(layout%masses, self%last_point)
      last_spring = min(layout%springs, self%last_point)
      if (size(positions, 2) /= max(0, last_mass - first_mass + 1) .or. size(momenta, 2) /= size(positions, 2) .or. &
          (layout%invariant_count == 3 .and. size(gamma) /= max(0, last_spring - first_mass + 1)) .or. &
          (layout%invariant_count >= 2 .and. size(tau) /= max(0, last_spring - first_mass + 1))) then
        call fail(failure, failure_input, 'the part of the state given does not fit this rank''s part of the chain')
        return
      end if
      call borrow(self%x, c%last_row - c%first_row + 1, values, ierr)
      if (ierr == 0) then
        do i = first_mass, last_mass
          associate (slots => layout%mass_indices(i) - c%first_row + 1)
            values(slots(1:d)) = positions(:, i - first_mass + 1)
            values(slots(d + 1:)) = momenta(:, i - first_mass + 1)
          end associate
        end do
        do a = first_mass, last_spring
          if (layout%invariant_count == 3) values(layout%gamma_index(a) - c%first_row + 1) = gamma(a - first_mass + 1)
          if (layout%invariant_count >= 2) values(layout%tau_index(a) - c%first_row + 1) = tau(a - first_mass + 1)
        end do
        call give_back(self%x, values, ierr)
      end if
      if (ierr == 0) call DMGlobalToLocalBegin(c%da, self%x, INSERT_VALUES, c%old_local, ierr)
      if (ierr == 0) call DMGlobalToLocalEnd(c%da, self%x, INSERT_VALUES, c%old_local, ierr)
    end associate
    call fail_on_code(failure, ierr, 'setting the chain''s state from a snapshot')
  end subroutine set_part

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

  ! The rank's rows of f at the iterate x into rows(:), slice by slice, without derivatives: the
  ! step's f(z_old, x) (z_old in old_local), or for the field (partials_exact) f(x) alone.
  subroutine field_into(context, x, rows, stat, ierr)
    type(chain_context), intent(inout) :: context
    Vec, intent(in) :: x
    real(real64), intent(out) :: rows(:)
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    integer :: slice_first, slice_last

    PetscCall(DMGlobalToLocalBegin(context%da, x, INSERT_VALUES, context%new_local, ierr))
    PetscCall(DMGlobalToLocalEnd(context%da, x, INSERT_VALUES, context%new_local, ierr))
    PetscCall(borrow_read(context%new_local, context%local_size, new, ierr))
    old => new
    if (context%problem%rule /= partials_exact) then
      PetscCall(borrow_read(context%old_local, context%local_size, old, ierr))
    end if
    stat = failure_none
    do slice_first = context%first_row, context%last_row, size(context%rows)
      slice_last = min(context%last_row, slice_first + size(context%rows) - 1)
      call context%problem%field_rows(old, new, context%base, slice_first, slice_last, &
                                      rows(slice_first - context%first_row + 1:slice_last - context%first_row + 1), stat=stat)
      if (stat /= failure_none) exit
    end do
    if (context%problem%rule /= partials_exact) then
      PetscCall(give_back_read(context%old_local, old, ierr))
    end if
    PetscCall(give_back_read(context%new_local, new, ierr))
  end subroutine field_into

  ! SNES callback: the rank's rows of R(x) = (x - z_old)/h - f(z_old, x) (field_into); a state
  ! outside a spring's domain is a domain error (SNES stops).
  subroutine chain_residual(snes, x, r, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Vec, intent(in) :: r
    type(chain_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), rows(:), state(:)
    integer :: stat, owned, first
    real(real64) :: h

    owned = context%last_row - context%first_row + 1
    first = context%first_row - context%base
    h = context%problem%fraction*context%problem%dt
    PetscCall(borrow(r, owned, rows, ierr))
    PetscCall(field_into(context, x, rows, stat, ierr))
    PetscCall(borrow_read(context%old_local, context%local_size, old, ierr))
    PetscCall(borrow_read(x, owned, state, ierr))
    rows = (state - old(first:first + owned - 1))/h - rows
    PetscCall(give_back_read(x, state, ierr))
    PetscCall(give_back_read(context%old_local, old, ierr))
    PetscCall(give_back(r, rows, ierr))
    if (stat /= failure_none) then
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine chain_residual

  ! SNES callback: the rank's rows of dR/dx = I/h - df/dx (jacobian_into).
  subroutine chain_jacobian(snes, x, jacobian, preconditioner, context, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian, preconditioner
    type(chain_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    integer :: stat

    PetscCall(jacobian_into(context, x, preconditioner, -1.0_real64, 1.0_real64/(context%problem%fraction*context%problem%dt), stat, ierr))
    if (jacobian /= preconditioner) then
      PetscCall(MatAssemblyBegin(jacobian, MAT_FINAL_ASSEMBLY, ierr))
      PetscCall(MatAssemblyEnd(jacobian, MAT_FINAL_ASSEMBLY, ierr))
    end if
    if (stat /= failure_none) then
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine chain_jacobian

  ! The rank's rows of sign df/dx + diagonal I at x into `matrix`, assembled: slice by slice,
  ! each row's structural nonzeros (coupling_pattern) taken from the slice's band and written over
  ! the row's stored values (MatSetValuesRow: the matrix holds exactly these columns, in this
  ! ascending order, since create_jacobian_matrix; no column search). With -chain_check_pattern
  ! a derivative outside the pattern is an error.
  subroutine jacobian_into(context, x, matrix, sign, diagonal, stat, ierr)
    type(chain_context), intent(inout) :: context
    Vec, intent(in) :: x
    Mat, intent(in) :: matrix
    real(real64), intent(in) :: sign, diagonal
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    integer :: half, row, slice_first, slice_last, k, band_column, point, slot, dof, points
    PetscInt :: count, row_index
    logical :: outside

    associate (problem => context%problem, band => context%band, columns => context%columns, values => context%values)
      half = problem%band_half_width()
      dof = size(context%pattern, 1)
      points = context%total/dof
      PetscCall(DMGlobalToLocalBegin(context%da, x, INSERT_VALUES, context%new_local, ierr))
      PetscCall(DMGlobalToLocalEnd(context%da, x, INSERT_VALUES, context%new_local, ierr))
      PetscCall(borrow_read(context%new_local, context%local_size, new, ierr))
      old => new
      if (problem%rule /= partials_exact) then
        PetscCall(borrow_read(context%old_local, context%local_size, old, ierr))
      end if
      stat = failure_none
      outside = .false.
      do slice_first = context%first_row, context%last_row, size(context%rows)
        slice_last = min(context%last_row, slice_first + size(context%rows) - 1)
        call problem%field_rows(old, new, context%base, slice_first, slice_last, context%rows(1:slice_last - slice_first + 1), &
                                band(:, 1:slice_last - slice_first + 1), stat)
        if (stat /= failure_none) exit
        do row = slice_first, slice_last
          associate (row_band => band(:, row - slice_first + 1))
            point = (row - 1)/dof + 1
            if (point >= 3 .and. point <= points - 3 .and. .not. context%check_pattern) then
              ! An interior row: its entries sit at fixed places of its band (create_petsc).
              slot = row - (point - 1)*dof
              count = context%interior_counts(slot)
              values(1:count) = sign*row_band(context%interior_band(1:count, slot))
              values(context%interior_diagonal(slot)) = values(context%interior_diagonal(slot)) + diagonal
            else
              call pattern_columns(context, row, columns, count)
              do k = 1, int(count)
                ! row_band(c - g + half + 1) holds row g, column c (1-based; columns are 0-based)
                band_column = int(columns(k)) + 1 - row + half + 1
                values(k) = sign*row_band(band_column)
                if (columns(k) == row - 1) values(k) = values(k) + diagonal
                if (context%check_pattern) row_band(band_column) = 0.0_real64
              end do
              if (context%check_pattern) outside = outside .or. any(abs(row_band) > 0.0_real64)
            end if
          end associate
          row_index = row - 1
          PetscCall(MatSetValuesRow(matrix, row_index, values, ierr))
        end do
      end do
      if (problem%rule /= partials_exact) then
        PetscCall(give_back_read(context%old_local, old, ierr))
      end if
      PetscCall(give_back_read(context%new_local, new, ierr))
    end associate
    PetscCall(MatAssemblyBegin(matrix, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatAssemblyEnd(matrix, MAT_FINAL_ASSEMBLY, ierr))
    if (outside) then
      ierr = PETSC_ERR_PLIB
      SETERRQ(PETSC_COMM_SELF, ierr, 'chain_jacobian: a derivative outside coupling_pattern (-chain_check_pattern)')
    end if
  end subroutine jacobian_into

  ! Which entries of dR/dz can be nonzero, from the blocks of spring_chain_blocks (docs/
  ! formulation.md section 10), point k holding (x_k, p_k, [gamma_k], [tau_k]) and spring k
  ! joining masses k - 1 and k: pattern(v, w, o) is true when row v of point k depends on
  ! unknown w of point k + o.
  !  - every unknown (I/h); x_k on p_k (v = p/m, the same component);
  !  - p_k on the forces of springs k and k + 1: on x_{k-1}, x_k, x_{k+1} (every component,
  !    through C) and on gamma, tau of points k and k + 1;
  !  - gamma_k on spring k: x_{k-1}, x_k, gamma_k, tau_k;
  !  - tau_k on spring k (x_{k-1}, x_k, p_{k-1}, p_k, gamma_k, tau_k) and on links (k-1, k) and
  !    (k, k+1): x_{k-2} .. x_{k+1}, gamma and tau of points k - 1 .. k + 1.
  pure function coupling_pattern(layout) result(pattern)
    type(chain_layout), intent(in) :: layout
    logical :: pattern(layout%point_size(), layout%point_size(), -2:2)
    integer :: d, c, x(layout%dimension), p(layout%dimension), own(layout%invariant_count - 1)

    d = layout%dimension
    x = [(c, c=1, d)]
    p = [(d + c, c=1, d)]
    own = [(c, c=2*d + 1, layout%point_size())]        ! [gamma,] [tau]
    pattern = .false.
    do c = 1, layout%point_size()
      pattern(c, c, 0) = .true.
    end do
    do c = 1, d
      pattern(x(c), p(c), 0) = .true.
    end do
    pattern(p, x, -1:1) = .true.
    pattern(p, own, 0:1) = .true.
    if (layout%invariant_count == 3) then
      pattern(own(1), x, -1:0) = .true.
      pattern(own(1), own, 0) = .true.
    end if
    if (layout%invariant_count >= 2) then
      associate (tau => layout%point_size())
        pattern(tau, x, -2:1) = .true.
        pattern(tau, p, -1:0) = .true.
        pattern(tau, own, -1:1) = .true.
      end associate
    end if
  end function coupling_pattern

  ! Row `row`'s (1-based) columns in coupling_pattern (0-based, ascending, within the points);
  ! an unused slot's row has its diagonal alone.
  subroutine pattern_columns(context, row, columns, count)
    type(chain_context), intent(in) :: context
    integer, intent(in) :: row
    PetscInt, intent(out) :: columns(:)
    PetscInt, intent(out) :: count
    integer :: dof, points, point, v, o, w

    dof = size(context%pattern, 1)
    points = context%total/dof
    point = (row - 1)/dof + 1
    if (point >= 3 .and. point <= points - 3) then
      v = row - (point - 1)*dof
      count = context%interior_counts(v)
      columns(1:count) = (point - 1)*dof + context%interior_columns(1:count, v)
      return
    end if
    v = slot_kind(point, row - (point - 1)*dof)
    count = 0
    if (v == 0) then
      count = 1
      columns(1) = row - 1
      return
    end if
    do o = max(-2, 1 - point), min(2, points - point)
      do w = 1, dof
        if (slot_kind(point + o, w) == 0) cycle
        if (.not. context%pattern(v, slot_kind(point + o, w), o)) cycle
        count = count + 1
        columns(count) = (point + o - 1)*dof + w - 1
      end do
    end do

  contains

    ! What slot `slot` of point `k` holds, in a mass point's numbering (0: unused).
    pure integer function slot_kind(k, slot)
      integer, intent(in) :: k, slot

      slot_kind = slot
      if (k == points) slot_kind = context%last_point_slots(slot)
    end function slot_kind
  end subroutine pattern_columns

  ! The Jacobian's matrix: AIJ with the rank's rows, preallocated with coupling_pattern's entries
  ! exactly and assembled with them (zeros), so that a later insertion outside them is an error.
  subroutine create_jacobian_matrix(context, comm, matrix, ierr)
    type(chain_context), intent(inout) :: context
    MPI_Comm, intent(in) :: comm
    Mat, intent(out) :: matrix
    PetscErrorCode, intent(out) :: ierr
    PetscInt, allocatable :: diagonal_counts(:), off_counts(:)
    PetscInt :: owned, total, entries, zero, one, row_index(1)
    integer :: row

    owned = context%last_row - context%first_row + 1
    total = context%total
    allocate (diagonal_counts(owned), off_counts(owned))
    do row = context%first_row, context%last_row
      call pattern_columns(context, row, context%columns, entries)
      diagonal_counts(row - context%first_row + 1) = count(context%columns(1:entries) >= context%first_row - 1 .and. &
                                                           context%columns(1:entries) <= context%last_row - 1)
      off_counts(row - context%first_row + 1) = entries - diagonal_counts(row - context%first_row + 1)
    end do
    zero = 0
    PetscCall(MatCreate(comm, matrix, ierr))
    PetscCall(MatSetSizes(matrix, owned, owned, total, total, ierr))
    PetscCall(MatSetType(matrix, MATAIJ, ierr))
    PetscCall(MatSeqAIJSetPreallocation(matrix, zero, diagonal_counts, ierr))
    PetscCall(MatMPIAIJSetPreallocation(matrix, zero, diagonal_counts, zero, off_counts, ierr))
    one = 1
    context%values = 0.0_real64
    do row = context%first_row, context%last_row
      call pattern_columns(context, row, context%columns, entries)
      row_index(1) = row - 1
      PetscCall(MatSetValues(matrix, one, row_index, entries, context%columns, context%values, INSERT_VALUES, ierr))
    end do
    PetscCall(MatAssemblyBegin(matrix, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatAssemblyEnd(matrix, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatSetOption(matrix, MAT_NEW_NONZERO_LOCATION_ERR, PETSC_TRUE, ierr))
    ! Each rank sets its own rows only: the assemblies skip the exchange of other ranks' entries
    ! (PetscCommBuildTwoSided, a synchronisation of the ranks at every assembly: on 2 ranks at 1e4
    ! springs it was up to 1.6 % of one rank's instructions in the loop, mostly waiting).
    PetscCall(MatSetOption(matrix, MAT_NO_OFF_PROC_ENTRIES, PETSC_TRUE, ierr))
  end subroutine create_jacobian_matrix

  ! SNES convergence test: |R| <= the absolute tolerance, or (after an update) the update at the
  ! rounding of the state, which Newton cannot go below; diverged at the iteration limit or on a
  ! non-finite norm.
  subroutine converged_or_rounding(snes, iteration, x_norm, update_norm, residual_norm, reason, context, ierr)
    SNES, intent(in) :: snes
    PetscInt, intent(in) :: iteration
    PetscReal, intent(in) :: x_norm, update_norm, residual_norm
    SNESConvergedReason, intent(out) :: reason
    type(chain_context), intent(inout) :: context
    PetscErrorCode, intent(out) :: ierr
    PetscReal :: atol, rtol, stol
    PetscInt :: max_iterations, max_evaluations

    PetscCall(SNESGetTolerances(snes, atol, rtol, stol, max_iterations, max_evaluations, ierr))
    if (.not. (residual_norm <= huge(residual_norm))) then
      reason = SNES_DIVERGED_FNORM_NAN
    else if (residual_norm <= min(atol, context%newton_tol)) then
      reason = SNES_CONVERGED_FNORM_ABS
    else if (iteration > 0 .and. update_norm <= max(context%update_floor, 16.0_real64*epsilon(1.0_real64)*x_norm)) then
      reason = SNES_CONVERGED_SNORM_RELATIVE
    else if (iteration >= max_iterations) then
      reason = SNES_DIVERGED_MAX_IT
    else
      reason = SNES_CONVERGED_ITERATING
    end if
  end subroutine converged_or_rounding

  !> The figures of the state held and of the last step to it (spring_chain_figures), each rank's
  !> share summed over the ranks (the minima taken over them) with MPI_Allreduce.
  subroutine figures(self, values, failure)
    class(distributed_chain), intent(inout) :: self
    type(distributed_figures), intent(out) :: values
    type(failure_type), intent(out) :: failure
    PetscErrorCode :: ierr
    integer :: stat

    call figures_petsc(self, values, stat, ierr)
    call fail_on_code(failure, ierr, 'summing the chain''s balances')
    if (.not. failure%failed() .and. stat /= failure_none) &
      call fail(failure, domain_overflow, 'a spring is outside its domain while summing the balances')
  end subroutine figures

  subroutine figures_petsc(self, values, stat, ierr)
    class(distributed_chain), intent(inout) :: self
    type(distributed_figures), intent(out) :: values
    integer, intent(out) :: stat
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: old(:), new(:)
    type(distributed_figures) :: share
    real(real64) :: sums(16), minima(3)
    MPI_Comm :: comm

    associate (c => self%context)
      PetscCall(DMGlobalToLocalBegin(c%da, self%x, INSERT_VALUES, c%new_local, ierr))
      PetscCall(DMGlobalToLocalEnd(c%da, self%x, INSERT_VALUES, c%new_local, ierr))
      PetscCall(borrow_read(c%old_local, c%local_size, old, ierr))
      PetscCall(borrow_read(c%new_local, c%local_size, new, ierr))
      call share_figures(c%problem, old, new, c%base, [self%first_point, self%last_point], share, stat)
      PetscCall(give_back_read(c%old_local, old, ierr))
      PetscCall(give_back_read(c%new_local, new, ierr))
      PetscCall(PetscObjectGetComm(c%da, comm, ierr))
      ! (a share outside its domain still takes part in the sums, so that no rank waits alone)
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      sums = [share%energy, share%energy_scale, share%entropy, share%entropy_scale, share%delta_energy, &
              share%delta_entropy, share%conserved, share%delta_conserved, share%momentum_scale, &
              share%angular_momentum]
      minima = [share%min_temperature, share%min_viscous_production, share%min_link_production]
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, sums, size(sums), MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, minima, size(minima), MPI_DOUBLE_PRECISION, MPI_MIN, comm, ierr))
    end associate
    values = distributed_figures(energy=sums(1), energy_scale=sums(2), entropy=sums(3), entropy_scale=sums(4), &
                                 delta_energy=sums(5), delta_entropy=sums(6), conserved_count=share%conserved_count, &
                                 conserved=sums(7:9), delta_conserved=sums(10:12), momentum_scale=sums(13), &
                                 angular_momentum=sums(14:16), &
                                 min_temperature=minima(1), min_viscous_production=minima(2), &
                                 min_link_production=minima(3))
  end subroutine figures_petsc

end module spring_chain_dmda
