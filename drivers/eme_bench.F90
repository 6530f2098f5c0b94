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
  use thermo_variable, only: tau_entropy, tau_temperature, tau_internal_energy, thermo_variable_names
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use pendulum_scene, only: double_pendulum_scene
  use step_residual, only: step_problem
  use dense_lu, only: lu_factors
  use integrator_settings, only: integrator_choice
  use integrator_registry, only: integrator_entry, find_integrator
  use stepper, only: time_stepper, step_report
  implicit none

  integer, parameter :: steps = 134
  real(real64), parameter :: dt = 0.15_real64, newton_tol = 1.0e-8_real64
  character(len=*), parameter :: snes_schemes(2) = [character(len=8) :: 'eme', 'midpoint']
  character(len=*), parameter :: ts_schemes(3) = [character(len=11) :: 'ts_midpoint', 'ts_bdf2', 'ts_rk4']
  type(double_pendulum_scene) :: scene
  type(integrator_choice) :: choice
  type(step_problem) :: problem           ! the floor's step
  type(lu_factors) :: lu                  ! the floor's factors
  class(generic_model), allocatable :: model
  type(constraint_slot), allocatable :: constraints(:)
  real(real64), allocatable :: z0(:), times(:)
  real(real64) :: median_eme_theta, newton_eme_theta, median_floor
  integer :: repeats, variable, k, iterations, stat
  character(len=32) :: argument, label
  character(len=:), allocatable :: message
  PetscErrorCode :: ierr

  if (command_argument_count() >= 1) then
    call get_command_argument(1, argument)
    if (argument == '--help' .or. argument == '-h') then
      write (output_unit, '(a)') 'usage: eme_bench [REPEATS] [PETSc options]', '', &
        'Times the stepping loop of every scheme on the paper scene (134 steps of 0.15 s): the median of', &
        'REPEATS runs (default 15) after a warm-up, per step, with Newton iterations per step; then the', &
        'same EME_theta step solved by a minimal LAPACK Newton loop (the floor). A benchmark, not a test:', &
        'the last line is machine-readable: us_per_step=... snes_over_floor=... newton_per_step=...'
      stop
    end if
  end if
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
  choice%dt = dt
  choice%newton_tol = newton_tol
  write (output_unit, '(a, i0, a)') 'per-step cost on the paper scene (134 steps of 0.15 s), median of ', repeats, &
    ' runs after a warm-up; Newton iterations per step are means'
  write (output_unit, '(a, t44, a, t58, a)') 'scheme', 'us per step', 'Newton/step'

  do k = 1, size(snes_schemes)
    do variable = tau_entropy, tau_internal_energy
      call time_scheme(trim(snes_schemes(k)), variable, fresh_start=.false., iterations=iterations)
      write (label, '(a, "_", a)') trim(merge('EME     ', 'midpoint', k == 1)), trim(thermo_variable_names(variable))
      call report_line(label, iterations)
      if (k == 1 .and. variable == tau_temperature) then
        median_eme_theta = median(times)/steps
        newton_eme_theta = real(iterations, real64)/steps
      end if
    end do
  end do
  do k = 1, size(ts_schemes)
    call time_scheme(trim(ts_schemes(k)), tau_temperature, fresh_start=.true., iterations=iterations)
    call report_line(trim(ts_schemes(k))//'_temperature', iterations)
  end do

  call time_floor(iterations)
  median_floor = median(times)/steps
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

  ! The paper scene's model and initial state in thermodynamic variable `variable`.
  subroutine set_scene(variable)
    integer, intent(in) :: variable

    call scene%build(variable, model, z0, constraints, stat, message)
    if (stat /= 0) call fail(message)
  end subroutine set_scene

  ! The run's stepping loop of integrator `name` from the registry, timed; iterations of the
  ! last run. fresh_start: the integrator starts anew for every repeat (a TS carries its state).
  subroutine time_scheme(name, variable, fresh_start, iterations)
    character(len=*), intent(in) :: name
    integer, intent(in) :: variable
    logical, intent(in) :: fresh_start
    integer, intent(out) :: iterations
    class(time_stepper), allocatable, target :: integrator
    type(integrator_entry) :: entry
    type(step_report) :: report
    real(real64), allocatable :: x(:), x_previous(:), x_new(:)
    integer :: run, n
    integer(int64) :: start, finish, rate
    logical :: found

    call set_scene(variable)
    choice%thermo_variable = variable
    call find_integrator(name, entry, found)
    if (.not. found) call fail('no integrator '//name)
    call entry%build(integrator)
    allocate (x(size(z0)), x_previous(size(z0)), x_new(size(z0)))
    do run = 0, repeats
      if (run == 0 .or. fresh_start) then
        call integrator%start(choice, model, constraints, z0, ierr)
        if (ierr /= 0) call fail('PETSc failed to set up '//name)
      end if
      x = z0
      x_previous = z0
      iterations = 0
      call system_clock(start, rate)
      do n = 1, steps
        call integrator%advance(x, (n - 1)*dt, dt, 2*x - x_previous, x_new, report, ierr)
        if (ierr /= 0 .or. .not. report%accepted) call fail('a step of '//name//' failed')
        iterations = iterations + report%newton_iterations
        x_previous = x
        x = x_new
      end do
      call system_clock(finish)
      if (run > 0) times(run) = real(finish - start, real64)/real(rate, real64)*1.0e6_real64
    end do
    call integrator%release(ierr)
    if (ierr /= 0) call fail('PETSc failed to free '//name)
  end subroutine time_scheme

  ! The floor: Newton with full steps and LAPACK's LU on the same EME_theta residual and
  ! Jacobian, the same predictor (extrapolation refined by a chord step with the last LU,
  ! falling back to the old state) and the same convergence test.
  subroutine time_floor(iterations)
    integer, intent(out) :: iterations
    real(real64), allocatable :: x(:), x_previous(:), x_new(:), guess(:)
    integer :: run, n, its
    logical :: ok
    integer(int64) :: start, finish, rate

    call set_scene(tau_temperature)
    allocate (problem%model, source=model)
    allocate (problem%constraints(0))
    problem%dt = dt
    call lu%reset(model%state_size)
    allocate (x(size(z0)), x_previous(size(z0)), x_new(size(z0)), guess(size(z0)))
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

  ! The floor's chord step: x := x - J^-1 R(x) with the factors of the last Newton iteration.
  subroutine chord(x)
    real(real64), intent(inout) :: x(:)
    real(real64) :: residual(size(x))
    integer :: stat, info

    call problem%evaluate(x, residual, stat=stat)
    if (stat /= 0) return
    call lu%solve(residual, info)
    if (info == 0) x = x - residual
  end subroutine chord

  ! The floor's Newton loop: full steps, the solver's convergence test.
  subroutine newton(initial, root, its, ok)
    real(real64), intent(in) :: initial(:)
    real(real64), allocatable, intent(inout) :: root(:)
    integer, intent(out) :: its
    logical, intent(out) :: ok
    real(real64) :: residual(size(initial)), update(size(initial)), jacobian(size(initial), size(initial))
    integer :: info, stat

    root = initial
    ok = .false.
    call problem%evaluate(root, residual, jacobian, stat)
    do its = 1, 50
      if (stat /= 0) return
      update = -residual
      call lu%factor(jacobian, info)
      if (info /= 0) return
      call lu%solve(update, info)
      root = root + update
      call problem%evaluate(root, residual, jacobian, stat)
      if (stat == 0 .and. norm2(residual) <= newton_tol .and. norm2(update) <= newton_tol) then
        ok = .true.
        return
      end if
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
