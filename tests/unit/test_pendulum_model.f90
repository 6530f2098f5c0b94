!> The double pendulum's continuous vector field against magnitudes typed from the paper, so
!> that a parameter reaching the physics doubled, divided or with the wrong sign fails here:
!>  - Fourier's law (12): the heat power into spring a at rest is kappa (theta_b - theta_a);
!>  - the viscous rate (12), (17): dgamma/dt = -(1/eta(theta_2)) d psi_2/d gamma, with
!>    eta(theta) = eta_cst exp(eta_theta (1/theta - 1/theta_ref)) and psi_2 as the paper writes it;
!>  - the mass matrix (1) with m1 /= m2: T = 1/2 qdot.m qdot and m^-1 p;
!>  - gravity: from rest, unstretched and at theta_ref, both masses accelerate along g;
!>  - the thermodynamic force at rest: dp_a/dt = -(d psi_a/d l_a) q_a/l_a (+ gravity).
!> Every expected value is computed here from Table 1's numbers and the paper's formulas, not
!> from the model's code; psi is the paper's literal transcription (oracles/paper_free_energy).
program test_pendulum_model
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use paper_free_energy, only: paper_psi
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  use double_pendulum, only: state_size, p_index, gamma_index, tau_index, kinetic_energy, &
                             inverse_mass_times, gravity_potential
  implicit none (type, external)

  ! Table 1 of the paper, typed here independently of model_parameters.
  real(real64), parameter :: kappa = 1.0_real64                  ! [J/(K s)]
  real(real64), parameter :: heat_capacity_1 = 10.0_real64       ! c_1 [J/K]
  real(real64), parameter :: eta_cst = 100.0_real64, eta_theta = 10.0_real64, theta_ref = 300.0_real64
  real(real64), parameter :: g_paper(3) = [0.0_real64, 0.0_real64, -9.81_real64]
  real(real64), parameter :: natural_length(2) = [1.5_real64, 2.0_real64]

  call run_unit_tests('test_pendulum_model', [ &
    unit_test('heat_flux_at_rest', heat_flux_at_rest), &
    unit_test('viscous_rate', viscous_rate), &
    unit_test('unequal_masses', unequal_masses), &
    unit_test('gravity_direction', gravity_direction), &
    unit_test('spring_force_at_rest', spring_force_at_rest)])

