!> Constraint g1 of eq. (13) for the double pendulum: spring 1 keeps its length,
!> g1 = (q1.q1 - length^2)/2 (FORMULATION section 1: the quadratic form of the paper's g1).
!> Its force -lambda q1_mid acts on p1; q1_mid is g1's exact discrete gradient, so the force does
!> no work and is parallel to q1_mid: E and J_z stay conserved (FORMULATION section 7).
module length_constraint
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: domain_ok
  use model_interface, only: generic_model
  use model_constraint, only: constraint
  use double_pendulum, only: q_index, p_index
  implicit none (type, external)
  private
  public :: fixed_length, make_fixed_length

  !> |q1| held at `length` [m].
  type, extends(constraint) :: fixed_length
    real(real64) :: length = 1.0_real64
  contains
    procedure :: add_terms
    procedure :: value
  end type fixed_length

contains

  !> The constraint |q1| = length.
  pure function make_fixed_length(length) result(rod)
    real(real64), intent(in) :: length
    type(fixed_length) :: rod

    rod%name = 'length'
    rod%multiplier_units = 'N/m'
    rod%value_units = 'm^2'
    rod%meaning = 'g = (q1.q1 - length^2)/2; lambda: the force -lambda q1_mid on p1'
    rod%length = length
  end function make_fixed_length

  !> Force -lambda q1_mid on p1 and g1(z') into the multiplier's row.
  pure subroutine add_terms(self, model, z_new, z_mid, partials, dpartials_dz, lambda, row, residual, jacobian, stat)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z_new(:), z_mid(:), partials(:, :, :), dpartials_dz(:, :, :, :), lambda
    integer, intent(in) :: row
    real(real64), intent(inout) :: residual(:)
    real(real64), intent(inout), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    integer :: i

    stat = domain_ok
    associate (q1 => z_new(q_index(:, 1)))
      residual(p_index(:, 1)) = residual(p_index(:, 1)) + lambda*z_mid(q_index(:, 1))
      residual(row) = 0.5_real64*(dot_product(q1, q1) - self%length**2)
      if (present(jacobian)) then
        jacobian(p_index(:, 1), row) = z_mid(q_index(:, 1))
        do i = 1, 3
          jacobian(p_index(i, 1), q_index(i, 1)) = jacobian(p_index(i, 1), q_index(i, 1)) + 0.5_real64*lambda
        end do
        jacobian(row, q_index(:, 1)) = q1
      end if
    end associate
  end subroutine add_terms

  !> g1(z) = (q1.q1 - length^2)/2.
  pure subroutine value(self, model, z, g, stat)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: g
    integer, intent(out) :: stat

    stat = domain_ok
    g = 0.5_real64*(dot_product(z(q_index(:, 1)), z(q_index(:, 1))) - self%length**2)
  end subroutine value

end module length_constraint
