!> free_energy: the closed forms e_a, sigma_a against psi as the paper writes it (16)-(17),
!> via s = -d psi/d theta and u = psi + theta s, and their (C, gamma) derivatives.
program test_free_energy
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: seed_random, uniform, paper_legendre
  use model_parameters, only: pendulum_parameters
  use free_energy, only: spring_law, spring_law_of, mechanical_parts
  implicit none (type, external)

  call run_unit_tests('test_free_energy', [ &
    unit_test('heat_capacities', heat_capacities), &
    unit_test('closed_forms_against_psi', closed_forms_against_psi), &
    unit_test('mechanical_derivatives', mechanical_derivatives), &
    unit_test('no_maxwell_element', no_maxwell_element)])

contains

  !> Cap_1 = c_1 and Cap_2 = (1 + beta_v) c_2 (FORMULATION section 3).
  subroutine heat_capacities(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(spring_law) :: law

    law = spring_law_of(params, 1)
    call suite%check_close('heat capacity spring 1', [law%heat_capacity], [10.0_real64])
    law = spring_law_of(params, 2)
    call suite%check_close('heat capacity spring 2', [law%heat_capacity], [15.0_real64])
  end subroutine heat_capacities

  !> s = sigma + Cap ln(theta/theta_ref) = -d psi/d theta and u = e + Cap (theta - theta_ref)
  !> = psi + theta s on random lengths, temperatures and gammas.
  subroutine closed_forms_against_psi(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(spring_law) :: law
    real(real64) :: length, theta, gamma, s_paper, u_paper, s_closed, u_closed
    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)
    integer :: a, trial
    character(len=40) :: label

    call seed_random(11)
    do a = 1, 2
      law = spring_law_of(params, a)
      do trial = 1, 20
        length = uniform(0.5_real64, 4.0_real64)
        theta = uniform(200.0_real64, 450.0_real64)
        gamma = uniform(-0.5_real64, 0.5_real64)
        call paper_legendre(params, a, length, theta, gamma, s_paper, u_paper)
        call mechanical_parts(law, length**2, gamma, e, sigma, de, dsigma, d2e, d2sigma)
        s_closed = sigma + law%heat_capacity*log(theta/params%theta_ref)
        u_closed = e + law%heat_capacity*(theta - params%theta_ref)
        write (label, '("spring ", i0, " trial ", i0)') a, trial
        call suite%check_close('s = -dpsi/dtheta, '//trim(label), [s_closed], [s_paper], rtol=1.0e-9_real64, atol=1.0e-9_real64)
        call suite%check_close('u = psi + theta s, '//trim(label), [u_closed], [u_paper], rtol=1.0e-9_real64, atol=1.0e-7_real64)
      end do
    end do
  end subroutine closed_forms_against_psi

  !> Gradients and Hessians of e and sigma in (C, gamma) against central differences.
  subroutine mechanical_derivatives(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    integer :: a, trial
    character(len=40) :: label

    call seed_random(12)
    do a = 1, 2
      do trial = 1, 5
        write (label, '("spring ", i0, " trial ", i0)') a, trial
        call check_mechanical_derivatives(suite, spring_law_of(params, a), uniform(0.3_real64, 16.0_real64), &
                                          uniform(-0.5_real64, 0.5_real64), label)
      end do
    end do
  end subroutine mechanical_derivatives

  !> Without beta_v, spring 2's closed forms reduce to spring 1's shape (same formula, a = 2 data).
  subroutine no_maxwell_element(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(spring_law) :: law
    real(real64) :: s_paper, u_paper, e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)

    params%beta_v = 0.0_real64
    params%mu_neq_const = 0.0_real64
    params%mu_neq_slope = 0.0_real64
    call paper_legendre(params, 2, 2.7_real64, 330.0_real64, 0.4_real64, s_paper, u_paper)
    law = spring_law_of(params, 2)
    call mechanical_parts(law, 2.7_real64**2, 0.4_real64, e, sigma, de, dsigma, d2e, d2sigma)
    call suite%check_close('no Maxwell element: s', [sigma + law%heat_capacity*log(330.0_real64/300.0_real64)], [s_paper], &
                           rtol=1.0e-9_real64)
  end subroutine no_maxwell_element


  ! Gradient and Hessian of e and sigma in (C, gamma) against central differences.
  subroutine check_mechanical_derivatives(suite, law, c, gamma, label)
    type(test_suite), intent(inout) :: suite
    type(spring_law), intent(in) :: law
    real(real64), intent(in) :: c, gamma
    character(len=*), intent(in) :: label
    real(real64) :: e, sigma, de(2), dsigma(2), d2e(2, 2), d2sigma(2, 2)
    real(real64) :: x(2), h(2), fd_de(2), fd_dsigma(2), fd_d2e(2, 2), fd_d2sigma(2, 2)
    real(real64) :: ep, em, sp, sm, dep(2), dem(2), dsp(2), dsm(2), scratch_e(2, 2), scratch_s(2, 2)
    real(real64) :: xp(2), xm(2)
    integer :: i

    x = [c, gamma]
    h = [1.0e-5_real64*c, 1.0e-5_real64]
    call mechanical_parts(law, c, gamma, e, sigma, de, dsigma, d2e, d2sigma)
    do i = 1, 2
      xp = x
      xm = x
      xp(i) = xp(i) + h(i)
      xm(i) = xm(i) - h(i)
      call mechanical_parts(law, xp(1), xp(2), ep, sp, dep, dsp, scratch_e, scratch_s)
      call mechanical_parts(law, xm(1), xm(2), em, sm, dem, dsm, scratch_e, scratch_s)
      fd_de(i) = (ep - em)/(2*h(i))
      fd_dsigma(i) = (sp - sm)/(2*h(i))
      fd_d2e(:, i) = (dep - dem)/(2*h(i))
      fd_d2sigma(:, i) = (dsp - dsm)/(2*h(i))
    end do
    call suite%check_close('de '//label, de, fd_de, rtol=1.0e-7_real64, atol=1.0e-8_real64)
    call suite%check_close('dsigma '//label, dsigma, fd_dsigma, rtol=1.0e-7_real64, atol=1.0e-10_real64)
    call suite%check_close('d2e '//label, reshape(d2e, [4]), reshape(fd_d2e, [4]), rtol=1.0e-6_real64, atol=1.0e-8_real64)
    call suite%check_close('d2sigma '//label, reshape(d2sigma, [4]), reshape(fd_d2sigma, [4]), &
                           rtol=1.0e-6_real64, atol=1.0e-10_real64)
  end subroutine check_mechanical_derivatives

end program test_free_energy