contains

  ! The field f at z with the exact partials of the model.
  function field(model, z) result(f)
    type(pendulum), intent(in) :: model
    real(real64), intent(in) :: z(state_size)
    real(real64) :: f(state_size), partials(3, 2, 2)
    integer :: stat

    call model%exact_partials(z, partials, stat=stat)
    if (stat /= 0) error stop 'test_pendulum_model: state outside the domain'
    call model%vector_field(z, partials, f)
  end function field

  ! A state at rest (p = 0) with the given positions, gamma and temperatures.
  function state_at_rest(model, q1, q2, gamma, theta) result(z)
    type(pendulum), intent(in) :: model
    real(real64), intent(in) :: q1(3), q2(3), gamma, theta(2)
    real(real64) :: z(state_size)
    integer :: stat

    call model%state_from_temperatures(q1, q2, [0.0_real64, 0.0_real64, 0.0_real64], &
                                       [0.0_real64, 0.0_real64, 0.0_real64], gamma, theta, z, stat)
    if (stat /= 0) error stop 'test_pendulum_model: state outside the domain'
  end function state_at_rest

  ! dU_1/dtau_1 at temperature theta_1, from the table of FORMULATION section 3: c_1 for
  ! tau = theta (U = e + c (theta - theta_ref)), theta for tau = s, 1 for tau = u.
  pure function du1_dtau1(variable, theta_1) result(slope)
    integer, intent(in) :: variable
    real(real64), intent(in) :: theta_1
    real(real64) :: slope

    select case (variable)
    case (tau_temperature)
      slope = heat_capacity_1
    case (tau_entropy)
      slope = theta_1
    case default
      slope = 1.0_real64
    end select
  end function du1_dtau1

  !> Fourier's law between the springs, eq. (12) with K0's conduction block: at rest the heat
  !> power into spring 1 is kappa (theta_2 - theta_1), in every thermodynamic variable.
  subroutine heat_flux_at_rest(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z(state_size), f(state_size), theta(2)
    integer :: variable

    theta = [280.0_real64, 350.0_real64]
    do variable = tau_entropy, tau_internal_energy
      model = make_pendulum(params, variable)
      z = state_at_rest(model, [1.2_real64, 0.3_real64, -0.4_real64], [0.5_real64, 2.1_real64, 0.2_real64], &
                        0.05_real64, theta)
      f = field(model, z)
      call suite%check_close('heat power into spring 1 = kappa (theta_2 - theta_1) = 70 W, '// &
                             trim(thermo_variable_names(variable)), [du1_dtau1(variable, theta(1))*f(tau_index(1))], &
                             [kappa*(theta(2) - theta(1))], rtol=1.0e-12_real64)
    end do
  end subroutine heat_flux_at_rest

  !> The viscous rate of eqs. (12) and (17): dgamma/dt = -(1/eta(theta_2)) d psi_2/d gamma.
  subroutine viscous_rate(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z(state_size), f(state_size), q2(3), length, gamma, theta_2, eta, h, dpsi_dgamma
    integer :: variable, trial

    do trial = 1, 3
      q2 = [2.4_real64, -0.3_real64, 0.1_real64*trial]
      length = norm2(q2)
      gamma = 0.1_real64*trial - 0.15_real64
      theta_2 = 250.0_real64 + 40.0_real64*trial
      eta = eta_cst*exp(eta_theta*(1.0_real64/theta_2 - 1.0_real64/theta_ref))
      h = 1.0e-4_real64
      dpsi_dgamma = (-paper_psi(params, 2, length, theta_2, gamma + 2*h) + 8*paper_psi(params, 2, length, theta_2, gamma + h) &
                     - 8*paper_psi(params, 2, length, theta_2, gamma - h) &
                     + paper_psi(params, 2, length, theta_2, gamma - 2*h))/(12*h)
      do variable = tau_entropy, tau_internal_energy
        model = make_pendulum(params, variable)
        z = state_at_rest(model, [1.0_real64, 0.0_real64, 0.0_real64], q2, gamma, [300.0_real64, theta_2])
        f = field(model, z)
        call suite%check_close('dgamma/dt = -(1/eta(theta_2)) dpsi_2/dgamma, '// &
                               trim(thermo_variable_names(variable)), [f(gamma_index)], [-dpsi_dgamma/eta], &
                               rtol=1.0e-9_real64)
      end do
    end do
  end subroutine viscous_rate

  !> Eq. (1) with m1 = 1 kg and m2 = 2.5 kg: p = m qdot with m = [[(m1+m2) I, m2 I], [m2 I, m2 I]]
  !> gives back qdot = m^-1 p, and T = 1/2 qdot.m qdot.
  subroutine unequal_masses(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    real(real64) :: qdot(3, 2), p(3, 2), z(state_size)
    real(real64), parameter :: m1 = 1.0_real64, m2 = 2.5_real64

    params%mass = [m1, m2]
    qdot(:, 1) = [0.3_real64, -1.2_real64, 0.7_real64]
    qdot(:, 2) = [-0.8_real64, 0.4_real64, 1.5_real64]
    p(:, 1) = (m1 + m2)*qdot(:, 1) + m2*qdot(:, 2)
    p(:, 2) = m2*qdot(:, 1) + m2*qdot(:, 2)
    call suite%check_close('m^-1 p = qdot with m1 /= m2', reshape(inverse_mass_times(params, p), [6]), &
                           reshape(qdot, [6]), rtol=1.0e-14_real64, atol=1.0e-15_real64)
    z = 0.0_real64
    z(p_index(:, 1)) = p(:, 1)
    z(p_index(:, 2)) = p(:, 2)
    call suite%check_close('T = 1/2 qdot.m qdot with m1 /= m2', [kinetic_energy(params, z)], &
                           [0.5_real64*sum(qdot*p)], rtol=1.0e-14_real64)
  end subroutine unequal_masses

  !> Unstretched springs at theta_ref with gamma = 0 exert no force (psi's l-derivative vanishes
  !> there), so from rest dp_1/dt = (m1 + m2) g and dp_2/dt = m2 g, and both masses accelerate
  !> with g: the absolute accelerations are m^-1 pdot for m1 and the sum for m2. Also
  !> V_g = -(m1 + m2) g.q1 - m2 g.q2.
  subroutine gravity_direction(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z(state_size), f(state_size), pdot(3, 2), acceleration(3, 2), q1(3), q2(3)
    real(real64), parameter :: m1 = 1.0_real64, m2 = 1.0_real64

    model = make_pendulum(params, tau_temperature)
    q1 = natural_length(1)*[0.6_real64, 0.0_real64, -0.8_real64]
    q2 = natural_length(2)*[0.0_real64, 0.6_real64, -0.8_real64]
    z = state_at_rest(model, q1, q2, 0.0_real64, [theta_ref, theta_ref])
    f = field(model, z)
    pdot = reshape(f(p_index(1, 1):p_index(3, 2)), [3, 2])
    call suite%check_close('dp_1/dt = (m1 + m2) g from rest', pdot(:, 1), (m1 + m2)*g_paper, atol=1.0e-12_real64)
    call suite%check_close('dp_2/dt = m2 g from rest', pdot(:, 2), m2*g_paper, atol=1.0e-12_real64)
    acceleration = inverse_mass_times(params, pdot)
    call suite%check_close('m1 accelerates along g', acceleration(:, 1), g_paper, atol=1.0e-12_real64)
    call suite%check_close('m2 accelerates along g', acceleration(:, 1) + acceleration(:, 2), g_paper, &
                           atol=1.0e-12_real64)
    call suite%check_close('V_g = -(m1 + m2) g.q1 - m2 g.q2', [gravity_potential(params, z)], &
                           [-(m1 + m2)*dot_product(g_paper, q1) - m2*dot_product(g_paper, q2)], rtol=1.0e-14_real64)
  end subroutine gravity_direction

  !> At rest, without gravity, dp_a/dt is the spring force -(d psi_a/d l)(l_a, theta_a, gamma) q_a/l_a
  !> (derivative at constant temperature, of psi as the paper writes it).
  subroutine spring_force_at_rest(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z(state_size), f(state_size), q(3, 2), theta(2), gamma, length, h, dpsi_dl
    integer :: a, variable

    params%gravity = 0.0_real64
    q(:, 1) = [1.1_real64, -0.6_real64, 0.5_real64]
    q(:, 2) = [0.4_real64, 2.2_real64, -0.9_real64]
    theta = [265.0_real64, 335.0_real64]
    gamma = 0.12_real64
    do variable = tau_entropy, tau_internal_energy
      model = make_pendulum(params, variable)
      z = state_at_rest(model, q(:, 1), q(:, 2), gamma, theta)
      f = field(model, z)
      do a = 1, 2
        length = norm2(q(:, a))
        h = 1.0e-4_real64
        dpsi_dl = (-paper_psi(params, a, length + 2*h, theta(a), gamma) + 8*paper_psi(params, a, length + h, theta(a), gamma) &
                   - 8*paper_psi(params, a, length - h, theta(a), gamma) &
                   + paper_psi(params, a, length - 2*h, theta(a), gamma))/(12*h)
        call suite%check_close('dp_'//achar(48 + a)//'/dt = -(dpsi/dl) q/l at rest, '// &
                               trim(thermo_variable_names(variable)), f(p_index(:, a)), -dpsi_dl*q(:, a)/length, &
                               rtol=1.0e-8_real64, atol=1.0e-10_real64)
      end do
    end do
  end subroutine spring_force_at_rest

end program test_pendulum_model
