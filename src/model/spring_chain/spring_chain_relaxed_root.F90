!> The relaxation of a relaxed step on the chain split over ranks (spring_chain_relaxed_run), as
!> src/solver/relaxation_root searches it: z_new = P(z + gamma d), P the least change of the
!> momenta that keeps the conserved components of J, and r(gamma)/gamma = [E(z_new) - E(z)]/gamma,
!> every whole-state quantity summed over the ranks (MPI_Allreduce), E's difference the sum of the
!> ranks' per-part differences (spring_chain_step's energy_difference: free of cancellation). A
!> module of its own: the root's function is one concept, used by the relaxed step
!> (spring_chain_relaxed_step) alone.
module spring_chain_relaxed_root
#include <petsc/finclude/petscdmda.h>
  use petscdmda
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none, domain_overflow
  use relaxation_root, only: relaxation_function
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use spring_chain_relaxation_share, only: momentum_share, projection_coefficients, project_momenta
  use spring_chain_relaxed_run, only: relaxed_chain_run
  implicit none
  private
  public :: split_relaxation

  !> A relaxed step's relaxation as src/solver/relaxation_root searches it: the run it relaxes.
  type, extends(relaxation_function) :: split_relaxation
    class(relaxed_chain_run), pointer :: run => null()
  contains
    procedure :: move
    procedure :: scaled_residual
  end type split_relaxation

contains

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

end module spring_chain_relaxed_root
