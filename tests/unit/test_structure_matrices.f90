!> structure_matrices and generic_vector_field: the degeneracy conditions (5) L grad S = 0 and
!> K grad E = 0, skew L and symmetric positive semidefinite K, eq. (9) for M_E^T grad E and
!> M_S^T grad S, for exact partials and for both discrete gradients; the written-out vector
!> field equals L grad E + K grad S; its derivatives against central differences.
program test_structure_matrices
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use fixtures, only: seed_random, random_state
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_internal_energy, thermo_variable_names, potential_u, potential_s
  use pendulum_model, only: pendulum, make_pendulum
  use double_pendulum, only: state_size, gamma_index, tau_index, var_c, var_gamma, var_tau, spring_invariants
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, discrete_gradient_of, discrete_gradient_names
  use structure_matrices, only: energy_gradient, entropy_gradient, mielke_transpose, poisson_matrix, friction_matrix
  use generic_vector_field, only: vector_field
  implicit none (type, external)

  type(test_suite) :: suite
  type(pendulum_parameters) :: params
  type(pendulum) :: model
  real(real64) :: z(state_size), z_new(state_size), z_mid(state_size), partials(3, 2, 2)
  integer :: variable, kind, trial
  character(len=80) :: label

  suite%name = 'test_structure_matrices'
  call seed_random(5)

  do variable = tau_entropy, tau_internal_energy
    model = make_pendulum(params, variable)
    do trial = 1, 3
      z = random_state(model)
      write (label, '(a, " exact partials, trial ", i0)') trim(thermo_variable_names(variable)), trial
      call exact_partials(model, z, partials)
      call check_structure(z, partials, trim(label))
      call check_vector_field_derivatives(z, partials, trim(label))
      ! Discrete partials between z and a nearby random state.
      z_new = z + 0.1_real64*(random_state(model) - z)
      z_mid = 0.5_real64*(z + z_new)
      do kind = gradient_gonzalez, gradient_partitioned
        write (label, '(a, " ", a, " partials, trial ", i0)') trim(thermo_variable_names(variable)), &
          trim(discrete_gradient_names(kind)), trial
        call discrete_partials(model, kind, z, z_new, partials)
        call check_structure(z_mid, partials, trim(label))
      end do
    end do
  end do

  call suite%finish()

