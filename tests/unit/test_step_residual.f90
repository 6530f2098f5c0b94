!> step_residual: the analytic Jacobian against central differences for both schemes, all
!> thermodynamic variables and both discrete gradients, also where the discrete gradients take
!> their fallback branch; and the discrete balance laws as identities valid for ANY z':
!>   E(z') - E(z) = dt DE . R(z')               (EME; midpoint with tau = u)
!>   S(z') - S(z) - dt DS . R(z') >= 0          (EME; midpoint with tau = s)
!>   J_z(z') - J_z(z) = dt [sum_a R_qa x p_a,mid + q_a,mid x R_pa]_z   (both schemes)
!> so that at a root (R = 0) energy and J_z are conserved and entropy cannot fall.
program test_step_residual
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use fixtures, only: seed_random, random_state, fd_jacobian_error
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: make_pendulum
  use double_pendulum, only: state_size, q_index, p_index, gamma_index, tau_index, angular_momentum, cross
  use number_text, only: scientific_text
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, discrete_gradient_names, &
                               metric_euclidean, metric_nondimensional
  use structure_matrices, only: energy_gradient, entropy_gradient
  use step_residual, only: step_problem, scheme_eme, scheme_midpoint
  implicit none (type, external)

  type(test_suite) :: suite
  type(pendulum_parameters) :: params
  type(step_problem), target :: problem
  real(real64) :: z_new(state_size)
  integer :: variable, kind, trial
  character(len=100) :: label

  suite%name = 'test_step_residual'
  call seed_random(17)

  do variable = tau_entropy, tau_internal_energy
    problem%model = make_pendulum(params, variable)
    problem%dt = 0.15_real64
    ! EME with each discrete gradient, and the midpoint rule (kind = 0).
    do kind = 0, gradient_partitioned
      if (kind == 0) then
        problem%scheme = scheme_midpoint
      else
        problem%scheme = scheme_eme
        problem%gradient = kind
      end if
      do trial = 1, 4
        call label_case(trim(case_name(kind))//' trial', trial)
        problem%z_old = random_state(problem%model)
        z_new = problem%z_old + 0.05_real64*(random_state(problem%model) - problem%z_old)
        call check_jacobian(z_new, trim(label))
        call check_balance_laws(z_new, kind, trim(label))
      end do
      ! Fallback states: spring invariants unchanged (only momenta move), then only tau_1 moves.
      call label_case(trim(case_name(kind))//' fallback: invariants fixed', 0)
      z_new = problem%z_old
      z_new(p_index(:, 2)) = z_new(p_index(:, 2)) + [0.3_real64, -0.2_real64, 0.1_real64]
      call check_jacobian(z_new, trim(label), fallback_columns=[q_index(:, 1), q_index(:, 2), gamma_index, tau_index])
      call check_balance_laws(z_new, kind, trim(label))
      call label_case(trim(case_name(kind))//' fallback: spring 2 fixed', 0)
      z_new = problem%z_old
      z_new(tau_index(1)) = z_new(tau_index(1))*1.1_real64
      z_new(q_index(:, 1)) = z_new(q_index(:, 1))*0.8_real64
      call check_jacobian(z_new, trim(label), fallback_columns=[q_index(:, 2), gamma_index, tau_index(2)])
    end do
  end do

  ! Constraints (FORMULATION section 7): the multipliers are unknowns 16 and 17.
  do variable = tau_entropy, tau_internal_energy
    problem%model = make_pendulum(params, variable)
    do kind = 0, gradient_partitioned
      problem%scheme = merge(scheme_midpoint, scheme_eme, kind == 0)
      if (kind > 0) problem%gradient = kind
      ! A well-separated pair: the stencil must not straddle a spring's fallback branch.
      problem%z_old = random_state(problem%model)
      z_new = problem%z_old + 0.2_real64*(random_state(problem%model) - problem%z_old)
      problem%length = norm2(problem%z_old(q_index(:, 1)))
      problem%temperature = 290.0_real64
      problem%fix_length = .true.
      problem%fix_temperature = .true.
      call suite%check_equal_int('two constraints add two unknowns', problem%unknowns(), state_size + 2)
      call check_jacobian([z_new, 3.7_real64, -41.0_real64], trim(case_name(kind))//' with both constraints')
      problem%fix_length = .false.
      call check_jacobian([z_new, -41.0_real64], trim(case_name(kind))//' with the temperature constraint')
      problem%fix_length = .true.
      problem%fix_temperature = .false.
      call check_jacobian([z_new, 3.7_real64], trim(case_name(kind))//' with the length constraint')
      problem%fix_length = .false.
    end do
  end do

  ! The Euclidean metric (FORMULATION section 5) is a different, equally exact discrete gradient.
  problem%model = make_pendulum(params, tau_internal_energy)
  problem%scheme = scheme_eme
  problem%gradient = gradient_gonzalez
  problem%metric = metric_euclidean
  problem%z_old = random_state(problem%model)
  z_new = problem%z_old + 0.05_real64*(random_state(problem%model) - problem%z_old)
  label = 'internal_energy gonzalez euclidean metric'
  call check_jacobian(z_new, trim(label))
  call check_balance_laws(z_new, gradient_gonzalez, trim(label))
  problem%metric = metric_nondimensional

  call suite%finish()

contains

  function case_name(kind) result(name)
    integer, intent(in) :: kind
    character(len=40) :: name

    if (kind == 0) then
      name = trim(thermo_variable_names(variable))//' midpoint'
    else
      name = trim(thermo_variable_names(variable))//' eme '//trim(discrete_gradient_names(kind))
    end if
  end function case_name

  subroutine label_case(text, trial)
    character(len=*), intent(in) :: text
    integer, intent(in) :: trial

    if (trial > 0) then
      write (label, '(a, 1x, i0)') text, trial
    else
      label = text
    end if
  end subroutine label_case

  ! Steps scale with each variable's size (tau by the spring's metric scale). Generic pairs use a
  ! 4th-order stencil with steps large enough to keep the quotients' rounding out of the way.
  ! The columns listed in fallback_columns move a spring whose discrete gradient is in its
  ! fallback branch: they get small 2nd-order steps so that the perturbed state stays there.
  subroutine check_jacobian(x_new, label, fallback_columns)
    real(real64), intent(in) :: x_new(:)
    character(len=*), intent(in) :: label
    integer, intent(in), optional :: fallback_columns(:)
    real(real64) :: r(size(x_new)), jac(size(x_new), size(x_new)), h(size(x_new)), err, tolerance
    integer :: stat, a

    call problem%evaluate(x_new, r, jac, stat)
    call suite%check_equal_int('state in domain, '//label, stat, 0)
    h = max(1.0_real64, abs(x_new))
    do a = 1, 2
      associate (scale => problem%model%spring(a)%metric_scale())
        h(tau_index(a)) = scale(a + 1)
      end associate
    end do
    if (present(fallback_columns)) then
      h = 1.0e-5_real64*h
      h(fallback_columns) = 1.0e-2_real64*h(fallback_columns)
      tolerance = 1.0e-5_real64
    else
      h = 1.0e-4_real64*h
      tolerance = 1.0e-6_real64
    end if
    err = fd_jacobian_error(residual_of, x_new, jac, h, fourth_order=.not. present(fallback_columns))
    call suite%check_true('Jacobian against central differences, '//label, err < tolerance, &
                          'largest |J - J_fd|/(1 + |J|) = '//scientific_text(err))
  end subroutine check_jacobian

  subroutine residual_of(x, r)
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: r(:)
    integer :: stat

    call problem%evaluate(x, r, stat=stat)
  end subroutine residual_of

  subroutine check_balance_laws(z_new, kind, label)
    real(real64), intent(in) :: z_new(state_size)
    integer, intent(in) :: kind
    character(len=*), intent(in) :: label
    real(real64) :: r(state_size), partials(3, 2, 2), z_mid(state_size), e_old, e_new, s_old, s_new
    real(real64) :: theta(2), j_residual(3), dt
    integer :: stat, a

    dt = problem%dt
    call problem%evaluate(z_new, r, stat=stat)
    call problem%scheme_partials(z_new, partials, stat=stat)
    z_mid = 0.5_real64*(problem%z_old + z_new)
    call problem%model%observe(problem%z_old, e_old, s_old, theta, stat)
    call problem%model%observe(z_new, e_new, s_new, theta, stat)
    if (kind /= 0 .or. variable == tau_internal_energy) then
      call suite%check_close('E(z'') - E(z) = dt DE.R, '//label, [e_new - e_old], &
                             [dt*dot_product(energy_gradient(params, z_mid, partials), r)], &
                             atol=1.0e-13_real64*abs(e_old))
    end if
    if (kind /= 0 .or. variable == tau_entropy) then
      call problem%scheme_temperatures(z_new, theta, stat)
      call suite%check_true('S(z'') - S(z) - dt DS.R >= 0, '//label, &
                            s_new - s_old - dt*dot_product(entropy_gradient(z_mid, partials), r) >= &
                            -1.0e-13_real64*abs(s_old) .and. all(theta > 0))
    end if
    ! (Midpoint with tau = theta has no such identity: the e2e tests show what it loses.)
    j_residual = 0.0_real64
    do a = 1, 2
      j_residual = j_residual + cross(r(q_index(:, a)), z_mid(p_index(:, a))) &
                   + cross(z_mid(q_index(:, a)), r(p_index(:, a)))
    end do
    associate (j_old => angular_momentum(problem%z_old), j_new => angular_momentum(z_new))
      call suite%check_close('J_z(z'') - J_z(z) = dt (R x p + q x R)_z, '//label, [j_new(3) - j_old(3)], &
                             [dt*j_residual(3)], atol=1.0e-13_real64*max(1.0_real64, abs(j_old(3))))
    end associate
  end subroutine check_balance_laws

end program test_step_residual
