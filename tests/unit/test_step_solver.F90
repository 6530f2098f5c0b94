!> step_solver: SNES solves one step of every scheme to a root at which the discrete balance
!> laws hold (energy and J_z to round-off for EME, entropy non-decreasing); and a root with a
!> negative discrete temperature is rejected. That case is built deliberately: EME_u with
!> Gonzalez's quotient in the raw Euclidean metric at the paper's dt (FORMULATION section 5)
!> has, for its first step, a root with D_tau U_1/D_tau S_1 < 0; plain Newton reaches it from a
!> start with spring 1 compressed and 95 J of internal energy moved, and the solver, handed that
!> root as its guess, must reject it and still find a physical root of the same step.
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
  use number_text, only: scientific_text
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
  character(len=:), allocatable :: rejection
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
                            norm2(residual) < 1.0e-2_real64*tol, 'norm = '//scientific_text(norm2(residual)))
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

  ! Deliberate unphysical root: EME_u, Euclidean metric, first step of the paper scene.
  problem%model = make_pendulum(params, tau_internal_energy)
  problem%scheme = scheme_eme
  problem%gradient = gradient_gonzalez
  problem%metric = metric_euclidean
  problem%dt = dt
  z0 = paper_state(problem%model)
  problem%z_old = z0
  z1 = z0
  z1(1) = z1(1) - 0.6_real64                       ! spring 1 compressed ...
  z1(7) = z1(7) - 15.0_real64
  z1(10) = z1(10) - 5.0_real64
  z1(14) = z1(14) + 20.0_real64                    ! ... and internal energy moved
  z1(15) = z1(15) - 75.0_real64
  call plain_newton(problem, z1)
  call problem%evaluate(z1, residual, stat=stat)
  call problem%scheme_temperatures(z1, theta, stat)
  call suite%check_true('the step equation has a root with a negative discrete temperature', &
                        norm2(residual) < 1.0e-10_real64 .and. theta(1) < 0.0_real64, &
                        'residual '//scientific_text(norm2(residual))//', Theta_1 '//scientific_text(theta(1)))
  call problem%check_root(z1, rejection)
  call suite%check_true('check_root rejects it', index(rejection, 'discrete temperature') > 0, rejection)
  call solver%create(problem, tol, 50, ierr)
  call solver%solve_step(z0, dt, z1, z2, report, ierr)
  call suite%check_true('the solver, starting at that root, rejects it', &
                        report%rejected_roots >= 1 .and. index(report%last_rejection, 'discrete temperature') > 0, &
                        'rejected roots: '//scientific_text(real(report%rejected_roots, real64))//'; '//report%last_rejection)
  call suite%check_true('the step still ends at a root', report%accepted, report%reason)
  call solver%problem%scheme_temperatures(z2, theta, stat)
  call suite%check_true('the accepted root has positive discrete temperatures', all(theta > 0), &
                        'Theta = '//scientific_text(theta(1))//' '//scientific_text(theta(2)))
  call solver%destroy(ierr)

  call suite%finish()
  PetscCallA(PetscFinalize(ierr))

contains

  ! Newton with full steps and LAPACK, no root validation: goes wherever the start leads.
  subroutine plain_newton(problem, x)
    type(step_problem), intent(in) :: problem
    real(real64), intent(inout) :: x(state_size)
    real(real64) :: r(state_size), j(state_size, state_size)
    integer :: iteration, stat, info, pivots(state_size)
    interface
      subroutine dgesv(n, nrhs, a, lda, ipiv, b, ldb, info)
        import :: real64
        integer, intent(in) :: n, nrhs, lda, ldb
        real(real64), intent(inout) :: a(lda, *), b(ldb, *)
        integer, intent(out) :: ipiv(*), info
      end subroutine dgesv
    end interface

    do iteration = 1, 50
      call problem%evaluate(x, r, j, stat)
      if (stat /= 0 .or. norm2(r) < 1.0e-11_real64) return
      call dgesv(state_size, 1, j, state_size, pivots, r, state_size, info)
      if (info /= 0) return
      x = x - r
    end do
  end subroutine plain_newton

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

end program test_step_solver