contains

  subroutine exact_partials(model, z, partials)
    type(pendulum), intent(in) :: model
    real(real64), intent(in) :: z(state_size)
    real(real64), intent(out) :: partials(3, 2, 2)
    real(real64) :: f(2), g(3, 2)
    integer :: stat

    partials = 0.0_real64
    call model%spring(1)%evaluate(spring_invariants(z, 1), f, g(1:2, :), stat=stat)
    partials([var_c, var_tau], :, 1) = g(1:2, :)
    call model%spring(2)%evaluate(spring_invariants(z, 2), f, g, stat=stat)
    partials(:, :, 2) = g
  end subroutine exact_partials

  subroutine discrete_partials(model, kind, z, z_new, partials)
    type(pendulum), intent(in) :: model
    integer, intent(in) :: kind
    real(real64), intent(in) :: z(state_size), z_new(state_size)
    real(real64), intent(out) :: partials(3, 2, 2)
    real(real64) :: g(3, 2)
    integer :: stat

    partials = 0.0_real64
    call discrete_gradient_of(kind, model%spring(1), spring_invariants(z, 1), spring_invariants(z_new, 1), &
                              model%spring(1)%metric_scale(), g(1:2, :), stat=stat)
    partials([var_c, var_tau], :, 1) = g(1:2, :)
    call discrete_gradient_of(kind, model%spring(2), spring_invariants(z, 2), spring_invariants(z_new, 2), &
                              model%spring(2)%metric_scale(), g, stat=stat)
    partials(:, :, 2) = g
  end subroutine discrete_partials

  subroutine check_structure(z, partials, label)
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    character(len=*), intent(in) :: label
    real(real64) :: l(state_size, state_size), k(state_size, state_size), mt(state_size, state_size)
    real(real64) :: grad_e(state_size), grad_s(state_size), f(state_size), v(state_size), scale_l, scale_k
    real(real64) :: smallest_quadratic_form, expected(state_size)
    integer :: i

    l = poisson_matrix(z, partials)
    k = friction_matrix(params, z, partials)
    grad_e = energy_gradient(params, z, partials)
    grad_s = entropy_gradient(z, partials)
    scale_l = maxval(abs(l))*maxval(abs(grad_s))
    scale_k = maxval(abs(k))*maxval(abs(grad_e))

    call suite%check_close('L grad S = 0, '//label, matmul(l, grad_s), spread(0.0_real64, 1, state_size), &
                           atol=1.0e-13_real64*scale_l)
    call suite%check_close('K grad E = 0, '//label, matmul(k, grad_e), spread(0.0_real64, 1, state_size), &
                           atol=1.0e-13_real64*scale_k)
    call suite%check_close('L skew, '//label, reshape(l + transpose(l), [state_size**2]), &
                           spread(0.0_real64, 1, state_size**2), atol=1.0e-14_real64*maxval(abs(l)))
    call suite%check_close('K symmetric, '//label, reshape(k - transpose(k), [state_size**2]), &
                           spread(0.0_real64, 1, state_size**2), atol=1.0e-14_real64*maxval(abs(k)))
    smallest_quadratic_form = huge(1.0_real64)
    do i = 1, 200
      call random_number(v)
      v = v - 0.5_real64
      smallest_quadratic_form = min(smallest_quadratic_form, dot_product(v, matmul(k, v)))
    end do
    call suite%check_true('K positive semidefinite, '//label, &
                          smallest_quadratic_form >= -1.0e-13_real64*maxval(abs(k)))

    ! Eq. (9): M_S^T grad S = (0, 1, 1); M_E^T grad E = 1 on the tau rows, 0 on the gamma row.
    mt = mielke_transpose(z, partials, potential_s)
    expected = 0.0_real64
    expected(tau_index) = 1.0_real64
    call suite%check_close('M_S^T grad S = (0, 1), '//label, matmul(mt, grad_s), expected, &
                           atol=1.0e-13_real64*maxval(abs(grad_s)))
    mt = mielke_transpose(z, partials, potential_u)
    v = matmul(mt, grad_e)
    call suite%check_close('M_E^T grad E on gamma and tau rows, '//label, v([gamma_index, tau_index]), &
                           [0.0_real64, 1.0_real64, 1.0_real64], atol=1.0e-13_real64*maxval(abs(grad_e)))

    ! The written-out field is the assembled product (8).
    call vector_field(params, z, partials, f)
    call suite%check_close('vector field = L grad E + K grad S, '//label, f, &
                           matmul(l, grad_e) + matmul(k, grad_s), rtol=1.0e-12_real64, atol=1.0e-12_real64*maxval(abs(f)))
    call suite%check_true('dS/dt = grad S . f >= 0, '//label, dot_product(grad_s, f) >= -1.0e-12_real64)
  end subroutine check_structure

  subroutine check_vector_field_derivatives(z, partials, label)
    real(real64), intent(in) :: z(state_size), partials(3, 2, 2)
    character(len=*), intent(in) :: label
    real(real64) :: f(state_size), df_dz(state_size, state_size), df_dp(state_size, 3, 2, 2)
    real(real64) :: fp(state_size), fm(state_size), zp(state_size), zm(state_size), pp(3, 2, 2), pm(3, 2, 2)
    real(real64) :: fd_dz(state_size, state_size), fd_dp(state_size, 3, 2, 2), h
    integer :: i, j, a

    call vector_field(params, z, partials, f, df_dz, df_dp)
    do i = 1, state_size
      h = 1.0e-6_real64*max(1.0_real64, abs(z(i)))
      zp = z
      zm = z
      zp(i) = z(i) + h
      zm(i) = z(i) - h
      call vector_field(params, zp, partials, fp)
      call vector_field(params, zm, partials, fm)
      fd_dz(:, i) = (fp - fm)/(2*h)
    end do
    call suite%check_close('df/dz against differences, '//label, reshape(df_dz, [state_size**2]), &
                           reshape(fd_dz, [state_size**2]), rtol=1.0e-6_real64, atol=1.0e-7_real64*maxval(abs(df_dz)))
    fd_dp = 0.0_real64
    do a = 1, 2
      do j = 1, 2
        do i = 1, 3
          if (a == 1 .and. i == var_gamma) cycle
          h = 1.0e-6_real64*max(1.0e-3_real64, abs(partials(i, j, a)))
          pp = partials
          pm = partials
          pp(i, j, a) = partials(i, j, a) + h
          pm(i, j, a) = partials(i, j, a) - h
          call vector_field(params, z, pp, fp)
          call vector_field(params, z, pm, fm)
          fd_dp(:, i, j, a) = (fp - fm)/(2*h)
        end do
      end do
    end do
    df_dp(:, var_gamma, :, 1) = 0.0_real64   ! spring 1 has no gamma slot
    call suite%check_close('df/dpartials against differences, '//label, reshape(df_dp, [state_size*12]), &
                           reshape(fd_dp, [state_size*12]), rtol=1.0e-6_real64, atol=1.0e-7_real64*maxval(abs(df_dp)))
  end subroutine check_vector_field_derivatives

end program test_structure_matrices
