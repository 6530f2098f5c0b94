!> The relaxed Runge-Kutta family: its tableaux against their published nodes and the quadrature
!> order conditions; the order of each tableau (without relaxation) on Kepler's problem with
!> eccentricity 1/2, whose exact solution is known (4, 8, 8, 6 within 0.3); the relaxation of a
!> step (E exact, J.a exact, only momenta corrected); the constrained flow's Jacobian against
!> central differences, through the implicit stages that use it, and its index-1 multiplier
!> against d(q1.v1)/dt = 0; and the entropy guard of relaxed_dp853, forced with a model whose
!> dissipation is negative (a negative viscosity).
program test_relaxed_runge_kutta
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: seed_random, random_state, uniform
  use number_text, only: scientific_text
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_temperature
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use pendulum_model, only: pendulum, make_pendulum
  use single_spring_model, only: single_spring, make_single_spring
  use butcher_tableaux, only: butcher_tableau, classic_rk4, cooper_verner8, dormand_prince853, gauss_legendre3
  use relaxation, only: relax
  use integrator_settings, only: integrator_choice
  use stepper, only: time_stepper, step_report
  use relaxed_stepper, only: new_relaxed_rk8, new_relaxed_dp853
  use collocation_stages, only: stage_system
  use constrained_flow, only: constrained_field, project_state
  use length_constraint, only: make_fixed_length
  use temperature_constraint, only: make_fixed_temperature
  use double_pendulum, only: q_index, p_index
  use fixtures, only: fd_jacobian_error
  implicit none (type, external)

  call run_unit_tests('test_relaxed_runge_kutta', [ &
    unit_test('tableau_nodes', tableau_nodes), &
    unit_test('quadrature_conditions', quadrature_conditions), &
    unit_test('order_on_kepler', order_on_kepler), &
    unit_test('relaxation_keeps_energy_and_momentum', relaxation_keeps_energy_and_momentum), &
    unit_test('constrained_stage_jacobian', constrained_stage_jacobian), &
    unit_test('index_one_multiplier', index_one_multiplier), &
    unit_test('entropy_guard', entropy_guard)])

