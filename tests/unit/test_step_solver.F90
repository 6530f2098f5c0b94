!> The discrete-gradient steps through PETSc SNES (discrete_gradient_stepper with snes_solver and
!> retry_strategies): one step of every scheme ends at a root at which the discrete balance laws
!> hold (energy and J_z to round-off for EME, entropy non-decreasing); and a root with a negative
!> discrete temperature is rejected. That case is built deliberately: EME_u with Gonzalez's
!> quotient in the raw Euclidean metric at the paper's dt (FORMULATION section 5) has, for its
!> first step, a root with D_tau U_1/D_tau S_1 < 0; plain Newton reaches it from a start with
!> spring 1 compressed and 95 J of internal energy moved, and the stepper, handed that root as
!> its guess, must reject it and still find a physical root of the same step.
program test_step_solver
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use unit_testing, only: unit_test, run_unit_tests
  use fixtures, only: paper_state
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  use single_spring_model, only: single_spring, make_single_spring
  use double_pendulum, only: state_size, angular_momentum
  use model_constraint, only: constraint_slot
  use number_text, only: scientific_text
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, metric_euclidean, discrete_gradient_names
  use dense_lu, only: lu_factors
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint
  use integrator_settings, only: integrator_choice
  use discrete_gradient_stepper, only: step_solver, new_eme, new_midpoint
  use stepper, only: time_stepper, step_report
  use pendulum_scene, only: double_pendulum_scene
  use model_interface, only: generic_model
  use pendulum_step_kernel, only: pendulum_step, build_pendulum_step, condensed_offset
  use lapack_newton, only: newton_loop
  use retry_strategies, only: root_search, find_root
  implicit none

  real(real64), parameter :: dt = 0.15_real64, tol = 1.0e-8_real64
  integer, parameter :: midpoint = 0
  PetscErrorCode :: ierr

  PetscCallA(PetscInitialize(ierr))
  call run_unit_tests('test_step_solver', [ &
    unit_test('first_step_of_each_scheme', first_step_of_each_scheme), &
    unit_test('unphysical_root_rejected', unphysical_root_rejected), &
    unit_test('single_spring_steps', single_spring_steps), &
    unit_test('lean_snes_is_the_newton_loop', lean_snes_is_the_newton_loop), &
    unit_test('standard_way_factors_once', standard_way_factors_once), &
    unit_test('jacobian_options_keep_snes_standard', jacobian_options_keep_snes_standard)])
  PetscCallA(PetscFinalize(ierr))

