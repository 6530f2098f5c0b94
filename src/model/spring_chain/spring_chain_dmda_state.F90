!> The chain's state on the DMDA in and out (spring_chain_dmda's distributed_chain): the whole
!> state or the rank's rows set and read, and the rank's part as a snapshot holds it (its masses'
!> positions and momenta, its springs' gamma, tau and temperatures) read and restored. A submodule
!> because it works on the chain's PETSc vectors and context.
#include <petsc/finclude/petscdmda.h>
submodule (spring_chain_dmda) spring_chain_dmda_state
  use failures, only: failure_none, failure_input, fail_on_code, fail, domain_overflow
  use vector_arrays, only: borrow, give_back, borrow_read, give_back_read
  use spring_chain_balance, only: spring_values
  implicit none

contains

  !> Sets the state from z (every unknown of the layout; each rank copies its own rows; the
  !> unused slots of a 'fixed-fixed' chain's last point are 0).
  module subroutine set_state(self, z, failure)
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
  module subroutine owned_state(self, z, first_row, failure)
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
  module subroutine set_rows(self, z, z_old, failure)
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

  !> The rank's part of the state as a snapshot holds it: its masses' positions and momenta
  !> (dimension x masses), its springs' gamma (none without a viscous branch) and tau, and their
  !> temperatures [K] (spring a lives at point a; its temperature needs mass a - 1, a ghost).
  module subroutine state_part(self, positions, momenta, gamma, tau, theta, failure)
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
  module subroutine set_part(self, positions, momenta, gamma, tau, failure)
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

end submodule spring_chain_dmda_state