contains

  !> Row sums c_i = sum_j a_ij against the nodes as their sources give them.
  subroutine tableau_nodes(suite)
    type(test_suite), intent(inout) :: suite
    type(butcher_tableau) :: t
    real(real64) :: r

    t = classic_rk4()
    call suite%check_close('RK4 nodes', sum(t%a, dim=2), [0.0_real64, 0.5_real64, 0.5_real64, 1.0_real64], atol=1.0e-15_real64)
    ! Cooper and Verner's nodes take the values 0, 1/2, (7 -+ sqrt(21))/14 and 1 only (the
    ! order test below is what pins the coefficients).
    r = sqrt(21.0_real64)
    t = cooper_verner8()
    call suite%check_true('Cooper-Verner nodes in {0, 1/2, (7 -+ sqrt(21))/14, 1}', &
                          all(minval(abs(spread(sum(t%a, dim=2), 2, 5) - spread([0.0_real64, 0.5_real64, (7 - r)/14, &
                          (7 + r)/14, 1.0_real64], 1, 11)), dim=2) < 1.0e-14_real64))
    t = dormand_prince853()
    call suite%check_close('DOP853 nodes c2..c12 as published', sum(t%a(2:, :), dim=2), &
                           [0.526001519587677318785587544488e-01_real64, 0.789002279381515978178381316732e-01_real64, &
                            0.118350341907227396726757197510e+00_real64, 0.281649658092772603273242802490e+00_real64, &
                            1.0_real64/3, 0.25_real64, 4.0_real64/13, 127.0_real64/195, 0.6_real64, 6.0_real64/7, &
                            1.0_real64], atol=1.0e-14_real64)
    t = gauss_legendre3()
    call suite%check_close('Gauss-Legendre row sums = nodes 1/2 -+ sqrt(15)/10', sum(t%a, dim=2), t%c, atol=1.0e-15_real64)
    call suite%check_close('Gauss-Legendre nodes', t%c, [0.5_real64 - sqrt(15.0_real64)/10, 0.5_real64, &
                           0.5_real64 + sqrt(15.0_real64)/10], atol=1.0e-15_real64)
  end subroutine tableau_nodes

  !> sum_i b_i c_i^(k-1) = 1/k for k = 1..p (the quadrature conditions), and for Gauss-Legendre
  !> also the simplifying condition C(3): sum_j a_ij c_j^(k-1) = c_i^k / k, k = 1..3.
  subroutine quadrature_conditions(suite)
    type(test_suite), intent(inout) :: suite
    type(butcher_tableau) :: tableaux(4)
    integer :: m, k

    tableaux = [classic_rk4(), cooper_verner8(), dormand_prince853(), gauss_legendre3()]
    do m = 1, size(tableaux)
      associate (t => tableaux(m))
        do k = 1, t%order
          ! DOP853's weights (up to 5.8 in size, both signs) cost a few more digits.
          call suite%check_close(trim(t%name)//': sum b c^(k-1) = 1/k, k = '//achar(48 + k), &
                                 [sum(t%b*t%c**(k - 1))], [1.0_real64/k], atol=1.0e-14_real64)
        end do
        call suite%check_true(trim(t%name)//': weights >= 0 unless it is DOP853', &
                              all(t%b >= 0.0_real64) .neqv. t%name == 'Dormand-Prince 8(5,3)')
      end associate
    end do
    associate (t => tableaux(4))
      do k = 1, 3
        call suite%check_close('Gauss-Legendre C(3), k = '//achar(48 + k), matmul(t%a, t%c**(k - 1)), t%c**k/k, &
                               atol=2.0e-15_real64)
      end do
    end associate
  end subroutine quadrature_conditions

  !> Each tableau (unrelaxed) on Kepler's problem u'' = -u/|u|^3 from (1 - e, 0) with velocity
  !> (0, sqrt((1 + e)/(1 - e))), e = 1/2, over one unit of time; the exact solution comes from
  !> Kepler's equation. The observed order over three halvings of h is within 0.3 of the order.
  subroutine order_on_kepler(suite)
    type(test_suite), intent(inout) :: suite
    type(butcher_tableau) :: tableaux(4)
    real(real64) :: errors(3), exact(4), observed
    integer :: m, level, steps(4)

    tableaux = [classic_rk4(), cooper_verner8(), dormand_prince853(), gauss_legendre3()]
    steps = [40, 10, 10, 16]           ! the coarsest step count of each, in its asymptotic range
    exact = kepler_exact(1.0_real64)
    do m = 1, size(tableaux)
      do level = 1, 3
        errors(level) = maxval(abs(integrate(tableaux(m), steps(m)*2**(level - 1)) - exact))
      end do
      observed = log(errors(2)/errors(3))/log(2.0_real64)
      call suite%check_true(trim(tableaux(m)%name)//' has its order on Kepler''s problem', &
                            abs(observed - tableaux(m)%order) <= 0.3_real64, &
                            'observed '//scientific_text(observed)//', errors '//scientific_text(errors(1))//' ' &
                            //scientific_text(errors(2))//' '//scientific_text(errors(3)))
    end do
  end subroutine order_on_kepler

  !> One relaxed classic RK4 step (h = 0.05) of the pendulum in entropy variables from random
  !> states: the energy at the new state equals the old to round-off, J.a too, and only the
  !> momenta differ from z + gamma d. A random direction has no root near 1, and says so.
  subroutine relaxation_keeps_energy_and_momentum(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    real(real64) :: z(15), d(15), z_new(15), gamma, delta_energy, energy, entropy, theta(2)
    type(constraint_slot) :: no_constraints(0)
    integer :: trial, evaluations, stat
    logical :: found

    call seed_random(41)
    model = make_pendulum(params, tau_entropy)
    do trial = 1, 5
      z = random_state(model)
      d = rk4_direction(model, z, 0.05_real64)
      call relax(model, no_constraints, z, d, 0.0_real64, gamma, z_new, found, evaluations)
      call suite%check_true('a relaxation root exists', found)
      call model%energy_difference(z, z_new, delta_energy, stat)
      call model%observe(z, energy, entropy, theta, stat)
      call suite%check_true('E(z_new) - E(z) at round-off', abs(delta_energy) <= 4*epsilon(1.0_real64)*abs(energy), &
                            'difference '//scientific_text(delta_energy)//' J, E = '//scientific_text(energy))
      call suite%check_close('J.a unchanged', [model%conserved_momentum(z_new)], [model%conserved_momentum(z)], &
                             atol=1.0e-14_real64)
      call suite%check_close('only the momenta are corrected', [z_new(1:6), z_new(13:15)], &
                             [z(1:6) + gamma*d(1:6), z(13:15) + gamma*d(13:15)], atol=1.0e-15_real64)
      call suite%check_true('at most 6 energy evaluations', evaluations <= 6, &
                            scientific_text(real(evaluations, real64)))
    end do
    d = 0.01_real64*(random_state(model) - z)
    call relax(model, no_constraints, z, d, 0.0_real64, gamma, z_new, found, evaluations)
    call suite%check_true('no root for a direction off the flow', .not. found, 'gamma '//scientific_text(gamma))
  end subroutine relaxation_keeps_energy_and_momentum

  ! h sum_i b_i k_i of classic RK4 from z, with the model's continuous field.
  function rk4_direction(model, z, h) result(d)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), h
    real(real64) :: d(size(z)), k(size(z), 4), partials(model%max_invariants, 2, model%subsystem_count())
    type(butcher_tableau) :: t
    integer :: i, stat

    t = classic_rk4()
    do i = 1, 4
      call model%exact_partials(z + h*matmul(k(:, 1:i - 1), t%a(i, 1:i - 1)), partials, stat=stat)
      call model%vector_field(z + h*matmul(k(:, 1:i - 1), t%a(i, 1:i - 1)), partials, k(:, i))
    end do
    d = h*matmul(k, t%b)
  end function rk4_direction

  !> The Gauss-Legendre stage equations under g1, g2 and both, in entropy variables, at random
  !> states and stages: their Jacobian (the constrained field's, through the slaved tau and the
  !> index-1 multiplier) against central differences.
  subroutine constrained_stage_jacobian(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(stage_system) :: stages
    type(butcher_tableau) :: gauss
    real(real64) :: z(15), k(45), f(15), jacobian(45, 45), steps(45)
    integer :: case, trial, stat, i
    character(len=*), parameter :: names(3) = [character(len=5) :: 'g1', 'g2', 'both']

    call seed_random(7)
    gauss = gauss_legendre3()
    allocate (stages%model, source=make_pendulum(params, tau_entropy))
    stages%a = gauss%a
    stages%h = 0.05_real64
    do case = 1, 3
      do trial = 1, 3
        select type (model => stages%model)
        type is (pendulum)
          z = random_state(model)
        end select
        stages%constraints = constraint_set(case, norm2(z(q_index(:, 1))), params%mass(1))
        stages%z = z
        call constrained_field(stages%model, stages%constraints, z, f, stat)
        do i = 1, 3
          k((i - 1)*15 + 1:i*15) = f*(1.0_real64 + 0.01_real64*i)
        end do
        call stages%evaluate(k, f, jacobian, stat)
        call suite%check_true(trim(names(case))//': the stages are in the domain', stat == 0)
        steps = 1.0e-5_real64*(1.0_real64 + abs(k))
        call suite%check_true(trim(names(case))//': stage Jacobian against central differences', &
                              fd_jacobian_error(stages, k, jacobian, steps, fourth_order=.true.) < 1.0e-7_real64, &
                              'error '//scientific_text(fd_jacobian_error(stages, k, jacobian, steps, fourth_order=.true.)))
      end do
    end do
  end subroutine constrained_stage_jacobian

  !> g1's force keeps the hidden constraint: on the manifold (|q1| = length, q1.v1 = 0), the
  !> constrained field F has d(q1.v1)/dt = |v1|^2 + q1.(F_p1 - F_p2)/m1 = 0; the unconstrained
  !> field does not. With unequal masses, so that m1 must be the right mass.
  subroutine index_one_multiplier(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    type(constraint_slot), allocatable :: rod(:)
    real(real64) :: z(15), f(15), v1(3), rate, free_rate
    integer :: trial, stat

    call seed_random(11)
    params%mass = [1.7_real64, 0.6_real64]
    model = make_pendulum(params, tau_entropy)
    do trial = 1, 5
      z = random_state(model)
      rod = constraint_set(1, norm2(z(q_index(:, 1))), params%mass(1))
      call project_state(model, rod, model%conserved_momentum(z), z, stat)
      v1 = (z(p_index(:, 1)) - z(p_index(:, 2)))/params%mass(1)
      call suite%check_close('on the manifold: q1.v1 = 0', [dot_product(z(q_index(:, 1)), v1)], [0.0_real64], &
                             atol=1.0e-13_real64)
      call model%continuous_field(z, f, stat)
      free_rate = dot_product(v1, v1) + dot_product(z(q_index(:, 1)), f(p_index(:, 1)) - f(p_index(:, 2)))/params%mass(1)
      call constrained_field(model, rod, z, f, stat)
      rate = dot_product(v1, v1) + dot_product(z(q_index(:, 1)), f(p_index(:, 1)) - f(p_index(:, 2)))/params%mass(1)
      call suite%check_close('d(q1.v1)/dt = 0 under the force', [rate], [0.0_real64], atol=1.0e-12_real64*abs(free_rate))
      call suite%check_true('and not without it', abs(free_rate) > 1.0e-3_real64, scientific_text(free_rate))
    end do
  end subroutine index_one_multiplier

  ! g1 (case 1), g2 at 290 K (case 2) or both (case 3).
  function constraint_set(case, length, mass_1) result(set)
    integer, intent(in) :: case
    real(real64), intent(in) :: length, mass_1
    type(constraint_slot), allocatable :: set(:)

    select case (case)
    case (1)
      allocate (set(1))
      allocate (set(1)%item, source=make_fixed_length(length, mass_1))
    case (2)
      allocate (set(1))
      allocate (set(1)%item, source=make_fixed_temperature(1, 290.0_real64))
    case default
      allocate (set(2))
      allocate (set(1)%item, source=make_fixed_length(length, mass_1))
      allocate (set(2)%item, source=make_fixed_temperature(1, 290.0_real64))
    end select
  end function constraint_set

  !> A negative viscosity makes the entropy production negative. relaxed_rk8 (weights >= 0)
  !> would take the step with S falling, which shows the production is negative; relaxed_dp853
  !> must refuse every such step by its guard and stop with the guard's reason.
  subroutine entropy_guard(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(single_spring) :: model
    type(integrator_choice) :: choice
    class(time_stepper), allocatable, target :: integrator
    type(constraint_slot) :: no_constraints(0)
    type(step_report) :: report
    real(real64) :: z0(8), z1(8)
    integer :: ierr

    params%viscosity_const = -100.0_real64
    model = make_single_spring(params, tau_temperature)
    call model%state_from_temperature([1.6_real64, 0.4_real64, -1.0_real64], [0.5_real64, 1.2_real64, -0.3_real64], &
                                      0.3_real64, 310.0_real64, z0)
    choice%dt = 0.05_real64
    choice%t_end = 1.0_real64
    call new_relaxed_rk8(integrator)
    call integrator%start(choice, model, no_constraints, z0, ierr)
    call integrator%advance(z0, 0.0_real64, choice%dt, z0, z1, report, ierr)
    call suite%check_true('without a guard the step is taken and S falls', report%accepted .and. &
                          report%diagnostics(4) < 0.0_real64, 'entropy production '//scientific_text(report%diagnostics(4)))
    call new_relaxed_dp853(integrator)
    call integrator%start(choice, model, no_constraints, z0, ierr)
    call integrator%advance(z0, 0.0_real64, choice%dt, z0, z1, report, ierr)
    call suite%check_true('relaxed_dp853 refuses it', .not. report%accepted, report%reason)
    call suite%check_true('by its entropy guard', index(report%reason, 'entropy guard') > 0, report%reason)
    call suite%check_true('after rejecting and halving', report%rejected > 1, &
                          'rejections '//scientific_text(real(report%rejected, real64)))
  end subroutine entropy_guard

  ! The position and velocity of Kepler's problem (e = 1/2, period 2 pi) at time t.
  function kepler_exact(t) result(y)
    real(real64), intent(in) :: t
    real(real64) :: y(4)
    real(real64), parameter :: e = 0.5_real64
    real(real64) :: anomaly, factor
    integer :: k

    anomaly = t
    do k = 1, 60      ! Newton on Kepler's equation E - e sin E = t
      anomaly = anomaly - (anomaly - e*sin(anomaly) - t)/(1.0_real64 - e*cos(anomaly))
    end do
    factor = 1.0_real64/(1.0_real64 - e*cos(anomaly))
    y = [cos(anomaly) - e, sqrt(1.0_real64 - e**2)*sin(anomaly), &
         -sin(anomaly)*factor, sqrt(1.0_real64 - e**2)*cos(anomaly)*factor]
  end function kepler_exact

  ! Kepler's field u' = v, v' = -u/|u|^3.
  pure function kepler_field(y) result(f)
    real(real64), intent(in) :: y(4)
    real(real64) :: f(4)

    f = [y(3), y(4), -y(1:2)/norm2(y(1:2))**3]
  end function kepler_field

  ! The tableau's method over [0, 1] in `steps` steps; implicit stages by fixed-point iteration
  ! to round-off (h is small enough for it to contract).
  function integrate(t, steps) result(y)
    type(butcher_tableau), intent(in) :: t
    integer, intent(in) :: steps
    real(real64) :: y(4), k(4, t%stages), k_old(4, t%stages), h
    integer :: n, i, iteration

    y = kepler_exact(0.0_real64)
    h = 1.0_real64/steps
    do n = 1, steps
      k = 0.0_real64
      if (t%implicit) then
        do i = 1, t%stages
          k(:, i) = kepler_field(y)
        end do
        do iteration = 1, 200
          k_old = k
          do i = 1, t%stages
            k(:, i) = kepler_field(y + h*matmul(k_old, t%a(i, :)))
          end do
          if (maxval(abs(k - k_old)) <= 1.0e-15_real64) exit
        end do
      else
        do i = 1, t%stages
          k(:, i) = kepler_field(y + h*matmul(k(:, 1:i - 1), t%a(i, 1:i - 1)))
        end do
      end if
      y = y + h*matmul(k, t%b)
    end do
  end function integrate

end program test_relaxed_runge_kutta