contains

  !> The first step of the paper scene for EME (both gradients) and the midpoint rule.
  subroutine first_step_of_each_scheme(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    type(integrator_choice) :: choice
    class(time_stepper), allocatable, target :: integrator
    type(constraint_slot) :: no_constraints(0)
    type(step_report) :: report
    real(real64) :: z0(state_size), z1(state_size), residual(state_size), theta(2), e0, e1, s0, s1, j0(3), j1(3)
    integer :: variable, kind, stat, ierr
    character(len=80) :: label

    choice%dt = dt
    choice%newton_tol = tol
    do variable = tau_entropy, tau_internal_energy
      do kind = midpoint, gradient_partitioned
        model = make_pendulum(params, variable)
        choice%thermo_variable = variable
        if (kind == midpoint) then
          call new_midpoint(integrator)
        else
          call new_eme(integrator)
          choice%discrete_gradient = kind
        end if
        label = case_label(variable, kind)
        z0 = paper_state(model)
        call integrator%start(choice, model, no_constraints, z0, ierr)
        call integrator%advance(z0, 0.0_real64, dt, z0, z1, report, ierr)
        call suite%check_true('step accepted, '//trim(label), report%accepted .and. ierr == 0, report%reason)
        select type (integrator)
        type is (step_solver)
          call integrator%problem%evaluate(z1, residual, stat=stat)
        end select
        ! The update criterion takes Newton well past the residual tolerance.
        call suite%check_true('residual at the root far below newton_tol, '//trim(label), &
                              norm2(residual) < 1.0e-2_real64*tol, 'norm = '//scientific_text(norm2(residual)))
        call model%observe(z0, e0, s0, theta, stat)
        call model%observe(z1, e1, s1, theta, stat)
        j0 = angular_momentum(z0)
        j1 = angular_momentum(z1)
        call suite%check_close('J_z conserved, '//trim(label), [j1(3)], [j0(3)], atol=1.0e-13_real64)
        if (kind /= midpoint .or. variable == tau_internal_energy) &
          call suite%check_close('energy conserved, '//trim(label), [e1], [e0], rtol=1.0e-14_real64)
        if (kind /= midpoint .or. variable == tau_entropy) &
          call suite%check_true('entropy does not fall, '//trim(label), s1 - s0 >= -1.0e-13_real64)
        call integrator%release(ierr)
      end do
    end do
  end subroutine first_step_of_each_scheme

  !> EME_u, Euclidean metric, first step of the paper scene: the stepper handed an unphysical
  !> root rejects it and finds a physical one.
  subroutine unphysical_root_rejected(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(pendulum) :: model
    type(integrator_choice) :: choice
    type(step_solver), target :: stepper
    type(constraint_slot) :: no_constraints(0)
    type(step_report) :: report
    real(real64) :: z0(state_size), z1(state_size), z2(state_size), residual(state_size), theta(2)
    character(len=:), allocatable :: rejection
    integer :: stat, ierr

    model = make_pendulum(params, tau_internal_energy)
    choice%thermo_variable = tau_internal_energy
    choice%discrete_gradient = gradient_gonzalez
    choice%metric = metric_euclidean
    choice%dt = dt
    choice%newton_tol = tol
    z0 = paper_state(model)
    call stepper%start(choice, model, no_constraints, z0, ierr)
    z1 = z0
    z1(1) = z1(1) - 0.6_real64                       ! spring 1 compressed ...
    z1(7) = z1(7) - 15.0_real64
    z1(10) = z1(10) - 5.0_real64
    z1(14) = z1(14) + 20.0_real64                    ! ... and internal energy moved
    z1(15) = z1(15) - 75.0_real64
    call plain_newton(stepper%problem, z1)
    call stepper%problem%evaluate(z1, residual, stat=stat)
    call stepper%problem%scheme_temperatures(z1, theta, stat)
    call suite%check_true('the step equation has a root with a negative discrete temperature', &
                          norm2(residual) < 1.0e-10_real64 .and. theta(1) < 0.0_real64, &
                          'residual '//scientific_text(norm2(residual))//', Theta_1 '//scientific_text(theta(1)))
    call stepper%problem%check_root(z1, rejection)
    call suite%check_true('check_root rejects it', index(rejection, 'discrete temperature') > 0, rejection)
    call stepper%advance(z0, 0.0_real64, dt, z1, z2, report, ierr)
    call suite%check_true('the stepper, starting at that root, rejects it', &
                          report%rejected >= 1 .and. index(report%last_rejection, 'discrete temperature') > 0, &
                          'rejected roots: '//scientific_text(real(report%rejected, real64))//'; '//report%last_rejection)
    call suite%check_true('the step still ends at a root', report%accepted, report%reason)
    call stepper%problem%scheme_temperatures(z2, theta, stat)
    call suite%check_true('the accepted root has positive discrete temperatures', all(theta > 0), &
                          'Theta = '//scientific_text(theta(1))//' '//scientific_text(theta(2)))
    call stepper%release(ierr)
  end subroutine unphysical_root_rejected

  ! Newton with full steps and LAPACK, no root validation: goes wherever the start leads.
  subroutine plain_newton(problem, x)
    type(step_problem), intent(in) :: problem
    real(real64), intent(inout) :: x(state_size)
    real(real64) :: r(state_size), j(state_size, state_size)
    type(lu_factors) :: lu
    integer :: iteration, stat, info

    call lu%reset(state_size)
    do iteration = 1, 50
      call problem%evaluate(x, r, j, stat)
      if (stat /= 0 .or. norm2(r) < 1.0e-11_real64) return
      call lu%factor(j, info)
      if (info /= 0) return
      call lu%solve(r, info)
      x = x - r
    end do
  end subroutine plain_newton

  !> EME on a second model through the same stepper (8 unknowns, one subsystem): 20 steps in
  !> every thermodynamic variable conserve E and J_z to round-off and never lose entropy.
  subroutine single_spring_steps(suite)
    type(test_suite), intent(inout) :: suite
    type(pendulum_parameters) :: params
    type(single_spring) :: model
    type(integrator_choice) :: choice
    class(time_stepper), allocatable, target :: integrator
    type(constraint_slot) :: no_constraints(0)
    type(step_report) :: report
    real(real64) :: z0(8), z(8), z_new(8), theta(1), e0, e, s_old, s, s_start, j0(3), j(3), worst_energy, worst_jz, least_ds
    integer :: variable, n, stat, ierr
    logical :: accepted

    choice%dt = 0.05_real64
    choice%newton_tol = tol
    do variable = tau_entropy, tau_internal_energy
      model = make_single_spring(params, variable)
      choice%thermo_variable = variable
      call new_eme(integrator)
      call model%state_from_temperature([1.6_real64, 0.4_real64, -1.0_real64], [0.5_real64, 1.2_real64, -0.3_real64], &
                                        0.08_real64, 310.0_real64, z0)
      call integrator%start(choice, model, no_constraints, z0, ierr)
      call model%observe(z0, e0, s_old, theta, stat)
      s_start = s_old
      j0 = model%angular_momentum(z0)
      z = z0
      accepted = .true.
      worst_energy = 0.0_real64
      worst_jz = 0.0_real64
      least_ds = huge(1.0_real64)
      do n = 1, 20
        call integrator%advance(z, (n - 1)*choice%dt, choice%dt, z, z_new, report, ierr)
        accepted = accepted .and. report%accepted .and. ierr == 0
        if (.not. accepted) exit
        z = z_new
        call model%observe(z, e, s, theta, stat)
        j = model%angular_momentum(z)
        worst_energy = max(worst_energy, abs(e - e0)/abs(e0))
        worst_jz = max(worst_jz, abs(j(3) - j0(3)))
        least_ds = min(least_ds, s - s_old)
        s_old = s
      end do
      associate (label => 'single spring, '//trim(thermo_variable_names(variable)))
        call suite%check_true('20 steps accepted, '//label, accepted, report%reason)
        call suite%check_true('energy conserved, '//label, worst_energy < 1.0e-13_real64, &
                              'max relative drift '//scientific_text(worst_energy))
        call suite%check_true('J_z conserved, '//label, worst_jz < 1.0e-13_real64, 'max drift '//scientific_text(worst_jz))
        call suite%check_true('entropy never falls, '//label, least_ds >= -1.0e-13_real64, &
                              'least increment '//scientific_text(least_ds))
        call suite%check_true('the damper produces entropy, '//label, s_old - s_start > 0.0_real64, &
                              'S_20 - S_0 = '//scientific_text(s_old - s_start))
      end associate
      call integrator%release(ierr)
    end do
  end subroutine single_spring_steps

  !> The lean SNES way adds nothing to the iteration: 30 steps of the paper scene (and its Fig. 5
  !> constraints) through the stepper end at the roots, after the Newton iterations, of the
  !> hand-written loop on the same kernel under the same search (src/solver/lapack_newton).
  subroutine lean_snes_is_the_newton_loop(suite)
    type(test_suite), intent(inout) :: suite
    integer :: variable, set

    do variable = tau_entropy, tau_internal_energy
      call compare_with_loop(suite, 'eme', variable, 0)
      call compare_with_loop(suite, 'midpoint', variable, 0)
    end do
    do set = 1, 3
      call compare_with_loop(suite, 'eme', tau_internal_energy, set)
    end do
  end subroutine lean_snes_is_the_newton_loop

  ! One scheme on the paper scene with the constraint set `set` (bit 0 length, bit 1 temperature).
  subroutine compare_with_loop(suite, scheme, variable, set)
    type(test_suite), intent(inout) :: suite
    character(len=*), intent(in) :: scheme
    integer, intent(in) :: variable, set
    type(integrator_choice) :: choice
    type(step_solver), target :: stepper
    type(pendulum_step), target :: kernel
    type(newton_loop) :: loop
    type(root_search) :: search
    type(step_report) :: report
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:), x(:), x_previous(:), x_new(:), y(:)
    real(real64) :: worst
    integer :: n, ierr, snes_iterations, loop_iterations
    logical :: built
    character(len=100) :: label

    call paper_scene(variable, set, model, z0, constraints)
    choice%dt = dt
    choice%newton_tol = tol
    choice%thermo_variable = variable
    stepper%partials_rule = merge(partials_midpoint, partials_discrete_gradient, scheme == 'midpoint')
    call stepper%start(choice, model, constraints, z0, ierr)
    call build_pendulum_step(stepper%problem, kernel, built)
    call loop%prepare(kernel%unknowns(), tol, choice%newton_max_iterations)
    write (label, '(a, 1x, a, a, i0)') scheme, trim(thermo_variable_names(variable)), ', constraints ', set
    call suite%check_true('the stepper is fused and lean, '//trim(label), stepper%fused .and. stepper%solver%lean())
    x = [z0, spread(0.0_real64, 1, size(constraints))]
    x_previous = x
    x_new = x
    y = x(condensed_offset + 1:)
    worst = 0.0_real64
    snes_iterations = 0
    loop_iterations = 0
    do n = 1, 30
      call stepper%advance(x, (n - 1)*dt, dt, 2*x - x_previous, x_new, report, ierr)
      call kernel%set_old_state(x)
      call find_root(loop, kernel, x(condensed_offset + 1:), kernel%condense(2*x - x_previous), y, search, ierr)
      if (.not. (report%accepted .and. search%accepted)) exit
      snes_iterations = snes_iterations + report%newton_iterations
      loop_iterations = loop_iterations + search%newton_iterations
      worst = max(worst, maxval(abs(x_new(condensed_offset + 1:) - y)/max(1.0_real64, abs(y))))
      x_previous = x
      x = x_new
    end do
    call suite%check_true('30 steps, '//trim(label), n > 30, report%reason//search%reason)
    call suite%check_equal_int('Newton iterations as the loop''s, '//trim(label), snes_iterations, loop_iterations)
    call suite%check_true('roots as the loop''s, '//trim(label), worst < 1.0e-13_real64, 'largest relative difference ' &
                          //scientific_text(worst))
    call stepper%release(ierr)
  end subroutine compare_with_loop

  !> The standard SNES way (-eme_lean_snes false: SNES computes the Jacobian, PCSetUp factors it)
  !> factors each Jacobian once: the shell reads the matrix without changing its state.
  subroutine standard_way_factors_once(suite)
    type(test_suite), intent(inout) :: suite
    type(integrator_choice) :: choice
    type(step_solver), target :: stepper
    type(step_report) :: report
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:), x(:), x_new(:)
    integer :: n, ierr, iterations

    PetscCallA(PetscOptionsSetValue(PETSC_NULL_OPTIONS, '-eme_lean_snes', 'false', ierr))
    call paper_scene(tau_entropy, 0, model, z0, constraints)
    choice%dt = dt
    choice%newton_tol = tol
    choice%thermo_variable = tau_entropy
    call stepper%start(choice, model, constraints, z0, ierr)
    call suite%check_true('-eme_lean_snes false: the standard way', .not. stepper%solver%lean())
    x = z0
    x_new = z0
    iterations = 0
    do n = 1, 5
      call stepper%advance(x, (n - 1)*dt, dt, x, x_new, report, ierr)
      iterations = iterations + report%newton_iterations
      x = x_new
    end do
    call suite%check_equal_int('one LU factorization per Newton iteration', stepper%solver%factorizations(), iterations)
    call stepper%release(ierr)
    PetscCallA(PetscOptionsClearValue(PETSC_NULL_OPTIONS, '-eme_lean_snes', ierr))
  end subroutine standard_way_factors_once

  !> Options that need SNES's own Jacobian or linear solver keep SNES the standard way, and
  !> -pc_type lu then solves with PETSc's LU: the steps end at the same roots.
  subroutine jacobian_options_keep_snes_standard(suite)
    type(test_suite), intent(inout) :: suite
    type(integrator_choice) :: choice
    type(step_solver), target :: lean, standard
    type(step_report) :: report
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:), x(:), x_lean(:), x_standard(:)
    integer :: n, ierr

    call paper_scene(tau_temperature, 0, model, z0, constraints)
    choice%dt = dt
    choice%newton_tol = tol
    choice%thermo_variable = tau_temperature
    call lean%start(choice, model, constraints, z0, ierr)
    PetscCallA(PetscOptionsSetValue(PETSC_NULL_OPTIONS, '-pc_type', 'lu', ierr))
    call standard%start(choice, model, constraints, z0, ierr)
    PetscCallA(PetscOptionsClearValue(PETSC_NULL_OPTIONS, '-pc_type', ierr))
    call suite%check_true('-pc_type lu: the standard way', lean%solver%lean() .and. .not. standard%solver%lean())
    call suite%check_equal_int('-pc_type lu: PETSc factors, not the shell', standard%solver%factorizations(), 0)
    x = z0
    x_lean = z0
    x_standard = z0
    do n = 1, 5
      call lean%advance(x, (n - 1)*dt, dt, x, x_lean, report, ierr)
      call standard%advance(x, (n - 1)*dt, dt, x, x_standard, report, ierr)
      call suite%check_close('-pc_type lu: the same root', x_standard, x_lean, rtol=1.0e-10_real64, atol=1.0e-12_real64)
      x = x_lean
    end do
    call suite%check_equal_int('-pc_type lu: still no factorization by the shell', standard%solver%factorizations(), 0)
    call lean%release(ierr)
    call standard%release(ierr)
  end subroutine jacobian_options_keep_snes_standard

  ! The paper scene with the constraint set `set` (bit 0: length |q1(0)|, bit 1: theta_1 = 280 K).
  subroutine paper_scene(variable, set, model, z0, constraints)
    integer, intent(in) :: variable, set
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:)
    type(constraint_slot), allocatable, intent(out) :: constraints(:)
    type(double_pendulum_scene) :: scene
    character(len=:), allocatable :: message
    integer :: stat

    scene%fix_length = btest(set, 0)
    scene%length = norm2(scene%q1)
    scene%fix_temperature = btest(set, 1)
    scene%temperature = scene%theta(1)
    call scene%build(variable, model, z0, constraints, stat, message)
    if (stat /= 0) error stop 'test_step_solver: the paper scene cannot be built'
  end subroutine paper_scene

  function case_label(variable, kind) result(label)
    integer, intent(in) :: variable, kind
    character(len=80) :: label

    if (kind == midpoint) then
      label = trim(thermo_variable_names(variable))//' midpoint'
    else
      label = trim(thermo_variable_names(variable))//' eme '//trim(discrete_gradient_names(kind))
    end if
  end function case_label

end program test_step_solver
