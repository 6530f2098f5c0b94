!> The run's own thermodynamic variable in the snapshots of the relaxed chain split over ranks
!> (spring_chain_relaxed_run): its steps run in entropy variables, so a snapshot's part takes each
!> spring's tau to the run's variable and a restored part takes it back, spring by spring at its
!> temperature (spring_chain_relaxation_share's converted_taus). A submodule because it reads the
!> run's chain and springs.
#include <petsc/finclude/petscdmda.h>
submodule (spring_chain_relaxed_run) spring_chain_relaxed_parts
  use vector_arrays, only: borrow_read, give_back_read
  use spring_chain_relaxation_share, only: converted_taus
  implicit none

contains

  !> The rank's part of the state for a snapshot, tau in the run's own variable
  !> (distributed_system).
  module subroutine part(self, state, failure)
    class(relaxed_chain_run), intent(inout) :: self
    type(distributed_part), intent(out) :: state
    type(failure_type), intent(out) :: failure

    call self%sparse_chain_run%part(state, failure)
    if (failure%failed() .or. size(state%tau) == 0 .or. self%run_variable == tau_entropy) return
    call convert_held_taus(self, .true., state%tau, failure)
  end subroutine part

  !> Makes the rank's part `state` (tau in the run's own variable) the current state, in entropy
  !> variables (distributed_system).
  module subroutine restore(self, state, failure)
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

end submodule spring_chain_relaxed_parts
