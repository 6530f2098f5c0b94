!> The spring potentials U_a and S_a as functions of the invariants x = (C, [gamma,] tau_a),
!> for each choice of the thermodynamic variable tau (docs/formulation.md section 3, table).
!> Spring 1 has n = 2 invariants (C1, tau1), spring 2 has n = 3 (C2, gamma, tau2).
!> Test support: the hand-derived reference the unit tests check the generated springs against; the
!> programs (and the fused step kernel) run the generated element of the paper's spring
!> (src/model/paper_spring/description.py).
module thermo_variable
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions, potential_u, potential_s
  use failures, only: failure_none, domain_nonpositive_length, domain_nonpositive_temperature, domain_overflow
  use free_energy, only: spring_law, mechanical_parts, mechanical_difference
  use special_functions, only: log1p, expm1
  use thermo_variable_kinds, only: tau_entropy, tau_temperature, tau_internal_energy
  implicit none (type, external)
  private
  public :: spring_potential, temperature_of, potentials_from_parts, difference_from_parts

  !> f = (U_a, S_a) of one spring in its invariants.
  type, extends(invariant_functions) :: spring_potential
    type(spring_law) :: law
    integer :: variable = tau_temperature
    integer :: n_invariants = 2   !! 2 for spring 1, 3 for spring 2
  contains
    procedure :: evaluate => evaluate_potentials
    procedure :: difference => potential_difference
    procedure :: temperature => spring_temperature
    procedure :: values_and_temperature => spring_values_and_temperature
    procedure :: tau_from_temperature
    procedure :: metric_scale
  end type spring_potential

  ! Largest argument of exp that stays finite, with a margin.
  real(real64), parameter :: max_exponent = 0.9_real64*log(huge(1.0_real64))

