!> step_solver: SNES solves one step of every scheme to a root at which the discrete balance
!> laws hold (energy and J_z to round-off for EME, entropy non-decreasing); and a root with a
!> negative discrete temperature is rejected. That case is built deliberately: EME_u with
!> Gonzalez's quotient in the raw Euclidean metric at the paper's dt (FORMULATION section 5),
!> whose second step has such a root next to Newton's start.
program test_step_solver
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64
  use assertions, only: test_suite
  use fixtures, only: paper_state
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: make_pendulum
  use double_pendulum, only: state_size, angular_momentum
  use discrete_gradient, only: gradient_gonzalez, gradient_partitioned, metric_euclidean, discrete_gradient_names
  use step_residual, only: step_problem, scheme_eme, scheme_midpoint
  use step_solver, only: snes_solver
  use time_stepper, only: step_report
  implicit none

  type(test_suite) :: suite
  type(pendulum_parameters) :: params
  type(step_problem) :: problem
  type(snes_solver), target :: solver
  type(step_report) :: report
  real(real64), parameter :: dt = 0.15_real64, tol = 1.0e-8_real64
  real(real64) :: z0(state_size), z1(state_size), z2(state_size), residual(state_size), theta(2)
  real(real64) :: e0, e1, s0, s1, j0(3), j1(3)
  integer :: variable, kind, stat
  character(len=80) :: label
  PetscErrorCode :: ierr

  PetscCallA(PetscInitialize(ierr))
  suite%name = 'test_step_solver'

  do variable = tau_entropy, tau_internal_energy
    do kind = 0, gradient_partitioned
      problem%model = make_pendulum(params, variable)
      problem%scheme = merge(scheme_midpoint, scheme_eme, kind == 0)
      if (kind > 0) problem%gradient = kind
      label = case_label(variable, kind)
      z0 = paper_state(problem%model)
      call solver%create(problem, tol, 50, ierr)
      call solver%solve_step(z0, dt, z0, z1, report, ierr)
      call suite%check_true('step accepted, '//trim(label), report%accepted .and. ierr == 0, report%reason)
      call solver%problem%evaluate(z1, residual, stat=stat)
      ! The update criterion takes Newton well past the residual tolerance.
      call suite%check_true('residual at the root far below newton_tol, '//trim(label), &
                            norm2(residual) < 1.0e-2_real64*tol, 'norm = '//real_text(norm2(residual)))
      call problem%model%observe(z0, e0, s0, theta, stat)
      call problem%model%observe(z1, e1, s1, theta, stat)
      j0 = angular_momentum(z0)
      j1 = angular_momentum(z1)
      call suite%check_close('J_z conserved, '//trim(label), [j1(3)], [j0(3)], atol=1.0e-13_real64)
      if (kind > 0 .or. variable == tau_internal_energy) &
        call suite%check_close('energy conserved, '//trim(label), [e1], [e0], rtol=1.0e-14_real64)
      if (kind > 0 .or. variable == tau_entropy) &
        call suite%check_true('entropy does not fall, '//trim(label), s1 - s0 >= -1.0e-13_real64)
      call solver%destroy(ierr)
    end do
  end do

  ! Deliberate unphysical root: EME_u, Euclidean metric. Step 2 from the predictor converges to
  ! a root whose discrete temperature is negative; the solver must reject it and go on to a
  ! physical root of the same step (same dt).
  problem%model = make_pendulum(params, tau_internal_energy)
  problem%scheme = scheme_eme
  problem%gradient = gradient_gonzalez
  problem%metric = metric_euclidean
  z0 = paper_state(problem%model)
  call solver%create(problem, tol, 50, ierr)
  call solver%solve_step(z0, dt, z0, z1, report, ierr)
  call solver%solve_step(z1, dt, 2*z1 - z0, z2, report, ierr)
  call suite%check_true('a root with negative discrete temperature was found and rejected', &
                        report%rejected_roots >= 1 .and. index(report%last_rejection, 'discrete temperature') > 0, &
                        'rejected roots: '//real_text(real(report%rejected_roots, real64))//'; '//report%last_rejection)
  call suite%check_true('the step still ends at a root', report%accepted, report%reason)
  call solver%problem%scheme_temperatures(z2, theta, stat)
  call suite%check_true('the accepted root has positive discrete temperatures', all(theta > 0), &
                        'Theta = '//real_text(theta(1))//real_text(theta(2)))
  call solver%destroy(ierr)

  call suite%finish()
  PetscCallA(PetscFinalize(ierr))

contains

  function case_label(variable, kind) result(label)
    integer, intent(in) :: variable, kind
    character(len=80) :: label

    select case (kind)
    case (gradient_gonzalez, gradient_partitioned)
      label = trim(thermo_variable_names(variable))//' eme '//trim(discrete_gradient_names(kind))
    case default
      label = trim(thermo_variable_names(variable))//' midpoint'
    end select
  end function case_label

  function real_text(x) result(text)
    real(real64), intent(in) :: x
    character(len=12) :: text

    write (text, '(es12.4)') x
  end function real_text

end program test_step_solver
