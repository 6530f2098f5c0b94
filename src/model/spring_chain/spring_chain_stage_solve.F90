!> The implicit stages of a relaxed Runge-Kutta step (relaxed_gauss6) on the chain split over
!> ranks (docs/integrators.md, "The relaxed family on the split chain"): the dense path's stage
!> equations (src/integrator/collocation_stages)
!>   R_i(K) = k_i - f(g_i),   g_i = z + h sum_j a_ij k_j,   i = 1..s,
!>   dR_i/dk_j = delta_ij I - h a_ij (df/dz)(g_i),
!> with f the chain's GENERIC field and df/dz its exact Jacobian (spring_chain_dmda's field_at and
!> jacobian_at, the rows each rank owns). The unknowns K sit point by point (a point's s stages of
!> its unknowns side by side: unknown c of point p, stage j, is s*dof*p + j*dof + c, 0-based), so
!> each rank owns the stages of its own points and the matrix keeps the chain's band, s times as
!> wide; its pattern is the chain's, each entry an s x s block. PETSc SNES solves them with the
!> chain's default linear solver (spring_chain_linear_solver; the options may choose others),
!> full Newton steps from k_i = f(z), stopping as the steps' Newton does (newton_verdict: at the
!> input's newton_tol or at an update below the rounding of the stage values, 16 eps |z|/h) or
!> where |R| stops falling close to that floor: a stiff chain's f rounds to more than that (on
!> a rod of 300 springs at 2e-5 s the updates settled at 1.1 times 16 eps |z|/h).
module spring_chain_stage_solve
#include <petsc/finclude/petscsnes.h>
  use petscsnes
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use spring_chain_dmda, only: distributed_chain
  use spring_chain_linear_solver, only: set_default_linear_solver, set_rounding_tolerance
  use spring_chain_dmda_pattern, only: pattern_columns
  use spring_chain_dmda_assembly, only: newton_verdict
  use dense_assembly, only: assemble_jacobian
  implicit none
  private
  public :: chain_stage_solver

  !> What the stage callbacks see (PETSc holds its address, inside a chain_stage_solver).
  type :: stage_context
    type(distributed_chain), pointer :: chain => null()
    real(real64), allocatable :: a(:, :)     !! the tableau's stage matrix
    real(real64) :: h = 0.0_real64
    integer :: dof = 0                       !! the chain's unknowns per point
    Vec :: z                                 !! the step's start
    Vec :: stage                             !! g_i
    Vec :: field                             !! f(g_i)
    Vec, allocatable :: k(:)                 !! the stage derivatives of the iterate
    real(real64) :: newton_tol = 0.0_real64, update_floor = 0.0_real64
    real(real64) :: previous_residual = 0.0_real64      !! |R| of the iteration before
    PetscInt, allocatable :: columns(:), stage_columns(:)   !! a row of df/dz, its columns in K
    real(real64), allocatable :: values(:), stage_values(:)
    !> places(:, j): where stage j's rows (the rank's, from its first) sit in the rank's rows of K
    integer, allocatable :: places(:, :)
  end type stage_context

  !> The stage equations' SNES on a chain. Do not copy it after `create`: PETSc holds the address
  !> of its context.
  type, public :: chain_stage_solver
    type(stage_context) :: context
    SNES :: snes
    Vec :: unknowns, residual
    Mat :: jacobian
    logical :: created = .false.
  contains
    procedure :: create
    procedure :: solve
    procedure :: destroy
  end type chain_stage_solver

