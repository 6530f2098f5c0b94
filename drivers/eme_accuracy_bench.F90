!> eme_accuracy_bench [REPEATS] [PETSc options]: CPU time to a given accuracy on the paper scene
!> at t = 5 s (make bench; docs/performance.md). A benchmark,
!> not a test.
!>
!> The error of a run is max(|q, p, gamma - reference|, |theta_a - reference|/theta_ref) at
!> t = 5 s, against PETSc's adaptive Dormand-Prince (ts_rk5dp) at tolerance 1e-13, which
!> relaxed_dp853 at 1e-13 cross-checks. For every scheme and target error (1e-4 and 1e-6) the
!> step (fixed-step schemes) or tolerance (adaptive ones) is calibrated first: from a start
!> value, a run's error and the scheme's order predict the setting that meets the target, with
!> a margin, until a run meets it. Then every chosen configuration runs REPEATS times (default
!> 5), one configuration after the other within each repeat, so that the machine's drift hits
!> all alike, and the median CPU time of the whole integration (no output) is reported with the
!> run's largest relative energy error over its steps. The last line is machine-readable.
program eme_accuracy_bench
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64, output_unit, error_unit
  use thermo_variable_kinds, only: tau_temperature
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use pendulum_scene, only: double_pendulum_scene
  use integrator_settings, only: integrator_choice
  use integrator_registry, only: integrator_entry, find_integrator, build_integrator
  use stepper, only: time_stepper, step_report
  use statistics, only: median
  use failures, only: failure_type
  use command_line, only: benchmark_repeats, petsc_help_requested, has_argument
  use library_versions, only: print_versions
  implicit none

  !> A scheme under test: its registry name, whether it is adaptive (calibrated in tolerance,
  !> else in dt), its order (of the error in dt, or about 1 in the tolerance) and where the
  !> calibration starts.
  type :: candidate
    character(len=16) :: name
    logical :: adaptive
    real(real64) :: order
    real(real64) :: start
  end type candidate

  !> A calibrated configuration and what it measured.
  type :: configuration
    integer :: scheme = 0
    integer :: target = 0                       !! in targets(:)
    real(real64) :: setting = 0.0_real64
    real(real64) :: error = 0.0_real64
    real(real64) :: energy_error = 0.0_real64
    integer :: steps = 0
    real(real64), allocatable :: seconds(:)
  end type configuration

  real(real64), parameter :: t_end = 5.0_real64
  real(real64), parameter :: targets(2) = [1.0e-4_real64, 1.0e-6_real64]
  integer, parameter :: max_calibration_runs = 12
  type(candidate), parameter :: candidates(8) = [ &
    candidate('relaxed_rk8', .false., 8.0_real64, 0.05_real64), &
    candidate('relaxed_dp853', .true., 1.0_real64, 1.0e-6_real64), &
    candidate('relaxed_gauss6', .false., 6.0_real64, 0.05_real64), &
    candidate('relaxed_rk4', .false., 4.0_real64, 0.01_real64), &
    candidate('cvode_bdf', .true., 1.0_real64, 1.0e-6_real64), &
    candidate('cvode_adams', .true., 1.0_real64, 1.0e-6_real64), &
    candidate('ts_rk5dp', .true., 1.0_real64, 1.0e-6_real64), &
    candidate('eme', .false., 2.0_real64, 0.001_real64)]
  type(double_pendulum_scene) :: scene
  class(generic_model), allocatable :: model
  type(constraint_slot), allocatable :: constraints(:)
  type(configuration) :: configurations(size(candidates)*size(targets))
  real(real64), allocatable :: z0(:), reference(:), end_state(:)
  real(real64) :: cross_check, seconds, cvode_seconds
  integer :: repeats, k, c, run, steps
  PetscErrorCode :: ierr
  type(failure_type) :: failure

  ! --help, -h and --version answer at once, wherever they stand, without PETSc and without timing.
  if (has_argument([character(len=6) :: '--help', '-h'])) then
    call print_usage()
    stop
  else if (has_argument(['--version'])) then
    call print_versions(output_unit, 'eme_accuracy_bench')
    stop
  end if
  PetscCallA(PetscInitialize(ierr))
  if (petsc_help_requested()) then
    ! PETSc's -help (PETSc has printed its own options): the usage, and no benchmark.
    call print_usage()
    PetscCallA(PetscFinalize(ierr))
    stop
  end if
  call benchmark_repeats(5, repeats, failure)
  if (failure%failed()) call fail(failure%message)
  call scene%build(tau_temperature, model, z0, constraints, failure)
  if (failure%failed()) call fail(failure%message)

  call integrate('ts_rk5dp', .true., 1.0e-13_real64, reference, seconds, steps)
  call integrate('relaxed_dp853', .true., 1.0e-13_real64, end_state, seconds, steps)
  cross_check = state_error(end_state)
  write (output_unit, '(a, es8.1, a)') 'paper scene to t = 5 s; reference ts_rk5dp at tolerance 1e-13, which '// &
    'relaxed_dp853 at 1e-13 matches to ', cross_check, ' (the error below is relative to theta_ref for temperatures)'
  flush (output_unit)

  do c = 1, size(candidates)
    do k = 1, size(targets)
      call calibrate(c, k, configurations((c - 1)*size(targets) + k))
    end do
  end do
  do run = 1, repeats
    do k = 1, size(configurations)
      associate (config => configurations(k))
        call integrate(candidates(config%scheme)%name, candidates(config%scheme)%adaptive, config%setting, &
                       end_state, seconds, steps)
        config%seconds(run) = seconds
      end associate
    end do
  end do

  cvode_seconds = median(configurations(index_of('cvode_bdf', 1))%seconds)
  write (output_unit, '(/, a, i0, a)') 'CPU time of the whole integration, median of ', repeats, ' alternating runs:'
  write (output_unit, '(a, t17, a, t28, a, t41, a, t50, a, t60, a, t72, a, t86, a, t100, a)') 'scheme', 'target', &
    'setting', 'error', 'steps', 'energy', 'CPU [ms]', '/CVODE-BDF', '/EME'
  do k = 1, size(configurations)
    associate (config => configurations(k))
      write (output_unit, '(a, t17, es8.1, t26, a, t39, es9.2, t50, i0, t58, es9.2, t71, f10.3, t86, f9.3, t100, f9.4)') &
        trim(candidates(config%scheme)%name), targets(config%target), setting_text(config), config%error, config%steps, &
        config%energy_error, 1.0e3_real64*median(config%seconds), median(config%seconds)/cvode_seconds, &
        median(config%seconds)/median(configurations(index_of('eme', config%target))%seconds)
    end associate
  end do
  write (output_unit, '(/, a)') '(setting: dt [s] or tolerance; energy: the largest relative energy error over the '// &
    'steps; /CVODE-BDF: the ratio to cvode_bdf at 1e-4; /EME: to EME_theta at the same target)'
  write (output_unit, '(a, f0.3, a, f0.3, a, f0.3, a, f0.3, a, f0.3)') &
    'rrk8_1e-6_ms=', 1.0e3_real64*median(configurations(index_of('relaxed_rk8', 2))%seconds), &
    ' rdp853_1e-6_ms=', 1.0e3_real64*median(configurations(index_of('relaxed_dp853', 2))%seconds), &
    ' cvode_bdf_1e-4_ms=', 1.0e3_real64*cvode_seconds, &
    ' rrk8_1e-6_over_cvode_bdf_1e-4=', median(configurations(index_of('relaxed_rk8', 2))%seconds)/cvode_seconds, &
    ' rdp853_1e-6_over_cvode_bdf_1e-4=', &
    median(configurations(index_of('relaxed_dp853', 2))%seconds)/cvode_seconds
  PetscCallA(PetscFinalize(ierr))

