!> eme_bench [REPEATS] [PETSc options]: per-step cost of every scheme on the paper's scene
!> (make bench). Each scheme runs the 134 steps of the Fig. 4 scene REPEATS times (default 15)
!> after one warm-up run; only the stepping loop is timed (no output). Reported: the median
!> microseconds per step and the mean Newton iterations per step. The floor is the same EME_theta
!> step (same residual, Jacobian, predictor and convergence test) solved by a minimal Newton loop
!> with LAPACK's dgetf2 and dgetrs instead of SNES; the ratio SNES/floor comes from the same
!> process.
!> The last line is machine-readable:
!>   us_per_step=<EME_theta median> snes_over_floor=<ratio> newton_per_step=<EME_theta mean>
program eme_bench
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64, int64, output_unit, error_unit
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  use double_pendulum, only: state_size
  use step_residual, only: step_problem, scheme_eme, scheme_midpoint
  use step_solver, only: snes_solver
  use ts_integrator, only: ts_stepper, ts_midpoint, ts_rk4, ts_scheme_names
  use time_stepper, only: step_report
  use lapack_lu, only: dgetf2, dgetrs
  implicit none

  integer, parameter :: steps = 134
  real(real64), parameter :: dt = 0.15_real64, newton_tol = 1.0e-8_real64
  type(pendulum_parameters) :: params
  type(pendulum) :: model
  type(step_problem) :: problem
  type(snes_solver), target :: solver
  real(real64) :: z0(state_size), median_eme_theta, newton_eme_theta, median_floor, newton_floor
  real(real64), allocatable :: times(:)
  real(real64) :: factors(state_size, state_size), jacobian_scratch(state_size, state_size)
  integer :: pivots(state_size)
  integer :: repeats, variable, scheme, method, iterations, stat
  character(len=32) :: argument, label
  PetscErrorCode :: ierr

  PetscCallA(PetscInitialize(ierr))
  repeats = 15
  if (command_argument_count() >= 1) then
    call get_command_argument(1, argument)
    if (argument(1:1) /= '-') then    ! else a PETSc option
      read (argument, *, iostat=stat) repeats
      if (stat /= 0 .or. repeats < 1) call fail('REPEATS must be a whole number >= 1')
    end if
  end if
  allocate (times(repeats))
  write (output_unit, '(a, i0, a)') 'per-step cost on the paper scene (134 steps of 0.15 s), median of ', repeats, &
    ' runs after a warm-up; Newton iterations per step are means'
  write (output_unit, '(a, t44, a, t58, a)') 'scheme', 'us per step', 'Newton/step'

  do scheme = scheme_eme, scheme_midpoint
    do variable = tau_entropy, tau_internal_energy
      call set_problem(scheme, variable)
      call solver%prepare(problem, newton_tol, 50, ierr)
      if (ierr /= 0) call fail('PETSc failed to set up the solver')
      call time_snes(iterations)
      write (label, '(a, "_", a)') trim(merge('EME     ', 'midpoint', scheme == scheme_eme)), &
        trim(thermo_variable_names(variable))
      call report_line(label, iterations)
      if (scheme == scheme_eme .and. variable == tau_temperature) then
        median_eme_theta = median(times)/steps
        newton_eme_theta = real(iterations, real64)/steps
      end if
    end do
  end do
  call solver%destroy(ierr)
  if (ierr /= 0) call fail('PETSc failed to free the solver')

  do method = ts_midpoint, ts_rk4
    model = make_pendulum(params, tau_temperature)
    call model%state_from_temperatures([1.0_real64, 0.0_real64, 0.0_real64], [3.0_real64, 0.0_real64, 0.0_real64], &
      [0.0_real64, 0.0_real64, 0.0_real64], [-1.0_real64, -1.0_real64, 0.0_real64], 0.0_real64, &
      [280.0_real64, 350.0_real64], z0, stat)
    call time_ts(method, iterations)
    call report_line(trim(ts_scheme_names(method))//'_temperature', iterations)
  end do

  call set_problem(scheme_eme, tau_temperature)
  call time_floor(iterations)
  median_floor = median(times)/steps
  newton_floor = real(iterations, real64)/steps
  call report_line('floor: EME_temperature, LAPACK Newton loop', iterations)
  write (output_unit, '(a, f0.2, a, f0.2, a)') 'SNES/floor for EME_temperature: ', median_eme_theta/median_floor, &
    ' (Newton/step ', newton_eme_theta, ' with SNES)'
  write (output_unit, '("us_per_step=", f0.2, " snes_over_floor=", f0.3, " newton_per_step=", f0.3)') &
    median_eme_theta, median_eme_theta/median_floor, newton_eme_theta
  PetscCallA(PetscFinalize(ierr))

contains

  ! A benchmark that cannot run says why and exits with status 1.
  subroutine fail(text)
    character(len=*), intent(in) :: text

    write (error_unit, '(a)') 'eme_bench: '//text
    stop 1, quiet=.true.
  end subroutine fail

  subroutine set_problem(scheme, variable)
    integer, intent(in) :: scheme, variable

    model = make_pendulum(params, variable)
    call model%state_from_temperatures([1.0_real64, 0.0_real64, 0.0_real64], [3.0_real64, 0.0_real64, 0.0_real64], &
      [0.0_real64, 0.0_real64, 0.0_real64], [-1.0_real64, -1.0_real64, 0.0_real64], 0.0_real64, &
      [280.0_real64, 350.0_real64], z0, stat)
    problem%model = model
    problem%scheme = scheme
    problem%dt = dt
    problem%z_old = z0
  end subroutine set_problem

  ! The run's stepping loop with the SNES solver, timed; iterations of the last run.
  subroutine time_snes(iterations)
    integer, intent(out) :: iterations
    type(step_report) :: report
    real(real64) :: x(state_size), x_previous(state_size), x_new(state_size)
    integer :: run, n
    integer(int64) :: start, finish, rate

    do run = 0, repeats
      x = z0
      x_previous = z0
      iterations = 0
      call system_clock(start, rate)
      do n = 1, steps
        call solver%advance(x, (n - 1)*dt, dt, 2*x - x_previous, x_new, report, ierr)
        if (ierr /= 0 .or. .not. report%accepted) call fail('a step failed')
        iterations = iterations + report%newton_iterations
        x_previous = x
        x = x_new
      end do
      call system_clock(finish)
      if (run > 0) times(run) = real(finish - start, real64)/real(rate, real64)*1.0e6_real64
    end do
  end subroutine time_snes

  subroutine time_ts(method, iterations)
    integer, intent(in) :: method
    integer, intent(out) :: iterations
    type(ts_stepper), target :: ts
    type(step_report) :: report
    real(real64) :: x(state_size), x_new(state_size)
    integer :: run, n
    integer(int64) :: start, finish, rate

    do run = 0, repeats
      call ts%create(model, method, z0, dt, newton_tol, 50, 1.0e-10_real64, ierr)
      if (ierr /= 0) call fail('PETSc failed to set up the TS')
      x = z0
      iterations = 0
      call system_clock(start, rate)
      do n = 1, steps
        call ts%advance(x, (n - 1)*dt, dt, x, x_new, report, ierr)
        if (ierr /= 0 .or. .not. report%accepted) call fail('a TS step failed')
        iterations = iterations + report%newton_iterations
        x = x_new
      end do
      call system_clock(finish)
      call ts%destroy(ierr)
      if (ierr /= 0) call fail('PETSc failed to free the TS')
      if (run > 0) times(run) = real(finish - start, real64)/real(rate, real64)*1.0e6_real64
    end do
  end subroutine time_ts

  ! The floor: Newton with full steps and LAPACK's LU on the same residual and Jacobian, the
  ! same predictor (extrapolation refined by a chord step with the last LU, falling back to the
  ! old state) and the same convergence test.
  subroutine time_floor(iterations)
    integer, intent(out) :: iterations
    real(real64) :: x(state_size), x_previous(state_size), x_new(state_size), guess(state_size)
    integer :: run, n, its
    logical :: ok
    integer(int64) :: start, finish, rate

    do run = 0, repeats
      x = z0
      x_previous = z0
      iterations = 0
      call system_clock(start, rate)
      do n = 1, steps
        problem%z_old = x
        guess = 2*x - x_previous
        if (n > 1) call chord(guess)
        call newton(guess, x_new, its, ok)
        iterations = iterations + its
        if (.not. ok) then
          call newton(x, x_new, its, ok)
          iterations = iterations + its
          if (.not. ok) call fail('the floor Newton loop failed')
        end if
        x_previous = x
        x = x_new
      end do
      call system_clock(finish)
      if (run > 0) times(run) = real(finish - start, real64)/real(rate, real64)*1.0e6_real64
    end do
  end subroutine time_floor

  ! x := x - J^-1 R(x) with the factors of the last Newton iteration.
  subroutine chord(x)
    real(real64), intent(inout) :: x(state_size)
    real(real64) :: residual(state_size)
    integer :: stat, info

    call problem%evaluate(x, residual, stat=stat)
    if (stat /= 0) return
    call dgetrs('N', state_size, 1, factors, state_size, pivots, residual, state_size, info)
    if (info == 0) x = x - residual
  end subroutine chord

  subroutine newton(start, root, its, ok)
    real(real64), intent(in) :: start(state_size)
    real(real64), intent(out) :: root(state_size)
    integer, intent(out) :: its
    logical, intent(out) :: ok
    real(real64) :: residual(state_size), update(state_size)
    integer :: info, stat

    root = start
    ok = .false.
    call problem%evaluate(root, residual, factors, stat)
    do its = 1, 50
      if (stat /= 0) return
      update = -residual
      call dgetf2(state_size, state_size, factors, state_size, pivots, info)
      if (info /= 0) return
      call dgetrs('N', state_size, 1, factors, state_size, pivots, update, state_size, info)
      root = root + update
      call problem%evaluate(root, residual, jacobian_scratch, stat)
      if (stat == 0 .and. norm2(residual) <= newton_tol .and. norm2(update) <= newton_tol) then
        ok = .true.
        return
      end if
      factors = jacobian_scratch
    end do
  end subroutine newton

  subroutine report_line(label, iterations)
    character(len=*), intent(in) :: label
    integer, intent(in) :: iterations

    write (output_unit, '(a, t44, f11.2, f14.2)') label, median(times)/steps, real(iterations, real64)/steps
    flush (output_unit)
  end subroutine report_line

  function median(values) result(m)
    real(real64), intent(in) :: values(:)
    real(real64) :: m, sorted(size(values)), swap
    integer :: i, j

    sorted = values
    do i = 2, size(sorted)
      swap = sorted(i)
      j = i - 1
      do while (j >= 1)
        if (sorted(j) <= swap) exit
        sorted(j + 1) = sorted(j)
        j = j - 1
      end do
      sorted(j + 1) = swap
    end do
    m = 0.5_real64*(sorted((size(sorted) + 1)/2) + sorted(size(sorted)/2 + 1))
  end function median

end program eme_bench
