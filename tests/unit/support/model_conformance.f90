!> The conformance kit of a model (docs/development.md, Adding a model): whatever model of
!> src/structure/model_interface, its GENERIC structure through the generic oracle
!> structure_matrices -- the degeneracy conditions (5) L grad S = 0 and K grad E = 0, skew L and
!> symmetric positive semidefinite K, eq. (9) for M_S^T grad S and M_E^T grad E, for exact
!> partials and both discrete gradients; the written-out vector field equals L grad E + K grad S;
!> its derivatives against central differences; the conserved momentum components (at most
!> three) constant along the continuous field, with their gradients in the momenta against
!> central differences.
!> check_model runs them all at states around a scene's initial state; test_model_conformance
!> runs it over every registered model.
module model_conformance
  use, intrinsic :: iso_fortran_env, only: real64
  use funit, only: assertTrue, assertEqual
  use close_values, only: is_close, closeness
  use invariant_function, only: potential_u, potential_s
  use model_interface, only: generic_model
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, discrete_gradient_of, discrete_gradient_names
  use structure_matrices, only: energy_gradient, entropy_gradient, mielke_transpose, poisson_matrix, friction_matrix
  implicit none (type, external)
  private
  public :: check_model, check_structure, check_vector_field_derivatives, check_conserved_momenta, discrete_partials

