!> Free energies (16)-(17) of the two springs in closed form (docs/formulation.md section 3): the
!> mechanical parts e_a and sigma_a as functions of the invariant C = q.q (and gamma), with
!> gradient and Hessian, and eta(theta) of eq. (17).
!> u_a = e_a + Cap_a (theta - theta_ref) and s_a = sigma_a + Cap_a ln(theta/theta_ref);
!> tests/unit/test_free_energy checks this against psi as the paper writes it
!> (tests/oracles/paper_free_energy) by s = -d psi/d theta, u = psi + theta s.
!> Test support: the hand-derived reference; the programs run the generated element of the paper's
!> spring (src/model/paper_spring/description.py).
module free_energy
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use special_functions, only: log1p
  implicit none (type, external)
  private
  public :: spring_law, spring_law_of, mechanical_parts, mechanical_parts_at, mechanical_difference
  public :: mechanical_difference_at, viscosity

  !> Coefficients of spring a's closed forms (docs/formulation.md section 3). Spring 1 has no Maxwell
  !> element: its beta_v, maxwell_ref and maxwell_slope are zero, so one formula serves both.
  type :: spring_law
    real(real64) :: natural_length = 1.0_real64  !! l_a^0
    real(real64) :: stiffness_ref = 0.0_real64   !! a_a = mu_{a,cst} + mu_{a,theta} theta_ref
    real(real64) :: stiffness_slope = 0.0_real64 !! mu_{a,theta}
    real(real64) :: beta = 0.0_real64            !! beta
    real(real64) :: theta_ref = 1.0_real64       !! theta_ref
    real(real64) :: beta_v = 0.0_real64          !! beta^v (spring 2 only)
    real(real64) :: maxwell_ref = 0.0_real64     !! A = mu^neq_cst + mu^neq_theta theta_ref (spring 2 only)
    real(real64) :: maxwell_slope = 0.0_real64   !! mu^neq_theta (spring 2 only)
    real(real64) :: heat_capacity = 1.0_real64   !! Cap_a: c_1, or (1 + beta^v) c_2
  end type spring_law

