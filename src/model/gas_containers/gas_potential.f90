!> The internal energy and entropy (U_a, S_a) of one gas container of the two-gas-containers
!> benchmark (docs/formulation.md section 8) as functions of its invariants x = (v, tau): the
!> container's volume v (q for the first, 2 - q for the second) and its thermodynamic variable.
!> In entropy variables U = (e^s/v)^(2/3) and S = s, so theta = dU/ds = 2U/3; in temperature
!> variables U = 3 theta/2 and S = ln v + (3/2) ln(3 theta/2); in internal-energy variables U = u
!> and S = ln v + (3/2) ln u (an ideal monatomic gas, nondimensional).
module gas_potential
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions, potential_u, potential_s
  use failures, only: failure_none, domain_nonpositive_length, domain_nonpositive_temperature, domain_overflow
  use thermo_variable_kinds, only: tau_entropy, tau_temperature, tau_internal_energy
  implicit none (type, external)
  private
  public :: container_potential

  !> (U, S) of a container in thermodynamic variable `variable` (thermo_variable_kinds' tau_*).
  type, extends(invariant_functions) :: container_potential
    integer :: variable = tau_entropy
  contains
    procedure :: evaluate
    procedure :: temperature
    procedure :: tau_from_temperature
  end type container_potential

  ! Largest argument of exp that stays finite, with a margin.
  real(real64), parameter :: max_exponent = 0.9_real64*log(huge(1.0_real64))

contains

  !> f = (U, S), their gradients in (v, tau) and optionally their Hessians.
  pure subroutine evaluate(self, x, f, grad, hess, stat)
    class(container_potential), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), grad(:, :)
    real(real64), intent(out), optional :: hess(:, :, :)
    integer, intent(out) :: stat
    real(real64) :: v, tau, exponent, u

    f = 0.0_real64
    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    v = x(1)
    tau = x(2)
    stat = failure_none
    if (.not. (v > 0.0_real64)) then
      stat = domain_nonpositive_length
      return
    end if
    select case (self%variable)
    case (tau_entropy)
      exponent = (2.0_real64/3.0_real64)*(tau - log(v))
      if (exponent > max_exponent) then
        stat = domain_overflow
        return
      end if
      u = exp(exponent)
      f = [u, tau]
      grad(:, potential_u) = [-(2.0_real64/3.0_real64)*u/v, (2.0_real64/3.0_real64)*u]
      grad(:, potential_s) = [0.0_real64, 1.0_real64]
      if (present(hess)) then
        hess(1, 1, potential_u) = (10.0_real64/9.0_real64)*u/v**2
        hess(1, 2, potential_u) = -(4.0_real64/9.0_real64)*u/v
        hess(2, 1, potential_u) = hess(1, 2, potential_u)
        hess(2, 2, potential_u) = (4.0_real64/9.0_real64)*u
      end if
    case (tau_temperature, tau_internal_energy)
      if (.not. (tau > 0.0_real64)) then
        stat = domain_nonpositive_temperature
        return
      end if
      if (self%variable == tau_temperature) then
        f = [1.5_real64*tau, log(v) + 1.5_real64*log(1.5_real64*tau)]
        grad(:, potential_u) = [0.0_real64, 1.5_real64]
      else
        f = [tau, log(v) + 1.5_real64*log(tau)]
        grad(:, potential_u) = [0.0_real64, 1.0_real64]
      end if
      grad(:, potential_s) = [1.0_real64/v, 1.5_real64/tau]
      if (present(hess)) then
        hess(1, 1, potential_s) = -1.0_real64/v**2
        hess(2, 2, potential_s) = -1.5_real64/tau**2
      end if
    end select
  end subroutine evaluate

  !> theta = dU/dtau / dS/dtau in closed form: 2U/3 (entropy), theta, 2u/3.
  pure subroutine temperature(self, x, theta, stat)
    class(container_potential), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: theta
    integer, intent(out) :: stat
    real(real64) :: f(2), grad(2, 2)

    call self%evaluate(x, f, grad, stat=stat)
    theta = 0.0_real64
    if (stat /= failure_none) return
    select case (self%variable)
    case (tau_entropy, tau_internal_energy)
      theta = (2.0_real64/3.0_real64)*f(potential_u)
    case default
      theta = x(2)
    end select
    if (.not. (theta > 0.0_real64)) stat = domain_nonpositive_temperature
  end subroutine temperature

  !> tau at volume mechanical(1) and temperature theta: s = ln v + (3/2) ln(3 theta/2), theta, or
  !> u = 3 theta/2.
  pure subroutine tau_from_temperature(self, mechanical, theta, tau, stat)
    class(container_potential), intent(in) :: self
    real(real64), intent(in) :: mechanical(:)
    real(real64), intent(in) :: theta
    real(real64), intent(out) :: tau
    integer, intent(out) :: stat

    tau = 0.0_real64
    stat = failure_none
    if (.not. (mechanical(1) > 0.0_real64)) then
      stat = domain_nonpositive_length
      return
    end if
    if (.not. (theta > 0.0_real64)) then
      stat = domain_nonpositive_temperature
      return
    end if
    select case (self%variable)
    case (tau_entropy)
      tau = log(mechanical(1)) + 1.5_real64*log(1.5_real64*theta)
    case (tau_temperature)
      tau = theta
    case default
      tau = 1.5_real64*theta
    end select
  end subroutine tau_from_temperature

end module gas_potential