contains

  !> Makes the SNES of the stages of tableau matrix `a` on `chain` (created; its own Jacobian
  !> matrix is borrowed for df/dz, so the chain has no SNES of its own): Newton stops at
  !> |R| <= newton_tol or at the rounding of K, within max_iterations.
  subroutine create(self, chain, a, newton_tol, max_iterations, ierr)
    class(chain_stage_solver), intent(inout), target :: self
    type(distributed_chain), intent(inout), target :: chain
    real(real64), intent(in) :: a(:, :), newton_tol
    integer, intent(in) :: max_iterations
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: owned, total, zero, iterations, max_evaluations
    PetscInt, allocatable :: diagonal_counts(:), off_counts(:)
    integer :: row, stages, entries, first, j
    MPI_Comm :: comm
    KSP :: ksp
    SNESLineSearch :: line_search

    associate (c => self%context)
      c%chain => chain
      c%a = a
      c%newton_tol = newton_tol
      stages = size(a, 1)
      c%dof = size(chain%context%pattern, 1)
      allocate (c%columns(size(chain%context%columns)), c%values(size(chain%context%columns)))
      allocate (c%stage_columns(size(c%columns)), c%stage_values(size(c%columns)))
      owned = stages*(chain%context%last_row - chain%context%first_row + 1)
      total = stages*chain%context%total
      PetscCall(PetscObjectGetComm(chain%context%da, comm, ierr))
      PetscCall(VecCreateMPI(comm, owned, total, self%unknowns, ierr))
      PetscCall(VecDuplicate(self%unknowns, self%residual, ierr))
      PetscCall(VecDuplicate(chain%x, c%z, ierr))
      PetscCall(VecDuplicate(chain%x, c%stage, ierr))
      PetscCall(VecDuplicate(chain%x, c%field, ierr))
      allocate (c%k(stages))
      do j = 1, stages
        PetscCall(VecDuplicate(chain%x, c%k(j), ierr))
      end do
      allocate (c%places(owned/stages, stages))
      do j = 1, stages
        c%places(:, j) = [(stage_row(c, row, j - 1) + 1, row = 0, owned/stages - 1)]
      end do
      ! A row of stage j at (point, slot) has the chain row's columns once per stage.
      allocate (diagonal_counts(owned), off_counts(owned))
      first = chain%context%first_row
      do row = first, chain%context%last_row
        call pattern_columns(chain%context, row, c%columns, entries)
        associate (inside => count(c%columns(1:entries) >= first - 1 .and. c%columns(1:entries) <= chain%context%last_row - 1))
          do j = 0, stages - 1
            diagonal_counts(stage_row(c, row - 1, j) - stages*(first - 1) + 1) = stages*inside
            off_counts(stage_row(c, row - 1, j) - stages*(first - 1) + 1) = stages*(entries - inside)
          end do
        end associate
      end do
      zero = 0
      PetscCall(MatCreate(comm, self%jacobian, ierr))
      PetscCall(MatSetSizes(self%jacobian, owned, owned, total, total, ierr))
      PetscCall(MatSetType(self%jacobian, MATAIJ, ierr))
      PetscCall(MatSeqAIJSetPreallocation(self%jacobian, zero, diagonal_counts, ierr))
      PetscCall(MatMPIAIJSetPreallocation(self%jacobian, zero, diagonal_counts, zero, off_counts, ierr))
      PetscCall(MatSetOption(self%jacobian, MAT_NO_OFF_PROC_ENTRIES, PETSC_TRUE, ierr))
    end associate
    PetscCall(SNESCreate(comm, self%snes, ierr))
    self%created = .true.
    PetscCall(SNESSetFunction(self%snes, self%residual, stage_residual, self%context, ierr))
    PetscCall(SNESSetJacobian(self%snes, self%jacobian, self%jacobian, stage_jacobian, self%context, ierr))
    max_evaluations = 10000
    iterations = max_iterations
    PetscCall(SNESSetTolerances(self%snes, newton_tol, 0.0_real64, 0.0_real64, iterations, max_evaluations, ierr))
    PetscCall(SNESSetConvergenceTest(self%snes, stage_convergence, self%context, PETSC_NULL_FUNCTION, ierr))
    ! Full Newton steps, as the steps' SNES and the dense path's stages take.
    PetscCall(SNESGetLineSearch(self%snes, line_search, ierr))
    PetscCall(SNESLineSearchSetType(line_search, SNESLINESEARCHBASIC, ierr))
    PetscCall(SNESGetKSP(self%snes, ksp, ierr))
    PetscCall(set_default_linear_solver(ksp, comm, ierr))
    PetscCall(SNESSetFromOptions(self%snes, ierr))
  end subroutine create

  !> The stages of one step of h from z into k(:) (the chain's vectors): Newton from k_i = f(z).
  !> converged false when Newton did not converge or f(z) is outside a spring's domain (then k
  !> is not set); iterations, the last |R| and SNES's reason (0 at a domain error of f(z)).
  subroutine solve(self, z, h, k, converged, iterations, residual_norm, reason, ierr)
    class(chain_stage_solver), intent(inout) :: self
    Vec, intent(in) :: z
    real(real64), intent(in) :: h
    Vec, intent(in) :: k(:)
    logical, intent(out) :: converged
    integer, intent(out) :: iterations, reason
    real(real64), intent(out) :: residual_norm
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: snes_iterations
    SNESConvergedReason :: snes_reason
    PetscReal :: norm
    integer :: stat, j
    MPI_Comm :: comm
    KSP :: ksp

    converged = .false.
    iterations = 0
    reason = 0
    residual_norm = 0.0_real64
    associate (c => self%context)
      c%h = h
      PetscCall(VecCopy(z, c%z, ierr))
      PetscCall(c%chain%field_at(z, c%field, stat, ierr))
      PetscCall(PetscObjectGetComm(self%snes, comm, ierr))
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      if (stat /= failure_none) return
      do j = 1, size(c%k)
        PetscCall(VecCopy(c%field, c%k(j), ierr))
      end do
      PetscCall(pack_stages(c, c%k, self%unknowns, ierr))
      ! K is resolved to the rounding of the stage values g_i = z + h sum_j a_ij k_j: updates
      ! below 16 eps |z|/h move them by less than the rounding of z.
      PetscCall(VecNorm(z, NORM_2, norm, ierr))
      c%update_floor = 16.0_real64*epsilon(1.0_real64)*norm/h
      PetscCall(SNESGetKSP(self%snes, ksp, ierr))
      PetscCall(set_rounding_tolerance(ksp, epsilon(1.0_real64)*norm/h, ierr))
      PetscCall(SNESSolve(self%snes, PETSC_NULL_VEC, self%unknowns, ierr))
      PetscCall(SNESGetConvergedReason(self%snes, snes_reason, ierr))
      PetscCall(SNESGetIterationNumber(self%snes, snes_iterations, ierr))
      PetscCall(SNESGetFunctionNorm(self%snes, norm, ierr))
      reason = snes_reason
      iterations = int(snes_iterations)
      residual_norm = norm
      converged = snes_reason > 0
      if (converged) then
        PetscCall(unpack_stages(c, self%unknowns, k, ierr))
      end if
    end associate
  end subroutine solve

  !> Frees the solver's PETSc objects (not the chain's).
  subroutine destroy(self, ierr)
    class(chain_stage_solver), intent(inout) :: self
    PetscErrorCode, intent(out) :: ierr
    integer :: j

    ierr = 0
    if (.not. self%created) return
    PetscCall(SNESDestroy(self%snes, ierr))
    PetscCall(MatDestroy(self%jacobian, ierr))
    PetscCall(VecDestroy(self%unknowns, ierr))
    PetscCall(VecDestroy(self%residual, ierr))
    PetscCall(VecDestroy(self%context%z, ierr))
    PetscCall(VecDestroy(self%context%stage, ierr))
    PetscCall(VecDestroy(self%context%field, ierr))
    do j = 1, size(self%context%k)
      PetscCall(VecDestroy(self%context%k(j), ierr))
    end do
    self%created = .false.
  end subroutine destroy

  ! K's index (0-based) of the chain's unknown `row` (0-based) in stage j (0-based).
  pure integer function stage_row(c, row, j)
    type(stage_context), intent(in) :: c
    integer, intent(in) :: row, j

    stage_row = size(c%a, 1)*c%dof*(row/c%dof) + j*c%dof + modulo(row, c%dof)
  end function stage_row

  ! The rank's rows of K from the stage vectors k(:).
  subroutine pack_stages(c, k, unknowns, ierr)
    type(stage_context), intent(in) :: c
    Vec, intent(in) :: k(:)
    Vec, intent(in) :: unknowns
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: packed(:), stage(:)
    integer :: j, owned

    owned = c%chain%context%last_row - c%chain%context%first_row + 1
    PetscCall(borrow(unknowns, size(k)*owned, packed, ierr))
    do j = 1, size(k)
      PetscCall(borrow_read(k(j), owned, stage, ierr))
      packed(c%places(:, j)) = stage
      PetscCall(give_back_read(k(j), stage, ierr))
    end do
    PetscCall(give_back(unknowns, packed, ierr))
  end subroutine pack_stages

  ! The stage vectors k(:) from the rank's rows of K.
  subroutine unpack_stages(c, unknowns, k, ierr)
    type(stage_context), intent(in) :: c
    Vec, intent(in) :: unknowns
    Vec, intent(in) :: k(:)
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: packed(:), stage(:)
    integer :: j, owned

    owned = c%chain%context%last_row - c%chain%context%first_row + 1
    PetscCall(borrow_read(unknowns, size(k)*owned, packed, ierr))
    do j = 1, size(k)
      PetscCall(borrow(k(j), owned, stage, ierr))
      stage = packed(c%places(:, j))
      PetscCall(give_back(k(j), stage, ierr))
    end do
    PetscCall(give_back_read(unknowns, packed, ierr))
  end subroutine unpack_stages

  ! g_i = z + h sum_j a_ij k_j into c%stage.
  subroutine stage_value(c, i, ierr)
    type(stage_context), intent(inout) :: c
    integer, intent(in) :: i
    PetscErrorCode, intent(out) :: ierr
    PetscInt :: count
    PetscScalar :: weights(size(c%k))

    count = size(c%k)
    weights = c%h*c%a(i, :)
    PetscCall(VecCopy(c%z, c%stage, ierr))
    PetscCall(VecMAXPY(c%stage, count, weights, c%k, ierr))
  end subroutine stage_value

  ! SNES callback: the rank's rows of R_i(K) = k_i - f(g_i), stage by stage; a stage outside a
  ! spring's domain is a domain error (SNES stops).
  subroutine stage_residual(snes, x, r, c, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Vec, intent(in) :: r
    type(stage_context), intent(inout) :: c
    PetscErrorCode, intent(out) :: ierr
    real(real64), pointer :: rows(:), field(:)
    integer :: i, stat, owned, failed

    owned = c%chain%context%last_row - c%chain%context%first_row + 1
    PetscCall(unpack_stages(c, x, c%k, ierr))
    PetscCall(VecCopy(x, r, ierr))
    failed = failure_none
    do i = 1, size(c%k)
      PetscCall(stage_value(c, i, ierr))
      PetscCall(c%chain%field_at(c%stage, c%field, stat, ierr))
      if (stat /= failure_none) failed = stat
      PetscCall(borrow(r, size(c%k)*owned, rows, ierr))
      PetscCall(borrow_read(c%field, owned, field, ierr))
      associate (places => c%places(:, i))
        rows(places) = rows(places) - field
      end associate
      PetscCall(give_back_read(c%field, field, ierr))
      PetscCall(give_back(r, rows, ierr))
    end do
    if (failed /= failure_none) then
      PetscCall(SNESSetFunctionDomainError(snes, ierr))
    end if
  end subroutine stage_residual

  ! SNES callback: the rank's rows of dR_i/dk_j = delta_ij I - h a_ij (df/dz)(g_i), stage row by
  ! stage row: df/dz at g_i into the chain's matrix (jacobian_at), each of its rows written s
  ! times, once per stage j.
  subroutine stage_jacobian(snes, x, jacobian, preconditioner, c, ierr)
    SNES, intent(in) :: snes
    Vec, intent(in) :: x
    Mat, intent(in) :: jacobian, preconditioner
    type(stage_context), intent(inout) :: c
    PetscErrorCode, intent(out) :: ierr
    integer :: i, j, row, stat, failed, entry
    PetscInt :: entries, one, row_index(1), chain_row

    one = 1
    failed = failure_none
    PetscCall(unpack_stages(c, x, c%k, ierr))
    do i = 1, size(c%k)
      PetscCall(stage_value(c, i, ierr))
      PetscCall(c%chain%jacobian_at(c%stage, c%chain%jacobian, stat, ierr))
      if (stat /= failure_none) failed = stat
      do row = c%chain%context%first_row - 1, c%chain%context%last_row - 1
        chain_row = row
        PetscCall(MatGetRow(c%chain%jacobian, chain_row, entries, c%columns, c%values, ierr))
        row_index(1) = stage_row(c, row, i - 1)
        do j = 1, size(c%k)
          do entry = 1, int(entries)
            c%stage_columns(entry) = stage_row(c, int(c%columns(entry)), j - 1)
            c%stage_values(entry) = -c%h*c%a(i, j)*c%values(entry)
            if (i == j .and. c%columns(entry) == row) c%stage_values(entry) = c%stage_values(entry) + 1.0_real64
          end do
          PetscCall(MatSetValues(preconditioner, one, row_index, entries, c%stage_columns, c%stage_values, INSERT_VALUES, ierr))
        end do
        PetscCall(MatRestoreRow(c%chain%jacobian, chain_row, entries, c%columns, c%values, ierr))
      end do
    end do
    PetscCall(assemble_jacobian(jacobian, preconditioner, ierr))
    if (failed /= failure_none) then
      PetscCall(SNESSetJacobianDomainError(snes, ierr))
    end if
  end subroutine stage_jacobian

  ! SNES convergence test: the steps' verdict (newton_verdict) on K, or Newton at the rounding of
  ! the residual: near the floor (an update within stagnation_band of it) an iteration that does
  ! not halve |R| has met rounding, where a converging Newton would have squared it.
  subroutine stage_convergence(snes, iteration, x_norm, update_norm, residual_norm, reason, c, ierr)
    SNES, intent(in) :: snes
    PetscInt, intent(in) :: iteration
    PetscReal, intent(in) :: x_norm, update_norm, residual_norm
    SNESConvergedReason, intent(out) :: reason
    type(stage_context), intent(inout) :: c
    PetscErrorCode, intent(out) :: ierr
    real(real64), parameter :: stagnation_band = 64.0_real64

    call newton_verdict(snes, iteration, x_norm, update_norm, residual_norm, c%newton_tol, c%update_floor, reason, ierr)
    if (reason == SNES_CONVERGED_ITERATING .and. iteration >= 2 .and. update_norm <= stagnation_band*c%update_floor .and. &
        residual_norm >= 0.5_real64*c%previous_residual) reason = SNES_CONVERGED_SNORM_RELATIVE
    c%previous_residual = residual_norm
  end subroutine stage_convergence

end module spring_chain_stage_solve