contains

  !> Every check at `trials` states within 5 % of z0 (each entry moved by a random fraction of
  !> itself, or of 0.05 where it is 0): exact partials, and both discrete gradients to a second
  !> such state.
  subroutine check_model(model, z0, label, trials)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z0(:)
    character(len=*), intent(in) :: label
    integer, intent(in) :: trials
    real(real64) :: z(size(z0)), z_new(size(z0)), partials(model%max_invariants, 2, model%subsystem_count())
    integer :: trial, kind, stat
    character(len=:), allocatable :: case_label

    do trial = 1, trials
      z = near(z0)
      z_new = near(z0)
      case_label = label//', exact partials, trial '//achar(iachar('0') + mod(trial, 10))
      call model%exact_partials(z, partials, stat=stat)
      call assertTrue(stat == 0, 'a state near the scene''s is in the domain, '//case_label)
      if (stat /= 0) return
      call check_structure(model, z, partials, case_label)
      call check_vector_field_derivatives(model, z, partials, case_label)
      call check_conserved_momenta(model, z, case_label)
      do kind = gradient_gonzalez, gradient_partitioned
        case_label = label//', '//trim(discrete_gradient_names(kind))//' partials, trial '// &
                     achar(iachar('0') + mod(trial, 10))
        call discrete_partials(model, kind, z, z_new, partials)
        call check_structure(model, 0.5_real64*(z + z_new), partials, case_label)
      end do
    end do
  end subroutine check_model

  ! z0 with each entry moved by up to 5 % of itself (of 0.05 where it is 0).
  function near(z0) result(z)
    real(real64), intent(in) :: z0(:)
    real(real64) :: z(size(z0)), r(size(z0))

    call random_number(r)
    z = z0 + 0.1_real64*(r - 0.5_real64)*merge(abs(z0), 1.0_real64, abs(z0) > 0.0_real64)
  end function near

  !> The discrete gradients of every subsystem between z and z_new, in its own invariants.
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

  !> The structure at z with partials (exact, or discrete between two states): (5), skew L,
  !> symmetric semidefinite K, eq. (9), field = L grad E + K grad S and dS/dt >= 0.
  subroutine check_structure(model, z, partials, label)
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

    call assertEqual(spread(0.0_real64, 1, n), matmul(l, grad_s), tolerance=1.0e-13_real64*scale_l, &
        message='L grad S = 0, '//label)
    call assertEqual(spread(0.0_real64, 1, n), matmul(k, grad_e), tolerance=1.0e-13_real64*scale_k, &
        message='K grad E = 0, '//label)
    call assertEqual(spread(0.0_real64, 1, n**2), reshape(l + transpose(l), [n**2]), &
        tolerance=1.0e-14_real64*maxval(abs(l)), message='L skew, '//label)
    call assertEqual(spread(0.0_real64, 1, n**2), reshape(k - transpose(k), [n**2]), &
        tolerance=1.0e-14_real64*maxval(abs(k)), message='K symmetric, '//label)
    smallest_quadratic_form = huge(1.0_real64)
    do i = 1, 200
      call random_number(v)
      v = v - 0.5_real64
      smallest_quadratic_form = min(smallest_quadratic_form, dot_product(v, matmul(k, v)))
    end do
    call assertTrue(smallest_quadratic_form >= -1.0e-13_real64*maxval(abs(k)), &
        message='K positive semidefinite, '//label)

    ! Eq. (9): M_S^T grad S is 1 on the tau rows and 0 elsewhere; M_E^T grad E is 1 on the tau
    ! rows, and on the others the gradient of the mechanical energy alone (the subsystems' part
    ! cancels).
    ! A mechanical model (no tau: elastic springs) has M = I, S = 0: M_S^T grad S = 0 and
    ! M_E^T grad E = grad E.
    expected = 0.0_real64
    do a = 1, model%temperature_count()
      expected(model%subsystems(a)%tau_column) = 1.0_real64
    end do
    mt = mielke_transpose(model, z, partials, potential_s)
    call assertEqual(expected, matmul(mt, grad_s), tolerance=1.0e-13_real64*max(maxval(abs(grad_s)), tiny(1.0_real64)), &
        message='M_S^T grad S = (0, 1), '//label)
    mt = mielke_transpose(model, z, partials, potential_u)
    v = model%mechanical_energy_gradient(z)
    do a = 1, model%temperature_count()
      v(model%subsystems(a)%tau_column) = 1.0_real64
    end do
    if (model%temperature_count() == 0) v = grad_e
    call assertEqual(v, matmul(mt, grad_e), tolerance=1.0e-13_real64*maxval(abs(grad_e)), &
        message='M_E^T grad E = (grad (T + V_g), 1), '//label)

    ! The written-out field is the assembled product (8).
    call model%vector_field(z, partials, f)
    expected = matmul(l, grad_e) + matmul(k, grad_s)
    call assert_close(f, expected, 1.0e-12_real64, 1.0e-12_real64*maxval(abs(f)), 'vector field = L grad E + K grad S, '//label)
    call assertTrue(dot_product(grad_s, f) >= -1.0e-12_real64, message='dS/dt = grad S . f >= 0, '//label)
  end subroutine check_structure

  !> The written-out field's df/dz and df/dpartials against central differences.
  subroutine check_vector_field_derivatives(model, z, partials, label)
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
    call assert_close(reshape(df_dz, [n**2]), reshape(fd_dz, [n**2]), 1.0e-6_real64, 1.0e-7_real64*maxval(abs(df_dz)), &
                      'df/dz against differences, '//label)
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
    call assert_close(reshape(df_dp, [size(df_dp)]), reshape(fd_dp, [size(fd_dp)]), 1.0e-6_real64, &
                      1.0e-7_real64*maxval(abs(df_dp)), 'df/dpartials against differences, '//label)
  end subroutine check_vector_field_derivatives

  !> Each conserved momentum component C_k is a first integral: its rate along the continuous
  !> field, (C_k(z + h f) - C_k(z - h f))/(2 h), is zero to rounding (C_k is at most quadratic in
  !> z, so the difference has no truncation error); and conserved_momenta_gradient(:, k) is dC_k/dz
  !> by central differences in every column where it is not zero (the momenta).
  subroutine check_conserved_momenta(model, z, label)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    character(len=*), intent(in) :: label
    real(real64) :: f(model%state_size), gradients(model%state_size, model%conserved_count())
    real(real64) :: rate(model%conserved_count()), fd(model%conserved_count()), zp(size(z)), zm(size(z)), h, scale
    integer :: stat, j, k

    if (model%conserved_count() == 0) return
    call assertTrue(model%conserved_count() <= 3, 'at most three conserved components (an angular momentum''s), '//label)
    call model%continuous_field(z, f, stat)
    call assertTrue(stat == 0, 'the continuous field at a state near the scene''s, '//label)
    if (stat /= 0) return
    h = 1.0e-3_real64/max(1.0_real64, maxval(abs(f)))
    rate = (model%conserved_momenta(z + h*f) - model%conserved_momenta(z - h*f))/(2*h)
    scale = maxval(abs(z))*maxval(abs(f))
    call assert_close(rate, 0*rate, 0.0_real64, 1.0e-10_real64*scale, 'd(conserved momenta)/dt = 0 along the field, '// &
                      label)
    gradients = model%conserved_momenta_gradient(z)
    do j = 1, size(z)
      if (.not. any(abs(gradients(j, :)) > 0.0_real64)) cycle
      h = 1.0e-6_real64*max(1.0_real64, abs(z(j)))
      zp = z
      zm = z
      zp(j) = z(j) + h
      zm(j) = z(j) - h
      fd = (model%conserved_momenta(zp) - model%conserved_momenta(zm))/(2*h)
      do k = 1, size(fd)
        call assert_close([gradients(j, k)], [fd(k)], 1.0e-8_real64, 1.0e-8_real64*maxval(abs(z)), &
                          'conserved momentum gradient against differences, '//label)
      end do
    end do
  end subroutine check_conserved_momenta

  ! got against expected within rtol and atol, the failure saying where they differ.
  subroutine assert_close(got, expected, rtol, atol, label)
    real(real64), intent(in) :: got(:), expected(:), rtol, atol
    character(len=*), intent(in) :: label

    call assertTrue(is_close(got, expected, rtol=rtol, atol=atol), message=label//': '// &
                    closeness(got, expected, rtol=rtol, atol=atol))
  end subroutine assert_close

end module model_conformance
