!> An elastic spring's stored energy as the potentials of its one invariant C = q.q, for the
!> elastic rung (docs/formulation.md section 9): U = W(C) = mu/2 (ln(l/l0))^2, the free energy
!> (16)-(17) at theta_ref with mu = mu_eq_const, and S = 0. The discrete gradients treat it as any
!> subsystem's potentials; it has no thermodynamic variable and no temperature.
module elastic_potential
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use invariant_function, only: invariant_functions, potential_u, potential_s
  use failures, only: failure_none, domain_nonpositive_length, domain_overflow
  use free_energy, only: spring_law, mechanical_parts, mechanical_difference
  implicit none (type, external)
  private
  public :: elastic_spring, make_elastic_spring

  !> f = (W, 0) of one spring in C.
  type, extends(invariant_functions) :: elastic_spring
    type(spring_law) :: law      !! stiffness mu_eq_const, no thermal or viscous terms
  contains
    procedure :: evaluate => evaluate_elastic
    procedure :: difference => elastic_difference
    procedure :: temperature => no_temperature
    procedure :: metric_scale
  end type elastic_spring

contains

  !> Spring a of `params` as an elastic spring of stiffness mu_eq_const(a).
  pure function make_elastic_spring(params, a) result(spring)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: a
    type(elastic_spring) :: spring

    spring%law%natural_length = params%natural_length(a)
    spring%law%stiffness_ref = params%mu_eq_const(a)
    spring%law%stiffness_slope = 0.0_real64
    spring%law%beta = 0.0_real64
  end function make_elastic_spring

  !> W and 0 with gradient and Hessian in C (the mechanical part e of free_energy with only its
  !> stiffness).
  pure subroutine evaluate_elastic(self, x, f, grad, hess, stat)
    class(elastic_spring), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), grad(:, :)
    real(real64), intent(out), optional :: hess(:, :, :)
    integer, intent(out) :: stat
    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)

    f = 0.0_real64
    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    if (.not. (x(1) > 0.0_real64)) then
      stat = domain_nonpositive_length
      return
    end if
    stat = failure_none
    call mechanical_parts(self%law, x(1), 0.0_real64, e, sigma, de, dsigma, d2e, d2sigma)
    f(potential_u) = e
    grad(1, potential_u) = de(1)
    if (present(hess)) hess(1, 1, potential_u) = d2e(1, 1)
  end subroutine evaluate_elastic

  !> W(b) - W(a) without cancellation (free_energy's mechanical_difference), and 0.
  pure subroutine elastic_difference(self, a, b, delta, stat)
    class(elastic_spring), intent(in) :: self
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: delta(:)
    integer, intent(out) :: stat
    real(real64) :: delta_sigma

    delta = 0.0_real64
    if (.not. (a(1) > 0.0_real64 .and. b(1) > 0.0_real64)) then
      stat = domain_nonpositive_length
      return
    end if
    stat = failure_none
    call mechanical_difference(self%law, a(1), 0.0_real64, b(1), 0.0_real64, delta(potential_u), delta_sigma)
    delta(potential_s) = 0.0_real64
  end subroutine elastic_difference

  !> An elastic spring has no temperature: the engine never asks (a model without thermodynamic
  !> variables has no temperatures), and a caller that does is told it cannot be done.
  pure subroutine no_temperature(self, x, theta, stat)
    class(elastic_spring), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: theta
    integer, intent(out) :: stat

    theta = 0.0_real64
    stat = domain_overflow
  end subroutine no_temperature

  !> The typical size of C for the nondimensional metric: (l^0)^2.
  pure function metric_scale(self) result(scale)
    class(elastic_spring), intent(in) :: self
    real(real64) :: scale(1)

    scale = self%law%natural_length**2
  end function metric_scale

end module elastic_potential
