!> discrete_gradient: both discrete gradients satisfy D f . (b - a) = f(b) - f(a) for U and S of
!> each spring and each thermodynamic variable; they are exact (grad f at the midpoint) for
!> quadratics; they take the fallback branch for tiny increments; their Jacobians in b agree
!> with central differences in both branches; the partitioned D_tau is positive.
program test_discrete_gradient
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: seed_random, random_state, quadratic_pair
  use invariant_function, only: invariant_functions, potential_u, potential_s
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  use double_pendulum, only: state_size, spring_invariants
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, discrete_gradient_names, &
                               discrete_gradient_of, quotient_threshold
  implicit none (type, external)

  call run_unit_tests('test_discrete_gradient', [ &
    unit_test('spring_potentials', spring_potentials), &
    unit_test('quadratics', quadratics)])

contains

  !> Directionality and Jacobians of both discrete gradients of U and S of each spring in each
  !> thermodynamic variable, in and out of the fallback branch; positive partitioned D_tau.
  subroutine spring_potentials(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z_a(state_size), z_b(state_size), x_a(3), x_b(3), scale(3), dg(3, 2), f_m(2), g_m(3, 2)
    real(real64) :: theta_min
    integer :: variable, a, kind, trial, n, stat
    logical :: fallback
    character(len=100) :: label

    call seed_random(3)
    do variable = tau_entropy, tau_internal_energy
      model = make_pendulum(params, variable)
      do a = 1, 2
        n = a + 1
        scale(1:n) = model%spring(a)%metric_scale()
        do kind = gradient_gonzalez, gradient_partitioned
          do trial = 1, 8
            write (label, '(a, " spring ", i0, " ", a, " trial ", i0)') trim(thermo_variable_names(variable)), a, &
              trim(discrete_gradient_names(kind)), trial
            ! Pairs from far apart (trial 1-4) to close (5-8).
            z_a = random_state(model)
            z_b = random_state(model)
            if (trial > 4) z_b = z_a + 10.0_real64**(-trial + 3)*(z_b - z_a)
            call spring_invariants(z_a, a, x_a(1:n))
            call spring_invariants(z_b, a, x_b(1:n))
            call check_directionality(suite, model%spring(a), kind, x_a(1:n), x_b(1:n), scale(1:n), trim(label))
            ! Below |d| ~ 1e-2 a difference quotient of the quotient is not resolved in double
            ! precision (rounding ~ eps |f| / (|d| h) with h < |d|); the formula is the same code.
            if (trial <= 5) call check_jacobian(suite, model%spring(a), kind, x_a(1:n), x_b(1:n), scale(1:n), trim(label))
          end do
          ! Fallback branch: an increment below the threshold, in every invariant at once.
          write (label, '(a, " spring ", i0, " ", a, " fallback")') trim(thermo_variable_names(variable)), a, &
            trim(discrete_gradient_names(kind))
          call spring_invariants(random_state(model), a, x_a(1:n))
          x_b(1:n) = x_a(1:n) + 0.2_real64*quotient_threshold*scale(1:n)
          call discrete_gradient_of(kind, model%spring(a), x_a(1:n), x_b(1:n), scale(1:n), dg(1:n, :), &
                                    fallback=fallback, stat=stat)
          call suite%check_true('fallback taken, '//trim(label), fallback)
          call check_directionality(suite, model%spring(a), kind, x_a(1:n), x_b(1:n), scale(1:n), trim(label))
          call check_jacobian(suite, model%spring(a), kind, x_a(1:n), x_b(1:n), scale(1:n), trim(label))
          call model%spring(a)%evaluate(0.5_real64*(x_a(1:n) + x_b(1:n)), f_m, g_m(1:n, :), stat=stat)
          call suite%check_close('fallback is the midpoint gradient, '//trim(label), reshape(dg(1:n, :), [2*n]), &
                                 reshape(g_m(1:n, :), [2*n]), rtol=1.0e-9_real64)
          ! Only the tau increment is small: the partitioned D_tau falls back, the others do not.
          if (kind == gradient_partitioned) then
            call spring_invariants(random_state(model), a, x_b(1:n))
            x_b(n) = x_a(n) + 0.1_real64*quotient_threshold*scale(n)
            write (label, '(a, " spring ", i0, " partitioned, only tau small")') trim(thermo_variable_names(variable)), a
            call check_directionality(suite, model%spring(a), kind, x_a(1:n), x_b(1:n), scale(1:n), trim(label))
            call check_jacobian(suite, model%spring(a), kind, x_a(1:n), x_b(1:n), scale(1:n), trim(label))
          end if
        end do
        ! FORMULATION section 5: the partitioned D_tau U and D_tau S are derivatives at intermediate
        ! points, so the discrete temperature is positive even for large jumps.
        theta_min = huge(1.0_real64)
        do trial = 1, 200
          call spring_invariants(random_state(model), a, x_a(1:n))
          call spring_invariants(random_state(model), a, x_b(1:n))
          call discrete_gradient_of(gradient_partitioned, model%spring(a), x_a(1:n), x_b(1:n), scale(1:n), &
                                    dg(1:n, :), stat=stat)
          theta_min = min(theta_min, dg(n, potential_u)/dg(n, potential_s))
        end do
        write (label, '(a, " spring ", i0)') trim(thermo_variable_names(variable)), a
        call suite%check_true('partitioned discrete temperature > 0 on 200 random pairs, '//trim(label), &
                              theta_min > 0.0_real64)
      end do
    end do

  end subroutine spring_potentials

  !> Quadratics: both discrete gradients equal grad f at the midpoint, whatever the metric.
  subroutine quadratics(suite)
    type(test_suite), intent(inout) :: suite
    type(quadratic_pair) :: quadratic
    real(real64) :: x_a(3), x_b(3), dg(3, 2), f_m(2), g_m(3, 2)
    integer :: kind, trial, stat, j
    character(len=100) :: label

    call seed_random(4)
    call random_number(quadratic%a)
    quadratic%a = quadratic%a + reshape([(transpose(quadratic%a(:, :, j)), j=1, 2)], [3, 3, 2])
    call random_number(quadratic%c)
    do kind = gradient_gonzalez, gradient_partitioned
      do trial = 1, 3
        call random_number(x_a)
        call random_number(x_b)
        call discrete_gradient_of(kind, quadratic, x_a, x_b, [1.0_real64, 3.0_real64, 0.2_real64], dg, stat=stat)
        call quadratic%evaluate(0.5_real64*(x_a + x_b), f_m, g_m, stat=stat)
        write (label, '(a, " quadratic, trial ", i0)') trim(discrete_gradient_names(kind)), trial
        call suite%check_close('exact for '//trim(label), reshape(dg, [6]), reshape(g_m, [6]), rtol=1.0e-12_real64)
        call check_directionality(suite, quadratic, kind, x_a, x_b, [1.0_real64, 3.0_real64, 0.2_real64], trim(label))
      end do
    end do
  end subroutine quadratics

  ! D f . (b - a) = f(b) - f(a) for both functions, to rounding of the larger of f(a), f(b).
  subroutine check_directionality(suite, fun, kind, x_a, x_b, scale, label)
    type(test_suite), intent(inout) :: suite
    class(invariant_functions), intent(in) :: fun
    integer, intent(in) :: kind
    real(real64), intent(in) :: x_a(:), x_b(:), scale(:)
    character(len=*), intent(in) :: label
    real(real64) :: dg(size(x_a), 2), g(size(x_a), 2), f_a(2), f_b(2)
    integer :: stat

    call discrete_gradient_of(kind, fun, x_a, x_b, scale, dg, stat=stat)
    call fun%evaluate(x_a, f_a, g, stat=stat)
    call fun%evaluate(x_b, f_b, g, stat=stat)
    call suite%check_close('directionality, '//label, matmul(x_b - x_a, dg), f_b - f_a, &
                           atol=1.0e-14_real64*max(maxval(abs(f_a)), maxval(abs(f_b)), 1.0_real64))
  end subroutine check_directionality

  ! d(D f)/db against central differences, compared in nondimensional units (scaled by the
  ! metric's sizes); the step h stays inside the branch the pair takes.
  subroutine check_jacobian(suite, fun, kind, x_a, x_b, scale, label)
    type(test_suite), intent(inout) :: suite
    class(invariant_functions), intent(in) :: fun
    integer, intent(in) :: kind
    real(real64), intent(in) :: x_a(:), x_b(:), scale(:)
    character(len=*), intent(in) :: label
    real(real64) :: dg(size(x_a), 2), ddg(size(x_a), size(x_a), 2), fd(size(x_a), size(x_a), 2)
    real(real64) :: dgp(size(x_a), 2), dgm(size(x_a), 2), xp(size(x_a)), xm(size(x_a)), h, d_min
    integer :: i, l, stat

    call discrete_gradient_of(kind, fun, x_a, x_b, scale, dg, ddg, stat=stat)
    d_min = minval(abs(x_b - x_a)/scale)
    do l = 1, size(x_a)
      h = scale(l)*min(1.0e-6_real64, 1.0e-2_real64*d_min)
      xp = x_b
      xm = x_b
      xp(l) = x_b(l) + h
      xm(l) = x_b(l) - h
      call discrete_gradient_of(kind, fun, x_a, xp, scale, dgp, stat=stat)
      call discrete_gradient_of(kind, fun, x_a, xm, scale, dgm, stat=stat)
      fd(:, l, :) = (dgp - dgm)/(2*h)
    end do
    do l = 1, size(x_a)
      do i = 1, size(x_a)
        ddg(i, l, :) = ddg(i, l, :)*scale(i)*scale(l)
        fd(i, l, :) = fd(i, l, :)*scale(i)*scale(l)
      end do
    end do
    call suite%check_close('Jacobian in b, '//label, reshape(ddg, [size(ddg)]), reshape(fd, [size(fd)]), &
                           rtol=1.0e-5_real64, atol=1.0e-6_real64*maxval(abs(ddg)))
  end subroutine check_jacobian

end program test_discrete_gradient