contains

  !> The usage and what the benchmark does (--help, -h, and PETSc's -help).
  subroutine print_usage()
    write (output_unit, '(a)') 'usage: eme_accuracy_bench [REPEATS] [PETSc options]', '', &
      'CPU time to an error of 1e-4 and 1e-6 at t = 5 s on the paper scene for the relaxed Runge-Kutta', &
      'schemes, CVODE, ts_rk5dp and EME_theta: each setting calibrated to its target, then the median of', &
      'REPEATS (default 5) alternating runs. A benchmark, not a test; the last line is machine-readable.', '', &
      '--help, -h: this text; --version: the code''s and the libraries'' versions; -help: PETSc''s help and', &
      'this text. Each prints and exits with status 0.'
  end subroutine print_usage


  ! A benchmark that cannot run says why and exits with status 1.
  subroutine fail(text)
    character(len=*), intent(in) :: text

    write (error_unit, '(a)') 'eme_accuracy_bench: '//text
    stop 1, quiet=.true.
  end subroutine fail

  ! The setting of candidate c whose error meets `target`: from the start value, each run's
  ! error e predicts the next setting by the order p, s <- s (0.7 target/e)^(1/p) for dt and
  ! s (0.5 target/e) for a tolerance, until a run meets the target.
  subroutine calibrate(c, k, config)
    integer, intent(in) :: c, k
    type(configuration), intent(out) :: config
    real(real64) :: setting, error, seconds, energy_error, target
    real(real64), allocatable :: state(:)
    integer :: attempt, steps

    target = targets(k)
    setting = candidates(c)%start
    do attempt = 1, max_calibration_runs
      call integrate(candidates(c)%name, candidates(c)%adaptive, setting, state, seconds, steps, energy_error)
      error = state_error(state)
      if (error <= target) then
        config = configuration(scheme=c, target=k, setting=setting, error=error, energy_error=energy_error, &
                               steps=steps)
        allocate (config%seconds(repeats))
        return
      end if
      setting = setting*min(0.9_real64, (0.7_real64*target/error)**(1.0_real64/candidates(c)%order))
    end do
    call fail('cannot calibrate '//trim(candidates(c)%name)//' to its target')
  end subroutine calibrate

  ! One integration of `name` from z0 to t_end at dt = setting (fixed-step) or tolerance =
  ! setting (adaptive, one output step), without output: its end state, CPU time, steps (output
  ! steps of the time loop) and, if asked (then the CPU time includes it), the largest relative
  ! energy error over them.
  subroutine integrate(name, adaptive, setting, state, seconds, steps, energy_error)
    character(len=*), intent(in) :: name
    logical, intent(in) :: adaptive
    real(real64), intent(in) :: setting
    real(real64), allocatable, intent(out) :: state(:)
    real(real64), intent(out) :: seconds
    integer, intent(out) :: steps
    real(real64), intent(out), optional :: energy_error
    class(time_stepper), allocatable, target :: integrator
    type(integrator_entry) :: entry
    type(integrator_choice) :: choice
    type(step_report) :: report
    real(real64) :: x(size(z0)), x_previous(size(z0)), x_new(size(z0))
    real(real64) :: time, start, finish, energy, energy_0, entropy, theta(model%subsystem_count())
    logical :: found, finished
    integer :: stat

    call find_integrator(name, entry, found)
    if (.not. found) call fail('no integrator '//name)
    choice%thermo_variable = tau_temperature
    choice%t_end = t_end
    choice%dt = t_end
    if (adaptive) then
      choice%tolerance = setting
    else
      choice%dt = setting
    end if
    ! A scheme on the output grid n dt needs a dt that divides t_end.
    if (.not. (adaptive .or. entry%chooses_time)) choice%dt = t_end/ceiling(t_end/setting - 1.0e-9_real64)
    call build_integrator(entry, integrator)
    call integrator%start(choice, model, constraints, z0, failure)
    if (failure%failed()) call fail('cannot start '//name)
    x = z0
    x_previous = z0
    time = 0.0_real64
    steps = 0
    finished = .false.
    call model%observe(z0, energy_0, entropy, theta, stat)
    if (present(energy_error)) energy_error = 0.0_real64
    call cpu_time(start)
    do while (.not. finished)
      call integrator%advance(x, time, choice%dt, 2*x - x_previous, x_new, report, failure)
      if (failure%failed() .or. .not. report%accepted) call fail('a step of '//trim(name)//' failed: '//report%reason)
      steps = steps + 1
      if (entry%chooses_time) then
        time = report%time
      else
        time = steps*choice%dt
      end if
      finished = time >= t_end*(1.0_real64 - 1.0e-12_real64)
      x_previous = x
      x = x_new
      if (present(energy_error)) then
        call model%observe(x, energy, entropy, theta, stat)
        energy_error = max(energy_error, abs(energy - energy_0)/abs(energy_0))
      end if
    end do
    call cpu_time(finish)
    seconds = finish - start
    if (abs(time - t_end) > 1.0e-12_real64*t_end) call fail(name//' did not end at t = 5 s')
    state = x
    call integrator%release(failure)
  end subroutine integrate

  ! The study's error measure against the reference (temperatures relative to theta_ref = 300 K).
  real(real64) function state_error(state)
    real(real64), intent(in) :: state(:)
    real(real64) :: energy, entropy, theta(model%subsystem_count()), theta_reference(model%subsystem_count())
    integer :: stat

    call model%observe(state, energy, entropy, theta, stat)
    call model%observe(reference, energy, entropy, theta_reference, stat)
    state_error = max(maxval(abs(state(1:13) - reference(1:13))), maxval(abs(theta - theta_reference))/300.0_real64)
  end function state_error

  ! The configuration of scheme `name` at targets(target).
  integer function index_of(name, target)
    character(len=*), intent(in) :: name
    integer, intent(in) :: target
    integer :: k

    do k = 1, size(configurations)
      index_of = k
      if (candidates(configurations(k)%scheme)%name == name .and. configurations(k)%target == target) return
    end do
    call fail('no configuration '//name)
  end function index_of

  function setting_text(config) result(text)
    type(configuration), intent(in) :: config
    character(len=12) :: text

    if (candidates(config%scheme)%adaptive) then
      write (text, '("tol ", es8.1)') config%setting
    else
      write (text, '("dt ", f9.6)') config%setting
    end if
  end function setting_text

end program eme_accuracy_bench