contains

  !> The closed-form coefficients of spring `a` (1 or 2).
  pure function spring_law_of(params, a) result(law)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: a
    type(spring_law) :: law

    law%natural_length = params%natural_length(a)
    law%stiffness_ref = params%mu_eq_const(a) + params%mu_eq_slope(a)*params%theta_ref
    law%stiffness_slope = params%mu_eq_slope(a)
    law%beta = params%beta
    law%theta_ref = params%theta_ref
    if (a == 2 .and. params%viscous()) then
      law%beta_v = params%beta_v
      law%maxwell_ref = params%mu_neq_const + params%mu_neq_slope*params%theta_ref
      law%maxwell_slope = params%mu_neq_slope
    end if
    law%heat_capacity = (1.0_real64 + law%beta_v)*params%heat_capacity(a)
  end function spring_law_of

  !> e_a and sigma_a with gradients and Hessians in (C, gamma), C = l^2 > 0 (docs/formulation.md section 3).
  pure subroutine mechanical_parts(law, c, gamma, e, sigma, de, dsigma, d2e, d2sigma)
    type(spring_law), intent(in) :: law
    real(real64), intent(in) :: c, gamma
    real(real64), intent(out) :: e, sigma
    real(real64), intent(out) :: de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)

    ! L = ln(l/l0) = ln(C/l0^2)/2 and r = 1/l = C^(-1/2).
    call mechanical_parts_at(law, c, 0.5_real64*log(c/law%natural_length**2), 1.0_real64/sqrt(c), gamma, &
                             e, sigma, de, dsigma, d2e, d2sigma)
  end subroutine mechanical_parts

  !> mechanical_parts for a caller that already has L = ln(l/l0) and r = 1/l at C (a caller
  !> shares them between the values, gradients and differences it needs).
  pure subroutine mechanical_parts_at(law, c, log_stretch, inv_length, gamma, e, sigma, de, dsigma, d2e, d2sigma)
    type(spring_law), intent(in) :: law
    real(real64), intent(in) :: c, log_stretch, inv_length, gamma
    real(real64), intent(out) :: e, sigma
    real(real64), intent(out) :: de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)
    real(real64) :: dlog, d2log, dinv, d2inv

    ! The C-derivatives of L and r.
    dlog = 0.5_real64/c
    d2log = -0.5_real64/c**2
    dinv = -0.5_real64*inv_length/c
    d2inv = 0.75_real64*inv_length/c**2

    ! e uses (a, beta theta_ref, A); sigma uses (mu_theta, beta, mu^neq_theta).
    call spring_part(law%stiffness_ref, law%beta*law%theta_ref, law%maxwell_ref, e, de, d2e)
    call spring_part(law%stiffness_slope, law%beta, law%maxwell_slope, sigma, dsigma, d2sigma)

  contains

    !> (1+bv)(k/2 L^2 + b L) + m gamma^2 - bv gamma (k L + b)/l, the common shape of e and sigma.
    pure subroutine spring_part(k, b, m, value, grad, hess)
      real(real64), intent(in) :: k, b, m
      real(real64), intent(out) :: value, grad(2), hess(2, 2)
      real(real64) :: slope, h, dh, d2h, bv

      bv = law%beta_v
      slope = k*log_stretch + b                       ! d/dL of k/2 L^2 + b L
      h = slope*inv_length                            ! (k L + b)/l
      dh = k*dlog*inv_length + slope*dinv
      d2h = k*d2log*inv_length + 2.0_real64*k*dlog*dinv + slope*d2inv

      value = (1.0_real64 + bv)*(0.5_real64*k*log_stretch**2 + b*log_stretch) &
              + m*gamma**2 - bv*gamma*h
      grad(1) = (1.0_real64 + bv)*slope*dlog - bv*gamma*dh
      grad(2) = 2.0_real64*m*gamma - bv*h
      hess(1, 1) = (1.0_real64 + bv)*(k*dlog**2 + slope*d2log) - bv*gamma*d2h
      hess(1, 2) = -bv*dh
      hess(2, 1) = hess(1, 2)
      hess(2, 2) = 2.0_real64*m
    end subroutine spring_part
  end subroutine mechanical_parts_at

  !> e(b) - e(a) and sigma(b) - sigma(a) for invariants (C, gamma) at a and b, computed without
  !> cancellation: ln(C_b/C_a) by log1p, L_b^2 - L_a^2 as (L_a + L_b) dL, 1/l_b - 1/l_a in closed
  !> form. The plain difference of two values of size |e| loses eps |e| / |e(b) - e(a)| of its
  !> digits, which the discrete gradients' quotients would divide by |b - a| again.
  pure subroutine mechanical_difference(law, c_a, gamma_a, c_b, gamma_b, delta_e, delta_sigma)
    type(spring_law), intent(in) :: law
    real(real64), intent(in) :: c_a, gamma_a, c_b, gamma_b
    real(real64), intent(out) :: delta_e, delta_sigma
    real(real64) :: inv_a, inv_b

    inv_a = 1.0_real64/sqrt(c_a)
    inv_b = 1.0_real64/sqrt(c_b)
    call mechanical_difference_at(law, 0.5_real64*log(c_a/law%natural_length**2), 0.5_real64*log1p((c_b - c_a)/c_a), &
                                  inv_b, -(c_b - c_a)*inv_a*inv_b/(sqrt(c_a) + sqrt(c_b)), gamma_a, gamma_b, &
                                  delta_e, delta_sigma)
  end subroutine mechanical_difference

  !> mechanical_difference for a caller that already has L_a = ln(l_a/l0), dL = L_b - L_a (by
  !> log1p), r_b = 1/l_b and dr = r_b - r_a (in closed form).
  pure subroutine mechanical_difference_at(law, log_a, delta_log, inv_b, delta_inv, gamma_a, gamma_b, delta_e, delta_sigma)
    type(spring_law), intent(in) :: law
    real(real64), intent(in) :: log_a, delta_log, inv_b, delta_inv, gamma_a, gamma_b
    real(real64), intent(out) :: delta_e, delta_sigma
    real(real64) :: log_b, delta_gamma

    log_b = log_a + delta_log
    delta_gamma = gamma_b - gamma_a
    delta_e = part_difference(law%stiffness_ref, law%beta*law%theta_ref, law%maxwell_ref)
    delta_sigma = part_difference(law%stiffness_slope, law%beta, law%maxwell_slope)

  contains

    ! Difference of (1+bv)(k/2 L^2 + b L) + m gamma^2 - bv gamma (k L + b)/l, term by term.
    pure real(real64) function part_difference(k, b, m)
      real(real64), intent(in) :: k, b, m
      real(real64) :: slope_a, slope_b

      slope_a = k*log_a + b
      slope_b = k*log_b + b
      part_difference = (1.0_real64 + law%beta_v)*(0.5_real64*k*(log_a + log_b) + b)*delta_log &
                        + m*(gamma_a + gamma_b)*delta_gamma &
                        - law%beta_v*(delta_gamma*slope_b*inv_b + gamma_a*(k*delta_log*inv_b + slope_a*delta_inv))
    end function part_difference
  end subroutine mechanical_difference_at

  !> eta(theta) = eta_cst exp(eta_theta (1/theta - 1/theta_ref)), eq. (17).
  pure function viscosity(params, theta) result(eta)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: theta
    real(real64) :: eta

    eta = params%viscosity_const*exp(params%viscosity_activation*(1.0_real64/theta - 1.0_real64/params%theta_ref))
  end function viscosity

end module free_energy