contains

  !> theta(x) in closed form, from the table in docs/formulation.md section 3 (it equals eq. (2)'s
  !> d_tau U / d_tau S, which the tests check); stat reports a domain violation.
  pure subroutine spring_temperature(self, x, theta, stat)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: theta
    integer, intent(out) :: stat
    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)

    call mechanical_state(self, x, e, sigma, de, dsigma, d2e, d2sigma, stat)
    if (stat /= failure_none) then
      theta = 0.0_real64
      return
    end if
    call temperature_of(self, x(self%n_invariants), e, sigma, theta, stat)
  end subroutine spring_temperature

  !> (U_a, S_a) and the temperature at x from one evaluation of the mechanical parts (a run
  !> observes them every step; evaluate and temperature would compute the parts twice), and
  !> optionally their rounding scales (invariant_function), the sizes of the terms each is summed
  !> from. A state's temperature is known to eps theta, whatever variable carries it (stored as
  !> tau = theta, given by exp from tau = s, summed onto theta_ref from tau = u, or converted from
  !> the variable a scheme integrates in), so Cap (theta - theta_ref) is known to Cap theta eps and
  !> Cap ln(theta/theta_ref) to Cap eps: U_a's scale is |e| + Cap (theta + theta_ref), S_a's is
  !> |sigma| + Cap (1 + |ln(theta/theta_ref)|) (docs/faults.md, Every accepted step checked), with
  !> Cap |ln(theta/theta_ref)| read as |S_a - sigma| (S_a = sigma + Cap ln(theta/theta_ref) in
  !> every variable), not from a second logarithm.
  pure subroutine spring_values_and_temperature(self, x, f, theta, stat, scales)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), theta
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: scales(:)
    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2), grad(size(x), 2), cap

    theta = 0.0_real64
    f = 0.0_real64
    if (present(scales)) scales = 0.0_real64
    call mechanical_state(self, x, e, sigma, de, dsigma, d2e, d2sigma, stat)
    if (stat /= failure_none) return
    call temperature_of(self, x(self%n_invariants), e, sigma, theta, stat)
    if (stat /= failure_none) return
    call potentials_from_parts(self, x(self%n_invariants), theta, e, sigma, de, dsigma, d2e, d2sigma, grad, f=f)
    if (present(scales)) then
      cap = self%law%heat_capacity
      scales(potential_u) = abs(e) + cap*(theta + self%law%theta_ref)
      scales(potential_s) = abs(sigma) + cap + abs(f(potential_s) - sigma)
    end if
  end subroutine spring_values_and_temperature

  !> U_a and S_a with gradients and Hessians in x (docs/formulation.md section 3, table).
  pure subroutine evaluate_potentials(self, x, f, grad, hess, stat)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), grad(:, :)
    real(real64), intent(out), optional :: hess(:, :, :)
    integer, intent(out) :: stat

    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2), theta

    f = 0.0_real64
    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    call mechanical_state(self, x, e, sigma, de, dsigma, d2e, d2sigma, stat)
    if (stat /= failure_none) return
    call temperature_of(self, x(self%n_invariants), e, sigma, theta, stat)
    if (stat /= failure_none) return
    call potentials_from_parts(self, x(self%n_invariants), theta, e, sigma, de, dsigma, d2e, d2sigma, grad, hess, f)
  end subroutine evaluate_potentials

  !> The table of docs/formulation.md section 3 from the mechanical parts e, sigma (with their (C, gamma)
  !> derivatives) and the temperature theta at invariants x = (C, [gamma,] tau): the gradient,
  !> optionally the Hessian and the values of (U_a, S_a).
  pure subroutine potentials_from_parts(self, tau, theta, e, sigma, de, dsigma, d2e, d2sigma, grad, hess, f)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: tau, theta, e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)
    real(real64), intent(out) :: grad(:, :)
    real(real64), intent(out), optional :: hess(:, :, :), f(:)
    real(real64) :: cap
    integer :: n, m

    n = self%n_invariants
    m = n - 1                        ! mechanical invariants: C, or (C, gamma)
    grad = 0.0_real64
    if (present(hess)) hess = 0.0_real64
    cap = self%law%heat_capacity

    select case (self%variable)
    case (tau_temperature)
      if (present(f)) then
        f(potential_u) = e + cap*(tau - self%law%theta_ref)
        f(potential_s) = sigma + cap*log(tau/self%law%theta_ref)
      end if
      grad(1:m, potential_u) = de(1:m)
      grad(n, potential_u) = cap
      grad(1:m, potential_s) = dsigma(1:m)
      grad(n, potential_s) = cap/tau
      if (present(hess)) then
        hess(1:m, 1:m, potential_u) = d2e(1:m, 1:m)
        hess(1:m, 1:m, potential_s) = d2sigma(1:m, 1:m)
        hess(n, n, potential_s) = -cap/tau**2
      end if
    case (tau_entropy)
      ! theta = theta_ref exp((tau - sigma)/Cap), so d theta = theta (d tau - d sigma)/Cap.
      if (present(f)) then
        f(potential_u) = e + cap*(theta - self%law%theta_ref)
        f(potential_s) = tau
      end if
      grad(1:m, potential_u) = de(1:m) - theta*dsigma(1:m)
      grad(n, potential_u) = theta
      grad(n, potential_s) = 1.0_real64
      if (present(hess)) then
        hess(1:m, 1:m, potential_u) = d2e(1:m, 1:m) - theta*d2sigma(1:m, 1:m) &
                                      + (theta/cap)*outer(dsigma(1:m), dsigma(1:m))
        hess(1:m, n, potential_u) = -(theta/cap)*dsigma(1:m)
        hess(n, 1:m, potential_u) = hess(1:m, n, potential_u)
        hess(n, n, potential_u) = theta/cap
      end if
    case (tau_internal_energy)
      ! theta = theta_ref + (tau - e)/Cap, so d theta = (d tau - d e)/Cap.
      if (present(f)) then
        f(potential_u) = tau
        f(potential_s) = sigma + cap*log(theta/self%law%theta_ref)
      end if
      grad(n, potential_u) = 1.0_real64
      grad(1:m, potential_s) = dsigma(1:m) - de(1:m)/theta
      grad(n, potential_s) = 1.0_real64/theta
      if (present(hess)) then
        hess(1:m, 1:m, potential_s) = d2sigma(1:m, 1:m) - d2e(1:m, 1:m)/theta &
                                      - outer(de(1:m), de(1:m))/(cap*theta**2)
        hess(1:m, n, potential_s) = de(1:m)/(cap*theta**2)
        hess(n, 1:m, potential_s) = hess(1:m, n, potential_s)
        hess(n, n, potential_s) = -1.0_real64/(cap*theta**2)
      end if
    end select
  end subroutine potentials_from_parts

  !> U(b) - U(a) and S(b) - S(a) without cancellation (docs/formulation.md section 3 table, term by
  !> term): the mechanical parts by `mechanical_difference`, ln(theta_b/theta_a) by log1p, and
  !> theta_b - theta_a by expm1 for tau = s.
  pure subroutine potential_difference(self, a, b, delta, stat)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: delta(:)
    integer, intent(out) :: stat
    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)
    real(real64) :: delta_e, delta_sigma, theta_a, theta_b, delta_theta, gamma_a, gamma_b
    integer :: n

    n = self%n_invariants
    delta = 0.0_real64
    call mechanical_state(self, a, e, sigma, de, dsigma, d2e, d2sigma, stat)
    if (stat /= failure_none) return
    call temperature_of(self, a(n), e, sigma, theta_a, stat)
    if (stat /= failure_none) return
    call self%temperature(b, theta_b, stat)
    if (stat /= failure_none) return
    gamma_a = 0.0_real64
    gamma_b = 0.0_real64
    if (n == 3) then
      gamma_a = a(2)
      gamma_b = b(2)
    end if
    call mechanical_difference(self%law, a(1), gamma_a, b(1), gamma_b, delta_e, delta_sigma)
    call difference_from_parts(self, a(n), b(n) - a(n), theta_a, delta_e, delta_sigma, delta, delta_theta)
  end subroutine potential_difference

  !> The table's differences U(b) - U(a), S(b) - S(a) term by term from tau_a, tau_b - tau_a,
  !> theta_a and the mechanical differences; also theta_b - theta_a.
  pure subroutine difference_from_parts(self, tau_a, delta_tau, theta_a, delta_e, delta_sigma, delta, delta_theta)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: tau_a, delta_tau, theta_a, delta_e, delta_sigma
    real(real64), intent(out) :: delta(:), delta_theta
    real(real64) :: cap

    cap = self%law%heat_capacity
    select case (self%variable)
    case (tau_temperature)
      delta_theta = delta_tau
      delta(potential_u) = delta_e + cap*delta_tau
      delta(potential_s) = delta_sigma + cap*log1p(delta_tau/tau_a)
    case (tau_entropy)
      delta_theta = theta_a*expm1((delta_tau - delta_sigma)/cap)
      delta(potential_u) = delta_e + cap*delta_theta
      delta(potential_s) = delta_tau
    case default
      delta_theta = (delta_tau - delta_e)/cap
      delta(potential_u) = delta_tau
      delta(potential_s) = delta_sigma + cap*log1p(delta_theta/theta_a)
    end select
  end subroutine difference_from_parts

  !> The value of tau that gives temperature theta at mechanical invariants (C, [gamma]).
  pure subroutine tau_from_temperature(self, mechanical, theta, tau, stat)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: mechanical(:)   !! C, or (C, gamma)
    real(real64), intent(in) :: theta
    real(real64), intent(out) :: tau
    integer, intent(out) :: stat
    real(real64) :: x(3), e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)

    tau = 0.0_real64
    if (theta <= 0.0_real64) then
      stat = domain_nonpositive_temperature
      return
    end if
    x = 0.0_real64
    x(1:self%n_invariants - 1) = mechanical(1:self%n_invariants - 1)
    call mechanical_state(self, x(1:self%n_invariants), e, sigma, de, dsigma, d2e, d2sigma, stat)
    if (stat /= failure_none) return
    select case (self%variable)
    case (tau_temperature)
      tau = theta
    case (tau_entropy)
      tau = sigma + self%law%heat_capacity*log(theta/self%law%theta_ref)
    case (tau_internal_energy)
      tau = e + self%law%heat_capacity*(theta - self%law%theta_ref)
    end select
  end subroutine tau_from_temperature

  !> Typical sizes of the invariants, for the nondimensional discrete-gradient metric
  !> (docs/formulation.md section 5): C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref.
  pure function metric_scale(self) result(scale)
    class(spring_potential), intent(in) :: self
    real(real64) :: scale(self%n_invariants)
    integer :: n

    n = self%n_invariants
    if (n < 2) return          ! (never: a spring has C and tau; says so to the optimizer)
    scale(1) = self%law%natural_length**2
    if (n == 3) scale(2) = 1.0_real64
    select case (self%variable)
    case (tau_temperature)
      scale(n) = self%law%theta_ref
    case (tau_entropy)
      scale(n) = self%law%heat_capacity
    case default
      scale(n) = self%law%heat_capacity*self%law%theta_ref
    end select
  end function metric_scale

  ! e, sigma and their (C, gamma) derivatives at x; gamma = 0 for spring 1.
  pure subroutine mechanical_state(self, x, e, sigma, de, dsigma, d2e, d2sigma, stat)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)
    integer, intent(out) :: stat
    real(real64) :: gamma

    if (.not. (x(1) > 0.0_real64)) then
      stat = domain_nonpositive_length
      e = 0.0_real64; sigma = 0.0_real64; de = 0.0_real64; dsigma = 0.0_real64
      d2e = 0.0_real64; d2sigma = 0.0_real64
      return
    end if
    gamma = 0.0_real64
    if (self%n_invariants == 3) gamma = x(2)
    call mechanical_parts(self%law, x(1), gamma, e, sigma, de, dsigma, d2e, d2sigma)
    stat = failure_none
  end subroutine mechanical_state

  !> theta from tau and the mechanical parts e, sigma (table of docs/formulation.md section 3).
  pure subroutine temperature_of(self, tau, e, sigma, theta, stat)
    class(spring_potential), intent(in) :: self
    real(real64), intent(in) :: tau, e, sigma
    real(real64), intent(out) :: theta
    integer, intent(out) :: stat
    real(real64) :: exponent

    stat = failure_none
    select case (self%variable)
    case (tau_temperature)
      theta = tau
    case (tau_entropy)
      exponent = (tau - sigma)/self%law%heat_capacity
      if (exponent > max_exponent) then
        theta = huge(1.0_real64)
        stat = domain_overflow
        return
      end if
      theta = self%law%theta_ref*exp(exponent)
    case default
      theta = self%law%theta_ref + (tau - e)/self%law%heat_capacity
    end select
    if (.not. (theta > 0.0_real64)) stat = domain_nonpositive_temperature
  end subroutine temperature_of

  pure function outer(a, b) result(ab)
    real(real64), intent(in) :: a(:), b(:)
    real(real64) :: ab(size(a), size(b))
    integer :: j

    do j = 1, size(b)
      ab(:, j) = a*b(j)
    end do
  end function outer

end module thermo_variable
