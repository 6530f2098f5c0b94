!> Constraint g1 of eq. (13) for the double pendulum: spring 1 keeps its length,
!> g1 = (q1.q1 - length^2)/2 (docs/formulation.md section 1: the quadratic form of the paper's g1).
!> Its force -lambda q1_mid acts on p1; q1_mid is g1's exact discrete gradient, so the force does
!> no work and is parallel to q1_mid: E and the conserved components of J stay conserved
!> (docs/formulation.md section 7).
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
  use double_pendulum, only: pendulum_layout
  use number_text, only: scientific_text
  implicit none (type, external)
  private
  public :: fixed_length, make_fixed_length

  !> |q1| held at `length` [m]; mass_1 is m1 [kg].
  type, extends(constraint) :: fixed_length
    real(real64) :: length = 1.0_real64
    real(real64) :: mass_1 = 1.0_real64
    integer, allocatable :: q1_columns(:), p1_columns(:), p2_columns(:)   !! in the scene's layout
  contains
    procedure :: add_terms
    procedure :: value
    procedure :: add_force
    procedure :: project_positions
    procedure :: momentum_condition
    procedure :: inconsistency
  end type fixed_length

contains

  !> The constraint |q1| = length on mass 1 of mass mass_1, in the scene's `layout`.
  pure function make_fixed_length(length, mass_1, layout) result(rod)
    real(real64), intent(in) :: length, mass_1
    type(pendulum_layout), intent(in) :: layout
    type(fixed_length) :: rod

    rod%name = 'length'
    rod%multiplier_units = 'N/m'
    rod%value_units = 'm^2'
    rod%meaning = 'g = (q1.q1 - length^2)/2; lambda: the force -lambda q1_mid on p1'
    rod%length = length
    rod%mass_1 = mass_1
    allocate (rod%q1_columns(layout%dimension), rod%p1_columns(layout%dimension), rod%p2_columns(layout%dimension))
    rod%q1_columns(:) = layout%q(1:layout%dimension, 1)
    rod%p1_columns(:) = layout%p(1:layout%dimension, 1)
    rod%p2_columns(:) = layout%p(1:layout%dimension, 2)
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
    associate (q1 => z_new(self%q1_columns))
      residual(self%p1_columns) = residual(self%p1_columns) + lambda*z_mid(self%q1_columns)
      residual(row) = 0.5_real64*(dot_product(q1, q1) - self%length**2)
      if (present(jacobian)) then
        jacobian(self%p1_columns, row) = z_mid(self%q1_columns)
        do i = 1, size(self%q1_columns)
          jacobian(self%p1_columns(i), self%q1_columns(i)) = jacobian(self%p1_columns(i), self%q1_columns(i)) + 0.5_real64*lambda
        end do
        jacobian(row, self%q1_columns) = q1
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
    g = 0.5_real64*(dot_product(z(self%q1_columns), z(self%q1_columns)) - self%length**2)
  end subroutine value

  !> f_p1 <- f_p1 - lambda q1 with the index-1 multiplier (above), and its derivative.
  pure subroutine add_force(self, model, z, f, multiplier, jacobian)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    real(real64), intent(inout) :: f(:)
    real(real64), intent(out) :: multiplier
    real(real64), intent(inout), optional :: jacobian(:, :)
    real(real64), dimension(size(self%q1_columns)) :: q1, v1, a1
    real(real64) :: length_squared, dlambda(size(z))
    integer :: i

    q1 = z(self%q1_columns)
    v1 = (z(self%p1_columns) - z(self%p2_columns))/self%mass_1
    a1 = f(self%p1_columns) - f(self%p2_columns)            ! m1 times the unconstrained dv1/dt
    length_squared = dot_product(q1, q1)
    multiplier = (self%mass_1*dot_product(v1, v1) + dot_product(q1, a1))/length_squared
    if (present(jacobian)) then
      dlambda = matmul(q1, jacobian(self%p1_columns, :) - jacobian(self%p2_columns, :))
      dlambda(self%p1_columns) = dlambda(self%p1_columns) + 2*v1
      dlambda(self%p2_columns) = dlambda(self%p2_columns) - 2*v1
      dlambda(self%q1_columns) = dlambda(self%q1_columns) + a1 - 2*multiplier*q1
      dlambda = dlambda/length_squared
      do i = 1, size(self%q1_columns)
        jacobian(self%p1_columns(i), :) = jacobian(self%p1_columns(i), :) - q1(i)*dlambda
        jacobian(self%p1_columns(i), self%q1_columns(i)) = jacobian(self%p1_columns(i), self%q1_columns(i)) - multiplier
      end do
    end if
    f(self%p1_columns) = f(self%p1_columns) - multiplier*q1
  end subroutine add_force

  !> q1 <- q1 length/|q1|.
  pure subroutine project_positions(self, model, z)
    class(fixed_length), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(inout) :: z(:)

    z(self%q1_columns) = z(self%q1_columns)*(self%length/norm2(z(self%q1_columns)))
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
    gradient(self%p1_columns) = z(self%q1_columns)/self%mass_1
    gradient(self%p2_columns) = -z(self%q1_columns)/self%mass_1
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
    if (abs(rate) > 1.0e-12_real64*norm2(z(self%q1_columns))*norm2(z(self%p1_columns) - z(self%p2_columns))/self%mass_1) &
      text = 'the fixed length needs q1.v1 = 0 at t = 0 (v1 = (p1 - p2)/m1 tangent to the sphere |q1| = length, '// &
             'as the constrained motion keeps it), but q1.v1 = '//scientific_text(rate)//' m^2/s'
  end function inconsistency

end module length_constraint
