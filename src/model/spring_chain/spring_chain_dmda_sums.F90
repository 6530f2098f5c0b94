!> The chain's whole-state sums on the DMDA (spring_chain_dmda's distributed_chain): E and S and
!> their changes over the last step, and the figures of spring_chain_figures, each rank's share of
!> its points summed over the ranks with MPI_Allreduce. A submodule because it reads the chain's
!> PETSc vectors and context.
#include <petsc/finclude/petscdmda.h>
submodule (spring_chain_dmda) spring_chain_dmda_sums
  use failures, only: failure_none, fail_on_code, fail, domain_overflow
  use vector_arrays, only: borrow_read, give_back_read
  use spring_chain_figures, only: share_figures
  implicit none

contains

  !> The balances of the last step, summed over the ranks (each rank sums its points' masses and
  !> springs; MPI_Allreduce adds them): E and S of the state held, and E - E_old and S - S_old as
  !> sums of the parts' differences (no cancellation of the large E).
  module subroutine sums(self, energy, entropy, delta_energy, delta_entropy, failure)
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
      ! Every rank fails alike when one rank's springs leave their domain (as figures_petsc).
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, stat, 1, MPI_INTEGER, MPI_MAX, comm, ierr))
      PetscCallMPI(MPI_Allreduce(local, total, 4, MPI_DOUBLE_PRECISION, MPI_SUM, comm, ierr))
    end associate
  end subroutine sums_petsc

  !> The figures of the state held and of the last step to it (spring_chain_figures), each rank's
  !> share summed over the ranks (the minima taken over them) with MPI_Allreduce.
  module subroutine figures(self, values, failure)
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

end submodule spring_chain_dmda_sums
