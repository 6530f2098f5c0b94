!> pendulum_step_kernel, the fused condensed step, against the generic step residual (the oracle,
!> src/scheme/step_residual) for every scheme, thermodynamic variable, discrete gradient, metric
!> and constraint set:
!>  - its residual at y equals the oracle's rows of p, gamma, tau and the constraints at
!>    z' = (q'(y), y), and there the oracle's position rows vanish (the condensation is exact);
!>  - its Jacobian against central differences of its own residual, including the discrete
!>    gradients' fallback branch, and against the oracle's Jacobian condensed by the chain rule
!>    dR/dy = dR/dz'|_y + dR/dq' (h/2) m^-1, written here independently;
!>  - check_root and the scheme's temperatures say what the oracle says, also for unphysical points;
!>  - a model it does not know is left to the oracle.
program test_pendulum_step_kernel
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: seed_random, random_state, fd_jacobian_error
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  use single_spring_model, only: make_single_spring
  use double_pendulum, only: state_size, q_index, tau_index
  use number_text, only: scientific_text
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, discrete_gradient_names, metric_euclidean, &
                               metric_nondimensional
  use length_constraint, only: make_fixed_length
  use temperature_constraint, only: make_fixed_temperature
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint
  use pendulum_step_kernel, only: pendulum_step, build_pendulum_step, condensed_offset
  implicit none (type, external)

  integer, parameter :: midpoint = 0   ! "kind" of the midpoint rule next to the discrete gradients' kinds
  integer, parameter :: no_constraints = 0, with_both = 3   ! constraint sets: bit 0 length, bit 1 temperature
  character(len=*), parameter :: constraint_names(0:3) = [character(len=22) :: 'no constraints', 'length', &
                                                          'temperature', 'length and temperature']

  call run_unit_tests('test_pendulum_step_kernel', [ &
    unit_test('residual_equals_oracle', residual_equals_oracle), &
    unit_test('jacobian_against_differences', jacobian_against_differences), &
    unit_test('jacobian_equals_condensed_oracle', jacobian_equals_condensed_oracle), &
    unit_test('fallback_branch', fallback_branch), &
    unit_test('roots_checked_as_oracle', roots_checked_as_oracle), &
    unit_test('unknown_model_left_to_oracle', unknown_model_left_to_oracle)])

