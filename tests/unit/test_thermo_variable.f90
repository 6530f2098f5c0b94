!> thermo_variable: U_a and S_a for tau = s, theta, u against psi as the paper writes it,
!> Theta = dU/dtau / dS/dtau = theta (eq. (2)), derivatives against central differences,
!> and domain errors.
program test_thermo_variable
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: seed_random, uniform, paper_legendre, check_derivatives
  use model_parameters, only: pendulum_parameters
  use invariant_function, only: potential_u, potential_s, domain_ok, domain_nonpositive_length, &
                                domain_nonpositive_temperature
  use thermo_variable, only: spring_potential, tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  implicit none (type, external)

  call run_unit_tests('test_thermo_variable', [ &
    unit_test('potentials_against_psi', potentials_against_psi), &
    unit_test('cancellation_free_difference', cancellation_free_difference), &
    unit_test('domain_errors', domain_errors)])

contains

  !> U_a and S_a against psi, eq. (2), the closed-form temperature and the derivatives.
  subroutine potentials_against_psi(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: length, theta, gamma, s_paper, u_paper, tau, theta_back, f(2), g(3, 2)
    real(real64), allocatable :: x(:)
    integer :: variable, a, trial, stat, n
    character(len=60) :: label

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

  end subroutine potentials_against_psi

  !> U(b) - U(a) and S(b) - S(a) without cancellation: equal to the plain difference for far
  !> pairs, and to grad f(mid).(b - a) for pairs 1e-9 apart, where the Taylor remainder is
  !> O(1e-27) and a plain difference of values of size |f| would keep only ~7 digits.
  subroutine cancellation_free_difference(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    integer :: variable, a, n
    character(len=60) :: label

    call seed_random(24)
    do variable = tau_entropy, tau_internal_energy
      model = make_pendulum(params, variable)
      do a = 1, 2
        n = a + 1
        write (label, '(a, " spring ", i0)') trim(thermo_variable_names(variable)), a
        call check_difference(suite, model%spring(a), n, 0.3_real64, 1.0e-12_real64, 'far pair, '//trim(label))
        call check_difference(suite, model%spring(a), n, 1.0e-9_real64, 1.0e-8_real64, 'close pair, '//trim(label))
      end do
    end do

  end subroutine cancellation_free_difference

  !> Domain errors are reported, not trapped.
  subroutine domain_errors(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: x3(3), f(2), g(3, 2)
    integer :: stat

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
  end subroutine domain_errors

  ! Compares spring%difference(x_a, x_b) with the plain difference (far pairs) or the midpoint
  ! gradient's first-order difference (close pairs), relative to rtol.
  subroutine check_difference(suite, spring, n, step, rtol, label)
    type(test_suite), intent(inout) :: suite
    type(spring_potential), intent(in) :: spring
    integer, intent(in) :: n
    real(real64), intent(in) :: step, rtol
    character(len=*), intent(in) :: label
    real(real64) :: x_a(n), x_b(n), scale(n), delta(2), f_a(2), f_b(2), g(n, 2), expected(2)
    integer :: i, stat

    scale = spring%metric_scale()
    x_a(1) = uniform(1.0_real64, 9.0_real64)
    if (n == 3) x_a(2) = uniform(-0.3_real64, 0.3_real64)
    call spring%tau_from_temperature(x_a(1:n - 1), uniform(260.0_real64, 380.0_real64), x_a(n), stat)
    do i = 1, n
      x_b(i) = x_a(i) + step*scale(i)*uniform(-1.0_real64, 1.0_real64)
    end do
    call spring%difference(x_a, x_b, delta, stat)
    if (step > 1.0e-3_real64) then
      call spring%evaluate(x_a, f_a, g, stat=stat)
      call spring%evaluate(x_b, f_b, g, stat=stat)
      expected = f_b - f_a
      call suite%check_close('difference = f(b) - f(a), '//label, delta, expected, &
                             atol=rtol*max(maxval(abs(f_a)), 1.0_real64))
    else
      call spring%evaluate(0.5_real64*(x_a + x_b), f_a, g, stat=stat)
      expected = matmul(x_b - x_a, g)
      call suite%check_close('difference = grad f(mid).d to first order, '//label, delta, expected, rtol=rtol)
    end if
  end subroutine check_difference

end program test_thermo_variable
