!> The GENERIC structure of the model, through the generic oracle structure_matrices (so any model
!> of src/structure/model_interface can run these checks): the degeneracy conditions (5)
!> L grad S = 0 and K grad E = 0, skew L and symmetric positive semidefinite K, eq. (9) for
!> M_S^T grad S and M_E^T grad E, for exact partials and for both discrete gradients; the model's
!> written-out vector field equals L grad E + K grad S; its derivatives against central differences.
program test_structure_matrices
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: seed_random, random_state
  use model_parameters, only: pendulum_parameters
  use invariant_function, only: potential_u, potential_s
  use thermo_variable, only: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use model_interface, only: generic_model
  use pendulum_model, only: pendulum, make_pendulum
  use single_spring_model, only: single_spring, make_single_spring
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, discrete_gradient_of, discrete_gradient_names
  use structure_matrices, only: energy_gradient, entropy_gradient, mielke_transpose, poisson_matrix, friction_matrix
  implicit none (type, external)

  call run_unit_tests('test_structure_matrices', [ &
    unit_test('structure_entropy', structure_entropy), &
    unit_test('structure_temperature', structure_temperature), &
    unit_test('structure_internal_energy', structure_internal_energy), &
    unit_test('single_spring_structure', single_spring_structure)])

contains

  subroutine structure_entropy(suite)
    type(test_suite), intent(inout) :: suite

    call check_variable(suite, tau_entropy)
  end subroutine structure_entropy

  subroutine structure_temperature(suite)
    type(test_suite), intent(inout) :: suite

    call check_variable(suite, tau_temperature)
  end subroutine structure_temperature

  subroutine structure_internal_energy(suite)
    type(test_suite), intent(inout) :: suite

    call check_variable(suite, tau_internal_energy)
  end subroutine structure_internal_energy

  !> The same checks on a second model (tests/unit/support/single_spring_model): 8 unknowns, one
  !> subsystem, in every thermodynamic variable.
  subroutine single_spring_structure(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(single_spring) :: model
    real(real64) :: z(8), z_new(8), partials(3, 2, 1), q(3), p(3)
    integer :: variable, trial, kind, stat
    character(len=80) :: label

    call seed_random(9)
    do variable = tau_entropy, tau_internal_energy
      model = make_single_spring(params, variable)
      do trial = 1, 3
        call random_number(q)
        call random_number(p)
        call model%state_from_temperature([1.5_real64, 0.0_real64, -1.0_real64] + 0.5_real64*q, 2.0_real64*p - 1.0_real64, &
                                          0.1_real64*trial, 270.0_real64 + 20.0_real64*trial, z)
        write (label, '("single spring ", a, " exact partials, trial ", i0)') trim(thermo_variable_names(variable)), trial
        call model%exact_partials(z, partials, stat=stat)
        call check_structure(suite, model, z, partials, trim(label))
        call check_vector_field_derivatives(suite, model, z, partials, trim(label))
        call model%state_from_temperature([1.2_real64, 0.3_real64, -1.1_real64], [0.4_real64, -0.2_real64, 0.9_real64], &
                                          0.05_real64, 300.0_real64, z_new)
        do kind = gradient_gonzalez, gradient_partitioned
          write (label, '("single spring ", a, " ", a, " partials, trial ", i0)') trim(thermo_variable_names(variable)), &
            trim(discrete_gradient_names(kind)), trial
          call discrete_partials(model, kind, z, z_new, partials)
          call check_structure(suite, model, 0.5_real64*(z + z_new), partials, trim(label))
        end do
      end do
    end do
  end subroutine single_spring_structure

  ! Random states of the pendulum in one variable: exact partials, and discrete partials between
  ! each state and a nearby one.
  subroutine check_variable(suite, variable)
    type(test_suite), intent(inout) :: suite
    integer, intent(in) :: variable
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64), allocatable :: z(:), z_new(:)
    real(real64) :: partials(3, 2, 2)
    integer :: kind, trial, stat
    character(len=80) :: label

    call seed_random(5 + variable)
    model = make_pendulum(params, variable)
    do trial = 1, 3
      z = random_state(model)
      write (label, '(a, " exact partials, trial ", i0)') trim(thermo_variable_names(variable)), trial
      call model%exact_partials(z, partials, stat=stat)
      call check_structure(suite, model, z, partials, trim(label))
      call check_vector_field_derivatives(suite, model, z, partials, trim(label))
      z_new = z + 0.1_real64*(random_state(model) - z)
      do kind = gradient_gonzalez, gradient_partitioned
        write (label, '(a, " ", a, " partials, trial ", i0)') trim(thermo_variable_names(variable)), &
          trim(discrete_gradient_names(kind)), trial
        call discrete_partials(model, kind, z, z_new, partials)
        call check_structure(suite, model, 0.5_real64*(z + z_new), partials, trim(label))
      end do
    end do
  end subroutine check_variable

  ! The discrete gradients of every subsystem between z and z_new, in its own invariants.
  subroutine discrete_partials(model, kind, z, z_new, partials)
    class(generic_model), intent(in) :: model
    integer, intent(in) :: kind
    real(real64), intent(in) :: z(:), z_new(:)
    real(real64), intent(out) :: partials(:, :, :)
    real(real64) :: x_old(model%max_invariants), x_new(model%max_invariants)
    integer :: a, n, stat

    partials = 0.0_real64
    do a = 1, model%subsystem_count()
      n = model%subsystems(a)%invariant_count
      call model%invariants(z, a, x_old(1:n))
      call model%invariants(z_new, a, x_new(1:n))
      call discrete_gradient_of(kind, model%subsystems(a)%potentials, x_old(1:n), x_new(1:n), &
                                model%subsystems(a)%metric_scale, partials(1:n, :, a), stat=stat)
    end do
  end subroutine discrete_partials

  subroutine check_structure(suite, model, z, partials, label)
    type(test_suite), intent(inout) :: suite
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    character(len=*), intent(in) :: label
    real(real64), dimension(model%state_size, model%state_size) :: l, k, mt
    real(real64), dimension(model%state_size) :: grad_e, grad_s, f, v, expected
    real(real64) :: scale_l, scale_k, smallest_quadratic_form
    integer :: i, a, n

    n = model%state_size
    l = poisson_matrix(model, z, partials)
    k = friction_matrix(model, z, partials)
    grad_e = energy_gradient(model, z, partials)
    grad_s = entropy_gradient(model, z, partials)
    scale_l = maxval(abs(l))*maxval(abs(grad_s))
    scale_k = maxval(abs(k))*maxval(abs(grad_e))

    call suite%check_close('L grad S = 0, '//label, matmul(l, grad_s), spread(0.0_real64, 1, n), atol=1.0e-13_real64*scale_l)
    call suite%check_close('K grad E = 0, '//label, matmul(k, grad_e), spread(0.0_real64, 1, n), atol=1.0e-13_real64*scale_k)
    call suite%check_close('L skew, '//label, reshape(l + transpose(l), [n**2]), spread(0.0_real64, 1, n**2), &
                           atol=1.0e-14_real64*maxval(abs(l)))
    call suite%check_close('K symmetric, '//label, reshape(k - transpose(k), [n**2]), spread(0.0_real64, 1, n**2), &
                           atol=1.0e-14_real64*maxval(abs(k)))
    smallest_quadratic_form = huge(1.0_real64)
    do i = 1, 200
      call random_number(v)
      v = v - 0.5_real64
      smallest_quadratic_form = min(smallest_quadratic_form, dot_product(v, matmul(k, v)))
    end do
    call suite%check_true('K positive semidefinite, '//label, smallest_quadratic_form >= -1.0e-13_real64*maxval(abs(k)))

    ! Eq. (9): M_S^T grad S is 1 on the tau rows and 0 elsewhere; M_E^T grad E is 1 on the tau
    ! rows, and on the others the gradient of the mechanical energy alone (the subsystems' part
    ! cancels).
    expected = 0.0_real64
    do a = 1, model%subsystem_count()
      expected(model%subsystems(a)%tau_column) = 1.0_real64
    end do
    mt = mielke_transpose(model, z, partials, potential_s)
    call suite%check_close('M_S^T grad S = (0, 1), '//label, matmul(mt, grad_s), expected, &
                           atol=1.0e-13_real64*maxval(abs(grad_s)))
    mt = mielke_transpose(model, z, partials, potential_u)
    v = model%mechanical_energy_gradient(z)
    do a = 1, model%subsystem_count()
      v(model%subsystems(a)%tau_column) = 1.0_real64
    end do
    call suite%check_close('M_E^T grad E = (grad (T + V_g), 1), '//label, matmul(mt, grad_e), v, &
                           atol=1.0e-13_real64*maxval(abs(grad_e)))

    ! The written-out field is the assembled product (8).
    call model%vector_field(z, partials, f)
    call suite%check_close('vector field = L grad E + K grad S, '//label, f, matmul(l, grad_e) + matmul(k, grad_s), &
                           rtol=1.0e-12_real64, atol=1.0e-12_real64*maxval(abs(f)))
    call suite%check_true('dS/dt = grad S . f >= 0, '//label, dot_product(grad_s, f) >= -1.0e-12_real64)
  end subroutine check_structure

  subroutine check_vector_field_derivatives(suite, model, z, partials, label)
    type(test_suite), intent(inout) :: suite
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), partials(:, :, :)
    character(len=*), intent(in) :: label
    real(real64), dimension(model%state_size) :: f, fp, fm, zp, zm
    real(real64), dimension(model%state_size, model%state_size) :: df_dz, fd_dz
    real(real64), dimension(model%state_size, model%max_invariants, 2, model%subsystem_count()) :: df_dp, fd_dp
    real(real64), dimension(model%max_invariants, 2, model%subsystem_count()) :: pp, pm
    real(real64) :: h
    integer :: i, j, a, n

    n = model%state_size
    call model%vector_field(z, partials, f, df_dz, df_dp)
    do i = 1, n
      h = 1.0e-6_real64*max(1.0_real64, abs(z(i)))
      zp = z
      zm = z
      zp(i) = z(i) + h
      zm(i) = z(i) - h
      call model%vector_field(zp, partials, fp)
      call model%vector_field(zm, partials, fm)
      fd_dz(:, i) = (fp - fm)/(2*h)
    end do
    call suite%check_close('df/dz against differences, '//label, reshape(df_dz, [n**2]), reshape(fd_dz, [n**2]), &
                           rtol=1.0e-6_real64, atol=1.0e-7_real64*maxval(abs(df_dz)))
    fd_dp = 0.0_real64
    do a = 1, model%subsystem_count()
      do j = 1, 2
        do i = 1, model%subsystems(a)%invariant_count
          h = 1.0e-6_real64*max(1.0e-3_real64, abs(partials(i, j, a)))
          pp = partials
          pm = partials
          pp(i, j, a) = partials(i, j, a) + h
          pm(i, j, a) = partials(i, j, a) - h
          call model%vector_field(z, pp, fp)
          call model%vector_field(z, pm, fm)
          fd_dp(:, i, j, a) = (fp - fm)/(2*h)
        end do
        df_dp(:, model%subsystems(a)%invariant_count + 1:, j, a) = 0.0_real64   ! slots the subsystem lacks
      end do
    end do
    call suite%check_close('df/dpartials against differences, '//label, reshape(df_dp, [size(df_dp)]), &
                           reshape(fd_dp, [size(fd_dp)]), rtol=1.0e-6_real64, atol=1.0e-7_real64*maxval(abs(df_dp)))
  end subroutine check_vector_field_derivatives

end program test_structure_matrices