contains

  ! The oracle's step of `kind` in `variable` with the constraint set `set`, from a random old
  ! state, and a random new point x = (z', multipliers) near it.
  subroutine set_case(problem, variable, kind, set, metric, x_new)
    type(step_problem), intent(inout) :: problem
    integer, intent(in) :: variable, kind, set, metric
    real(real64), allocatable, intent(out) :: x_new(:)
    real(real64), parameter :: multipliers(2) = [3.7_real64, -41.0_real64]
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z_new(state_size)
    integer :: k

    model = make_pendulum(params, variable)
    if (allocated(problem%model)) deallocate (problem%model)
    allocate (problem%model, source=model)
    problem%partials_rule = merge(partials_midpoint, partials_discrete_gradient, kind == midpoint)
    if (kind /= midpoint) problem%gradient = kind
    problem%metric = metric
    problem%dt = 0.15_real64
    problem%fraction = 1.0_real64
    problem%z_old = random_state(model)
    z_new = problem%z_old + 0.2_real64*(random_state(model) - problem%z_old)
    if (allocated(problem%constraints)) deallocate (problem%constraints)
    allocate (problem%constraints(popcnt(set)))
    k = 0
    if (btest(set, 0)) then
      k = k + 1
      allocate (problem%constraints(k)%item, source=make_fixed_length(norm2(problem%z_old(q_index(:, 1))), 1.0_real64))
    end if
    if (btest(set, 1)) then
      k = k + 1
      allocate (problem%constraints(k)%item, source=make_fixed_temperature(1 + mod(variable, 2), 290.0_real64))
    end if
    x_new = [z_new, multipliers(1:k)]
  end subroutine set_case

  function case_name(variable, kind, set, metric) result(name)
    integer, intent(in) :: variable, kind, set, metric
    character(len=120) :: name

    if (kind == midpoint) then
      name = trim(thermo_variable_names(variable))//' midpoint'
    else
      name = trim(thermo_variable_names(variable))//' eme '//trim(discrete_gradient_names(kind))
    end if
    if (metric == metric_euclidean) name = trim(name)//' euclidean'
    name = trim(name)//', '//trim(constraint_names(set))
  end function case_name

  ! Every case: variables, schemes, constraint sets, and the Euclidean metric for Gonzalez.
  subroutine for_each_case(suite, check)
    type(test_suite), intent(inout) :: suite
    interface
      subroutine check(suite, problem, kernel, y, label)
        import :: test_suite, step_problem, pendulum_step, real64
        type(test_suite), intent(inout) :: suite
        type(step_problem), intent(in) :: problem
        type(pendulum_step), intent(in) :: kernel
        real(real64), intent(in) :: y(:)
        character(len=*), intent(in) :: label
      end subroutine check
    end interface
    type(step_problem) :: problem
    type(pendulum_step) :: kernel
    real(real64), allocatable :: x_new(:)
    integer :: variable, kind, set, metric, trial
    logical :: built

    call seed_random(41)
    do variable = tau_entropy, tau_internal_energy
      do kind = midpoint, gradient_partitioned
        do metric = metric_nondimensional, metric_euclidean
          if (metric == metric_euclidean .and. kind /= gradient_gonzalez) cycle
          do set = no_constraints, with_both
            do trial = 1, 2
              call set_case(problem, variable, kind, set, metric, x_new)
              call build_pendulum_step(problem, kernel, built)
              call suite%check_true('kernel built, '//trim(case_name(variable, kind, set, metric)), built)
              call check(suite, problem, kernel, x_new(condensed_offset + 1:), trim(case_name(variable, kind, set, metric)))
            end do
          end do
        end do
      end do
    end do
  end subroutine for_each_case

  subroutine residual_equals_oracle(suite)
    type(test_suite), intent(inout) :: suite

    call for_each_case(suite, check_residual)
  end subroutine residual_equals_oracle

  subroutine check_residual(suite, problem, kernel, y, label)
    type(test_suite), intent(inout) :: suite
    type(step_problem), intent(in) :: problem
    type(pendulum_step), intent(in) :: kernel
    real(real64), intent(in) :: y(:)
    character(len=*), intent(in) :: label
    real(real64) :: r(size(y)), x(size(y) + condensed_offset), r_oracle(size(y) + condensed_offset), scale
    integer :: stat, stat_oracle

    call kernel%evaluate(y, r, stat=stat)
    x = kernel%expand(y)
    call problem%evaluate(x, r_oracle, stat=stat_oracle)
    call suite%check_true('in the domain, '//label, stat == 0 .and. stat_oracle == 0)
    ! Rounding of the terms (z' - z)/h, whose size is that of z/h.
    scale = epsilon(1.0_real64)*maxval(abs(x(1:state_size)))/problem%dt
    call suite%check_close('position rows vanish at q''(y), '//label, r_oracle(1:condensed_offset), &
                           0*r_oracle(1:condensed_offset), atol=16*scale)
    call suite%check_close('residual = oracle''s rows, '//label, r, r_oracle(condensed_offset + 1:), &
                           rtol=1.0e-12_real64, atol=64*scale)
  end subroutine check_residual

  subroutine jacobian_against_differences(suite)
    type(test_suite), intent(inout) :: suite

    call for_each_case(suite, check_differences)
  end subroutine jacobian_against_differences

  ! 4th-order central differences with steps of 1e-4 of each unknown's size (tau by its metric
  ! scale); 1e-6 for the Euclidean metric, whose quotients curve more sharply (as test_step_residual).
  subroutine check_differences(suite, problem, kernel, y, label)
    type(test_suite), intent(inout) :: suite
    type(step_problem), intent(in) :: problem
    type(pendulum_step), intent(in) :: kernel
    real(real64), intent(in) :: y(:)
    character(len=*), intent(in) :: label
    real(real64) :: r(size(y)), jac(size(y), size(y)), h(size(y)), err
    integer :: stat, a

    call kernel%evaluate(y, r, jac, stat)
    h = max(1.0_real64, abs(y))
    do a = 1, 2
      h(tau_index(a) - condensed_offset) = problem%model%subsystems(a)%metric_scale(a + 1)
    end do
    h = merge(1.0e-6_real64, 1.0e-4_real64, problem%metric == metric_euclidean)*h
    err = fd_jacobian_error(kernel, y, jac, h, fourth_order=.true.)
    call suite%check_true('Jacobian against central differences, '//label, stat == 0 .and. err < 1.0e-6_real64, &
                          'largest |J - J_fd|/(1 + |J|) = '//scientific_text(err))
  end subroutine check_differences

  subroutine jacobian_equals_condensed_oracle(suite)
    type(test_suite), intent(inout) :: suite

    call for_each_case(suite, check_condensed)
  end subroutine jacobian_equals_condensed_oracle

  ! dR/dy = J(rows y, columns y) + J(rows y, columns q') dq'/dp', dq_a'/dp_b' = (h/2) m^-1_ab I.
  subroutine check_condensed(suite, problem, kernel, y, label)
    type(test_suite), intent(inout) :: suite
    type(step_problem), intent(in) :: problem
    type(pendulum_step), intent(in) :: kernel
    real(real64), intent(in) :: y(:)
    character(len=*), intent(in) :: label
    real(real64) :: r(size(y)), jac(size(y), size(y)), x(size(y) + 6), r_full(size(x)), j_full(size(x), size(x))
    real(real64) :: expected(size(y), size(y)), dq_dp(6, 6), m1, m2
    integer :: stat, i

    call kernel%evaluate(y, r, jac, stat)
    x = kernel%expand(y)
    call problem%evaluate(x, r_full, j_full, stat)
    m1 = 0.0_real64
    m2 = 0.0_real64
    select type (model => problem%model)
    type is (pendulum)
      m1 = model%params%mass(1)
      m2 = model%params%mass(2)
    end select
    dq_dp = 0.0_real64
    do i = 1, 3
      dq_dp(i, i) = 1.0_real64/m1
      dq_dp(i, i + 3) = -1.0_real64/m1
      dq_dp(i + 3, i) = -1.0_real64/m1
      dq_dp(i + 3, i + 3) = (m1 + m2)/(m1*m2)
    end do
    dq_dp = 0.5_real64*problem%dt*dq_dp
    expected = j_full(7:, 7:)
    expected(:, 1:6) = expected(:, 1:6) + matmul(j_full(7:, 1:6), dq_dp)
    call suite%check_close('Jacobian = oracle''s condensed, '//label, reshape(jac, [size(jac)]), &
                           reshape(expected, [size(jac)]), rtol=1.0e-9_real64, atol=1.0e-9_real64*maxval(abs(expected)))
  end subroutine check_condensed

  !> Where a spring's invariants hardly move, the discrete gradients take the midpoint
  !> derivative and the Jacobian follows that branch. From an old state at rest, tiny new momenta
  !> leave both springs' invariants in place; momenta with v_2 = m^-1 p_mid|_2 = 0 and a warmer
  !> spring 1 leave only spring 2 there. Steps of 1e-7 keep the stencil in the branch.
  subroutine fallback_branch(suite)
    type(test_suite), intent(inout) :: suite
    type(step_problem) :: problem
    type(pendulum_step) :: kernel
    real(real64), allocatable :: x_new(:), y(:)
    real(real64) :: m1, m2
    integer :: variable, kind, which
    logical :: built

    call seed_random(43)
    do variable = tau_entropy, tau_internal_energy
      do kind = gradient_gonzalez, gradient_partitioned
        call set_case(problem, variable, kind, no_constraints, metric_nondimensional, x_new)
        problem%z_old(7:12) = 0.0_real64
        call build_pendulum_step(problem, kernel, built)
        m1 = 0.0_real64
        m2 = 0.0_real64
        select type (model => problem%model)
        type is (pendulum)
          m1 = model%params%mass(1)
          m2 = model%params%mass(2)
        end select
        do which = 1, 2
          y = problem%z_old(condensed_offset + 1:state_size)
          if (which == 1) then
            y(1:6) = 1.0e-9_real64*[1.0_real64, -2.0_real64, 0.5_real64, 0.3_real64, 1.0_real64, -1.0_real64]
          else
            y(1:3) = [0.5_real64, -1.0_real64, 0.3_real64]
            y(4:6) = y(1:3)*m2/(m1 + m2)
            y(tau_index(1) - condensed_offset) = 1.1_real64*y(tau_index(1) - condensed_offset)
          end if
          call check_fallback(suite, problem, kernel, y, trim(case_name(variable, kind, no_constraints, &
                              metric_nondimensional))//merge(', fallback: both springs', ', fallback: spring 2    ', &
                              which == 1))
        end do
      end do
    end do
  end subroutine fallback_branch

  subroutine check_fallback(suite, problem, kernel, y, label)
    type(test_suite), intent(inout) :: suite
    type(step_problem), intent(in) :: problem
    type(pendulum_step), intent(in) :: kernel
    real(real64), intent(in) :: y(:)
    character(len=*), intent(in) :: label
    real(real64) :: r(9), r_oracle(15), jac(9, 9), h(9), err
    integer :: stat, a

    call kernel%evaluate(y, r, jac, stat)
    call problem%evaluate(kernel%expand(y), r_oracle, stat=stat)
    call suite%check_close('residual = oracle''s rows, '//label, r, r_oracle(7:), rtol=1.0e-12_real64, &
                           atol=1.0e-10_real64)
    h = max(1.0_real64, abs(y))
    do a = 1, 2
      h(tau_index(a) - condensed_offset) = problem%model%subsystems(a)%metric_scale(a + 1)
    end do
    err = fd_jacobian_error(kernel, y, jac, 1.0e-7_real64*h)
    call suite%check_true('Jacobian against central differences, '//label, err < 1.0e-5_real64, &
                          'largest |J - J_fd|/(1 + |J|) = '//scientific_text(err))
  end subroutine check_fallback

  !> check_root and scheme_temperatures as the oracle's, at good points and at points with a
  !> non-positive temperature at the new state.
  subroutine roots_checked_as_oracle(suite)
    type(test_suite), intent(inout) :: suite

    call for_each_case(suite, check_roots)
  end subroutine roots_checked_as_oracle

  subroutine check_roots(suite, problem, kernel, y, label)
    type(test_suite), intent(inout) :: suite
    type(step_problem), intent(in) :: problem
    type(pendulum_step), intent(in) :: kernel
    real(real64), intent(in) :: y(:)
    character(len=*), intent(in) :: label
    character(len=:), allocatable :: text, text_oracle
    real(real64) :: theta(2), theta_oracle(2), bad(size(y))
    integer :: stat, stat_oracle, a

    call kernel%check_root(y, text)
    call problem%check_root(kernel%expand(y), text_oracle)
    call suite%check_true('check_root as the oracle, '//label, text == text_oracle, text//' | '//text_oracle)
    call kernel%scheme_temperatures(y, theta, stat)
    call problem%scheme_temperatures(kernel%expand(y), theta_oracle, stat_oracle)
    call suite%check_close('scheme temperatures as the oracle, '//label, theta, theta_oracle, rtol=1.0e-12_real64)
    ! Spring a's temperature driven to zero or below at the new state (tau = theta: tau < 0; s: so
    ! far below that theta_ref exp((s - sigma)/Cap) underflows; u: below e - Cap theta_ref).
    do a = 1, 2
      bad = y
      select case (problem%model%thermo_variable)
      case (tau_temperature)
        bad(tau_index(a) - condensed_offset) = -5.0_real64
      case (tau_entropy)
        bad(tau_index(a) - condensed_offset) = bad(tau_index(a) - condensed_offset) - 2.0e4_real64
      case default
        bad(tau_index(a) - condensed_offset) = -1.0e5_real64
      end select
      call kernel%check_root(bad, text)
      call problem%check_root(kernel%expand(bad), text_oracle)
      call suite%check_true('check_root as the oracle with a bad temperature, '//label, &
                            text == text_oracle .and. len(text) > 0, text//' | '//text_oracle)
    end do
  end subroutine check_roots

  !> The generic residual serves a model the kernel does not know (the test's single spring).
  subroutine unknown_model_left_to_oracle(suite)
    type(test_suite), intent(inout) :: suite
    type(step_problem) :: problem
    type(pendulum_step) :: kernel
    type(pendulum_parameters) :: params
    logical :: built

    allocate (problem%model, source=make_single_spring(params, tau_temperature))
    allocate (problem%constraints(0))
    problem%z_old = [1.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 300.0_real64]
    call build_pendulum_step(problem, kernel, built)
    call suite%check_true('no kernel for another model', .not. built)
  end subroutine unknown_model_left_to_oracle

end program test_pendulum_step_kernel
