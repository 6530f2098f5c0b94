!> thermo_variable: U_a and S_a for tau = s, theta, u against psi as the paper writes it,
!> Theta = dU/dtau / dS/dtau = theta (eq. (2)), derivatives against central differences,
!> and domain errors.
program test_thermo_variable
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use fixtures, only: seed_random, uniform, paper_legendre, check_derivatives
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: spring_potential, tau_entropy, tau_temperature, tau_internal_energy, &
                             thermo_variable_names, potential_u, potential_s, domain_ok, &
                             domain_nonpositive_length, domain_nonpositive_temperature
  use pendulum_model, only: pendulum, make_pendulum
  implicit none (type, external)

  type(test_suite) :: suite
  type(pendulum_parameters) :: params
  type(pendulum) :: model
  real(real64) :: length, theta, gamma, s_paper, u_paper, tau, theta_back, x3(3), f(2), g(3, 2)
  real(real64), allocatable :: x(:)
  integer :: variable, a, trial, stat, n
  character(len=60) :: label

  suite%name = 'test_thermo_variable'
  call seed_random(23)

  do variable = tau_entropy, tau_internal_energy
    model = make_pendulum(params, variable)
    do a = 1, 2
      n = a + 1
      do trial = 1, 10
        length = uniform(0.6_real64, 4.0_real64)
        theta = uniform(200.0_real64, 450.0_real64)
        gamma = uniform(-0.5_real64, 0.5_real64)
        write (label, '(a, " spring ", i0, " trial ", i0)') trim(thermo_variable_names(variable)), a, trial
        call model%spring(a)%tau_from_temperature([length**2, gamma], theta, tau, stat)
        if (a == 1) then
          x = [length**2, tau]
        else
          x = [length**2, gamma, tau]
        end if
        call model%spring(a)%evaluate(x, f, g(1:n, :), stat=stat)
        call paper_legendre(params, a, length, theta, gamma, s_paper, u_paper)
        call suite%check_close('U against psi, '//trim(label), [f(potential_u)], [u_paper], rtol=1.0e-9_real64)
        call suite%check_close('S against psi, '//trim(label), [f(potential_s)], [s_paper], &
                               rtol=1.0e-9_real64, atol=1.0e-9_real64)
        call suite%check_close('eq. (2) Theta = theta, '//trim(label), [g(n, potential_u)/g(n, potential_s)], [theta], &
                               rtol=1.0e-12_real64)
        call model%spring(a)%temperature(x, theta_back, stat)
        call suite%check_close('temperature(x) = theta, '//trim(label), [theta_back], [theta], rtol=1.0e-12_real64)
        if (trial <= 3) call check_derivatives(suite, trim(label), model%spring(a), x, &
                                               1.0e-5_real64*model%spring(a)%metric_scale(), 2)
      end do
    end do
  end do

  ! Domain errors are reported, not trapped.
  model = make_pendulum(params, tau_temperature)
  call model%spring(2)%evaluate([0.0_real64, 0.0_real64, 300.0_real64], f, g, stat=stat)
  call suite%check_equal_int('zero length is outside the domain', stat, domain_nonpositive_length)
  call model%spring(2)%evaluate([4.0_real64, 0.0_real64, -1.0_real64], f, g, stat=stat)
  call suite%check_equal_int('negative temperature (tau = theta)', stat, domain_nonpositive_temperature)
  model = make_pendulum(params, tau_internal_energy)
  x3 = [4.0_real64, 0.0_real64, -1.0e4_real64]
  call model%spring(2)%evaluate(x3, f, g, stat=stat)
  call suite%check_equal_int('internal energy below the zero-kelvin value', stat, domain_nonpositive_temperature)
  call model%spring(2)%evaluate([4.0_real64, 0.0_real64, 100.0_real64], f, g, stat=stat)
  call suite%check_equal_int('admissible internal energy', stat, domain_ok)

  call suite%finish()

end program test_thermo_variable
