!> The stage equations of an implicit Runge-Kutta step as a nonlinear system for the solvers:
!>   R_i(K) = K_i - f(z + h sum_j a_ij K_j),   i = 1..s,
!> with f the continuous GENERIC field of the model under its constraints
!> (src/integrator/constrained_flow), and the Jacobian
!>   dR_i/dK_j = delta_ij I - h a_ij (df/dz)(Y_i),   Y_i = z + h sum_j a_ij K_j.
!> Its continuation parameter scales h: at s -> 0 every K_i = f(z) is a root.
module collocation_stages
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none, domain_overflow
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use constrained_flow, only: constrained_field
  use nonlinear_problem, only: nonlinear_system
  implicit none (type, external)
  private
  public :: stage_system

  !> The stages of one step of h from z with coefficients a.
  type, extends(nonlinear_system) :: stage_system
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)   !! the field is the constrained flow's
    real(real64), allocatable :: a(:, :)
    real(real64), allocatable :: z(:)
    real(real64) :: h = 0.0_real64
    real(real64) :: fraction = 1.0_real64
  contains
    procedure :: unknowns
    procedure :: evaluate
    procedure :: check_root
    procedure :: set_continuation
    procedure :: stage_values
  end type stage_system

contains

  pure integer function unknowns(self)
    class(stage_system), intent(in) :: self

    unknowns = size(self%a, 1)*self%model%state_size
  end function unknowns

  !> The step of s h from the same state.
  pure subroutine set_continuation(self, s)
    class(stage_system), intent(inout) :: self
    real(real64), intent(in) :: s

    self%fraction = s
  end subroutine set_continuation

  !> Y_i = z + h sum_j a_ij K_j for the stages K (one after another in `k`).
  pure function stage_values(self, k) result(y)
    class(stage_system), intent(in) :: self
    real(real64), intent(in) :: k(:)
    real(real64) :: y(self%model%state_size, size(self%a, 1))
    integer :: i, n

    n = self%model%state_size
    y = matmul(reshape(k, [n, size(self%a, 1)]), transpose(self%a))*(self%fraction*self%h)
    do i = 1, size(self%a, 1)
      y(:, i) = self%z + y(:, i)
    end do
  end function stage_values

  !> R(K) and optionally dR/dK; stat /= 0 when a stage value is outside the model's domain.
  pure subroutine evaluate(self, x, residual, jacobian, stat)
    class(stage_system), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    real(real64), intent(out), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    real(real64) :: y(self%model%state_size, size(self%a, 1)), f(self%model%state_size)
    real(real64), allocatable :: df(:, :)     ! n x n: allocated (8 MB at 1000 unknowns)
    integer :: i, j, n, s, d

    n = self%model%state_size
    s = size(self%a, 1)
    y = self%stage_values(x)
    if (present(jacobian)) then
      jacobian = 0.0_real64
      allocate (df(n, n))
    end if
    do i = 1, s
      if (present(jacobian)) then
        call constrained_field(self%model, self%constraints, y(:, i), f, stat, df)
      else
        call constrained_field(self%model, self%constraints, y(:, i), f, stat)
      end if
      if (stat /= failure_none) return
      residual((i - 1)*n + 1:i*n) = x((i - 1)*n + 1:i*n) - f
      if (present(jacobian)) then
        do j = 1, s
          jacobian((i - 1)*n + 1:i*n, (j - 1)*n + 1:j*n) = -(self%fraction*self%h*self%a(i, j))*df
        end do
        do d = (i - 1)*n + 1, i*n
          jacobian(d, d) = jacobian(d, d) + 1.0_real64
        end do
      end if
    end do
    if (.not. all(abs(residual) <= huge(1.0_real64))) stat = domain_overflow
  end subroutine evaluate

  !> A root is acceptable when every stage value lies in the model's domain.
  pure subroutine check_root(self, x, problem_text)
    class(stage_system), intent(in) :: self
    real(real64), intent(in) :: x(:)
    character(len=:), allocatable, intent(out) :: problem_text
    real(real64) :: residual(size(x))
    integer :: stat

    problem_text = ''
    call self%evaluate(x, residual, stat=stat)
    if (stat /= failure_none) problem_text = 'a stage value lies outside the model''s domain'
  end subroutine check_root


end module collocation_stages
