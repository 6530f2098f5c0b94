!> Constraint g1 of eq. (13) for the double pendulum: spring 1 keeps its length,
!> g1 = (q1.q1 - length^2)/2 (docs/formulation.md section 1: the quadratic form of the paper's g1).
!> Its force -lambda q1_mid acts on p1; q1_mid is g1's exact discrete gradient, so the force does
!> no work and is parallel to q1_mid: E and J_z stay conserved (docs/formulation.md section 7).
!>
!> Its continuous-time form (the relaxed Runge-Kutta family): the force -lambda q1 on p1 with
!> the index-1 multiplier of d^2 g1/dt^2 = |v1|^2 + q1.dv1/dt = 0, v1 = (p1 - p2)/m1, which is
!>   lambda = (m1 |v1|^2 + q1.(f_p1 - f_p2)) / |q1|^2
!> for the unconstrained momentum rates f_p; the hidden constraint dg1/dt = q1.v1 = 0, which
!> must hold at t = 0; and q1 scaled back to |q1| = length after a step.
module length_constraint
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use model_interface, only: generic_model
  use model_constraint, only: constraint
  use double_pendulum, only: q_index, p_index
  use number_text, only: scientific_text
  implicit none (type, external)
  private
  public :: fixed_length, make_fixed_length

  !> |q1| held at `length` [m]; mass_1 is m1 [kg].
  type, extends(constraint) :: fixed_length
    real(real64) :: length = 1.0_real64
    real(real64) :: mass_1 = 1.0_real64
  contains
    procedure :: add_terms
    procedure :: value
    procedure :: add_force
    procedure :: project_positions
    procedure :: momentum_condition
    procedure :: inconsistency
  end type fixed_length

contains

  !> The constraint |q1| = length on mass 1 of mass mass_1.
  pure function make_fixed_length(length, mass_1) result(rod)
    real(real64), intent(in) :: length, mass_1
    type(fixed_length) :: rod

    rod%name = 'length'
    rod%multiplier_units = 'N/m'
    rod%value_units = 'm^2'
    rod%meaning = 'g = (q1.q1 - length^2)/2; lambda: the force -lambda q1_mid on p1'
    rod%length = length
    rod%mass_1 = mass_1
    rod%continuous_form = .true.
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

    stat = failure_none
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

    stat = failure_none
    g = 0.5_real64*(dot_product(z(q_index(:, 1)), z(q_index(:, 1))) - self%length**2)
  end subroutine value

  !> f_p1 <- f_p1 - lambda q1 with the index-1 multiplier (above), and its derivative.
  pure subroutine add_force(self, model, z, f, multiplier, jacobian)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    real(real64), intent(inout) :: f(:)
    real(real64), intent(out) :: multiplier
    real(real64), intent(inout), optional :: jacobian(:, :)
    real(real64) :: q1(3), v1(3), a1(3), length_squared, dlambda(size(z))
    integer :: i

    q1 = z(q_index(:, 1))
    v1 = (z(p_index(:, 1)) - z(p_index(:, 2)))/self%mass_1
    a1 = f(p_index(:, 1)) - f(p_index(:, 2))            ! m1 times the unconstrained dv1/dt
    length_squared = dot_product(q1, q1)
    multiplier = (self%mass_1*dot_product(v1, v1) + dot_product(q1, a1))/length_squared
    if (present(jacobian)) then
      dlambda = matmul(q1, jacobian(p_index(:, 1), :) - jacobian(p_index(:, 2), :))
      dlambda(p_index(:, 1)) = dlambda(p_index(:, 1)) + 2*v1
      dlambda(p_index(:, 2)) = dlambda(p_index(:, 2)) - 2*v1
      dlambda(q_index(:, 1)) = dlambda(q_index(:, 1)) + a1 - 2*multiplier*q1
      dlambda = dlambda/length_squared
      do i = 1, 3
        jacobian(p_index(i, 1), :) = jacobian(p_index(i, 1), :) - q1(i)*dlambda
        jacobian(p_index(i, 1), q_index(i, 1)) = jacobian(p_index(i, 1), q_index(i, 1)) - multiplier
      end do
    end if
    f(p_index(:, 1)) = f(p_index(:, 1)) - multiplier*q1
  end subroutine add_force

  !> q1 <- q1 length/|q1|.
  pure subroutine project_positions(self, model, z)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(inout) :: z(:)

    z(q_index(:, 1)) = z(q_index(:, 1))*(self%length/norm2(z(q_index(:, 1))))
  end subroutine project_positions

  !> dg1/dt = q1.v1 = q1.(p1 - p2)/m1, linear in the momenta.
  pure subroutine momentum_condition(self, model, z, has, value, gradient)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    logical, intent(out) :: has
    real(real64), intent(out) :: value, gradient(:)

    has = .true.
    gradient = 0.0_real64
    gradient(p_index(:, 1)) = z(q_index(:, 1))/self%mass_1
    gradient(p_index(:, 2)) = -z(q_index(:, 1))/self%mass_1
    value = dot_product(gradient, z)
  end subroutine momentum_condition

  !> q1.v1 must vanish at t = 0 (to round-off relative to |q1| |v1|).
  function inconsistency(self, model, z) result(text)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    character(len=:), allocatable :: text
    real(real64) :: rate, gradient(size(z))
    logical :: has

    call self%momentum_condition(model, z, has, rate, gradient)
    text = ''
    if (abs(rate) > 1.0e-12_real64*norm2(z(q_index(:, 1)))*norm2(z(p_index(:, 1)) - z(p_index(:, 2)))/self%mass_1) &
      text = 'the fixed length needs q1.v1 = 0 at t = 0 (v1 = (p1 - p2)/m1 tangent to the sphere |q1| = length, '// &
             'as the constrained motion keeps it), but q1.v1 = '//scientific_text(rate)//' m^2/s'
  end function inconsistency

end module length_constraint
