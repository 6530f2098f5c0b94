!> eme_bench [REPEATS] [PETSc options]: per-step cost of every scheme on the paper's scene and the
!> constrained scenes of Fig. 5 (make bench). Each case runs the 134 steps of its scene REPEATS
!> times (default 15) after one warm-up run; only the stepping loop is timed (no output).
!>
!> Every discrete-gradient case is timed twice per repeat, alternately: through the integrator as
!> a run uses it (PETSc SNES on the fused kernel, the retry strategies), and on the floor, the same
!> steps solved by a hand-written Newton loop on the same fused kernel (same predictor and chord
!> refinement, same final chord step, same convergence test and root check, the same dense LU, no
!> PETSc; src/solver/hand_newton). Each repeat runs every case in turn, and each case alternates
!> SNES and floor, in one process, so that the machine's drifts spread over all cases and stay out
!> of the ratio; reported are the medians of each and the median of the per-repeat ratios. The
!> PETSc TS baselines are timed alone afterwards, for reference. SUNDIALS CVODE (cvode_bdf at the
!> default tolerance, 1e-10) runs in the round robin too, once per repeat, and EME_theta's cost
!> per step is reported as the median of its per-repeat ratios to CVODE's cost per internal step.
!> The last line is machine-readable:
!>   us_per_step=<EME_theta median> snes_over_floor=<its ratio> newton_per_step=<EME_theta mean>
program eme_bench
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64, int64, output_unit, error_unit
  use thermo_variable_kinds, only: tau_entropy, tau_temperature, tau_internal_energy
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use pendulum_scene, only: double_pendulum_scene
  use pendulum_step_kernel, only: pendulum_step, build_pendulum_step, condensed_offset
  use retry_strategies, only: root_search, find_root
  use hand_newton, only: newton_loop
  use solver_options, only: step_solver_options, read_solver_options
  use integrator_settings, only: integrator_choice
  use integrator_registry, only: integrator_entry, find_integrator, build_integrator
  use discrete_gradient_stepper, only: step_solver
  use stepper, only: time_stepper, step_report
  use statistics, only: median
  use failures, only: failure_type
  use command_line, only: benchmark_repeats, petsc_help_requested, has_argument
  use library_versions, only: print_versions
  implicit none

  integer, parameter :: steps = 134, max_iterations = 50
  real(real64), parameter :: dt = 0.15_real64, newton_tol = 1.0e-8_real64


  !> One case: a scheme on a scene, what its runs need, and its SNES and floor timings (us per
  !> step, per repeat).
  type :: bench_case
    character(len=40) :: label = ''
    character(len=16) :: scheme = ''
    integer :: variable = tau_temperature
    logical :: fix_length = .false.
    logical :: fix_temperature = .false.
    real(real64), allocatable :: snes_times(:), floor_times(:)
    integer :: snes_iterations = 0, floor_iterations = 0, solves = 0
    integer :: factorizations = 0        !! SNES's LU factorizations in one run
    class(time_stepper), allocatable :: integrator
    type(integrator_choice) :: choice
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:), x0(:)
    type(constraint_slot), allocatable :: constraints(:)
    type(pendulum_step) :: kernel        !! the floor's
    type(newton_loop) :: floor
  end type bench_case

  character(len=*), parameter :: ts_schemes(3) = [character(len=11) :: 'ts_midpoint', 'ts_bdf2', 'ts_rk4']
  type(bench_case), allocatable :: cases(:)
  type(bench_case) :: cvode                         !! cvode_bdf on the paper scene (its SNES fields unused)
  type(step_solver_options) :: options
  real(real64), allocatable :: times(:), cvode_times(:), cvode_internal(:), eme_over_cvode(:)
  integer :: cvode_steps, cvode_solves
  integer :: repeats, k, iterations, theta_case, run
  PetscErrorCode :: ierr
  type(failure_type) :: failure

  ! --help, -h and --version answer at once, wherever they stand, without PETSc and without timing.
  if (has_argument([character(len=6) :: '--help', '-h'])) then
    call print_usage()
    stop
  else if (has_argument(['--version'])) then
    call print_versions(output_unit, 'eme_bench')
    stop
  end if
  PetscCallA(PetscInitialize(ierr))
  if (petsc_help_requested()) then
    ! PETSc's -help: the usage, then (as PETSc prints them while they are read) the -eme_* options.
    call print_usage()
    call read_solver_options(options, failure)
    PetscCallA(PetscFinalize(ierr))
    stop
  end if
  call benchmark_repeats(15, repeats, failure)
  if (failure%failed()) call fail(failure%message)
  call read_solver_options(options, failure)
  if (failure%failed()) call fail('cannot read the -eme_* options')
  allocate (times(repeats), cvode_times(repeats), cvode_internal(repeats), eme_over_cvode(repeats))

  cases = [bench_case('EME_entropy', 'eme', tau_entropy), bench_case('EME_temperature', 'eme', tau_temperature), &
           bench_case('EME_internal_energy', 'eme', tau_internal_energy), &
           bench_case('midpoint_entropy', 'midpoint', tau_entropy), &
           bench_case('midpoint_temperature', 'midpoint', tau_temperature), &
           bench_case('midpoint_internal_energy', 'midpoint', tau_internal_energy), &
           bench_case('EME_temperature + length', 'eme', tau_temperature, fix_length=.true.), &
           bench_case('EME_temperature + temperature', 'eme', tau_temperature, fix_temperature=.true.), &
           bench_case('EME_temperature + both', 'eme', tau_temperature, fix_length=.true., fix_temperature=.true.)]
  theta_case = 2

  write (output_unit, '(a, i0, a)') 'per-step cost (134 steps of 0.15 s), medians of ', repeats, &
    ' repeats after a warm-up, SNES and floor alternating per repeat; Newton/step are means'
  write (output_unit, '(a, t34, a, t48, a, t62, a, t76, a, t90, a, t104, a)') 'case', 'SNES us/step', &
    'floor us/step', 'SNES/floor', 'Newton/step', 'LU/step', 'SNES us/solve'
  ! Round robin: every repeat runs every case, so that the machine's drifts spread over all of them.
  do k = 1, size(cases)
    call set_up_case(cases(k))
  end do
  call set_up_cvode(cvode)
  do run = 0, repeats
    do k = 1, size(cases)
      call repeat_case(cases(k), run)
    end do
    call cvode%integrator%start(cvode%choice, cvode%model, cvode%constraints, cvode%z0, failure)   ! CVODE carries its state
    if (failure%failed()) call fail('SUNDIALS CVODE failed to start')
    times(1) = snes_run(cvode%integrator, cvode%x0, cvode_steps, cvode_solves)
    if (run > 0) then
      cvode_times(run) = times(1)
      cvode_internal(run) = times(1)*steps/cvode_solves
      eme_over_cvode(run) = cases(theta_case)%snes_times(run)/cvode_internal(run)
    end if
  end do
  call cvode%integrator%release(failure)
  do k = 1, size(cases)
    call cases(k)%integrator%release(failure)
    if (failure%failed()) call fail('PETSc failed to free '//trim(cases(k)%label))
    associate (c => cases(k))
      write (output_unit, '(a, t34, f12.2, f14.2, f14.3, f14.2, f14.2, f14.2)') trim(c%label), median(c%snes_times), &
        median(c%floor_times), median(c%snes_times/c%floor_times), real(c%snes_iterations, real64)/steps, &
        real(c%factorizations, real64)/steps, (median(c%snes_times) - median(c%floor_times))*steps/c%solves
      if (c%floor_iterations /= c%snes_iterations) write (output_unit, '(2x, a, i0, a, i0, a)') &
        '(the floor took ', c%floor_iterations, ' Newton iterations, SNES ', c%snes_iterations, ')'
    end associate
    flush (output_unit)
  end do
  do k = 1, size(ts_schemes)
    call time_ts(trim(ts_schemes(k)), iterations)
    write (output_unit, '(a, t34, f12.2, t76, f14.2)') trim(ts_schemes(k))//'_temperature', median(times), &
      real(iterations, real64)/steps
  end do
  write (output_unit, '(a, t34, f12.2, a, f0.1, a, f0.2, a)') 'cvode_bdf_temperature', median(cvode_times), &
    ' (', real(cvode_solves, real64)/steps, ' internal steps per step, ', median(cvode_internal), ' us each)'
  write (output_unit, '(a, f0.2, a)') 'EME_temperature per step over cvode_bdf per internal step: ', &
    median(eme_over_cvode), ' (median of the per-repeat ratios)'
  write (output_unit, '(a, 2(f0.3, a))') 'EME_entropy and EME_internal_energy over EME_temperature: ', &
    median(cases(1)%snes_times)/median(cases(theta_case)%snes_times), ' and ', &
    median(cases(3)%snes_times)/median(cases(theta_case)%snes_times), ''
  write (output_unit, '("us_per_step=", f0.2, " snes_over_floor=", f0.3, " newton_per_step=", f0.3)') &
    median(cases(theta_case)%snes_times), median(cases(theta_case)%snes_times/cases(theta_case)%floor_times), &
    real(cases(theta_case)%snes_iterations, real64)/steps
  PetscCallA(PetscFinalize(ierr))

contains

  !> The usage and what the benchmark does (--help, -h, and PETSc's -help before its option list).
  subroutine print_usage()
    write (output_unit, '(a)') 'usage: eme_bench [REPEATS] [PETSc options]', '', &
      'Times the stepping loop of every scheme on the paper scene and the Fig. 5 constrained scenes (134', &
      'steps of 0.15 s): per repeat, alternately through PETSc SNES as a run does and by a hand-written', &
      'Newton loop on the same fused kernel (the floor); medians of REPEATS runs (default 15) after a', &
      'warm-up, per step, with Newton iterations per step; the PETSc TS baselines alone. The -eme_*', &
      'options (-help lists them) switch the speed-ups off one by one. A benchmark, not a test: the last', &
      'line is machine-readable: us_per_step=... snes_over_floor=... newton_per_step=...', '', &
      '--help, -h: this text; --version: the code''s and the libraries'' versions; -help: this text and', &
      'the PETSc options the benchmark reads. Each prints and exits with status 0.'
  end subroutine print_usage


  ! A benchmark that cannot run says why and exits with status 1.
  subroutine fail(text)
    character(len=*), intent(in) :: text

    write (error_unit, '(a)') 'eme_bench: '//text
    stop 1, quiet=.true.
  end subroutine fail

  ! The paper scene, with the case's constraints (Fig. 5: length |q1(0)| = 1 m, theta_1 = 280 K):
  ! the model, its initial state z0 and the run's initial unknowns x0 = (z0, multipliers 0).
  subroutine set_scene(c, model, z0, constraints, x0)
    type(bench_case), intent(in) :: c
    class(generic_model), allocatable, intent(out) :: model
    real(real64), allocatable, intent(out) :: z0(:), x0(:)
    type(constraint_slot), allocatable, intent(out) :: constraints(:)
    type(double_pendulum_scene) :: scene

    scene%fix_length = c%fix_length
    scene%length = norm2(scene%q1)
    scene%fix_temperature = c%fix_temperature
    scene%temperature = scene%theta(1)
    call scene%build(c%variable, model, z0, constraints, failure)
    if (failure%failed()) call fail(failure%message)
    x0 = [z0, spread(0.0_real64, 1, size(constraints))]
  end subroutine set_scene

  ! cvode_bdf on the paper scene at the default tolerance.
  subroutine set_up_cvode(c)
    type(bench_case), intent(inout), target :: c
    type(integrator_entry) :: entry
    logical :: found

    c%label = 'cvode_bdf_temperature'
    call set_scene(c, c%model, c%z0, c%constraints, c%x0)
    c%choice%dt = dt
    c%choice%thermo_variable = tau_temperature
    call find_integrator('cvode_bdf', entry, found)
    if (.not. found) call fail('no integrator cvode_bdf')
    call build_integrator(entry, c%integrator)
  end subroutine set_up_cvode

  ! A case's integrator, scene and floor.
  subroutine set_up_case(c)
    type(bench_case), intent(inout), target :: c
    type(integrator_entry) :: entry
    logical :: found, built

    call set_scene(c, c%model, c%z0, c%constraints, c%x0)
    c%choice%dt = dt
    c%choice%newton_tol = newton_tol
    c%choice%newton_max_iterations = max_iterations
    c%choice%thermo_variable = c%variable
    call find_integrator(trim(c%scheme), entry, found)
    if (.not. found) call fail('no integrator '//trim(c%scheme))
    call build_integrator(entry, c%integrator)
    call start_run(c%integrator, c%choice, c%model, c%constraints, c%z0, c%label)
    select type (integrator => c%integrator)
    type is (step_solver)
      call build_pendulum_step(integrator%problem, c%kernel, built)
    class default
      built = .false.
    end select
    if (.not. built) call fail('no fused kernel for '//trim(c%label))
    call c%floor%prepare(c%kernel%unknowns(), newton_tol, max_iterations)
    c%floor%chord_predictor = options%chord_predictor
    c%floor%final_chord = options%final_chord
    c%floor%modified_newton = options%modified_newton
    c%floor%reuse%chord_iterations = options%chord_iterations
    allocate (c%snes_times(repeats), c%floor_times(repeats))
  end subroutine set_up_case

  ! Repeat `run` of a case (0: the warm-up): its SNES run, then its floor run.
  subroutine repeat_case(c, run)
    type(bench_case), intent(inout), target :: c
    integer, intent(in) :: run
    integer :: factorizations

    if (run > 0) call start_run(c%integrator, c%choice, c%model, c%constraints, c%z0, c%label)
    factorizations = integrator_factorizations(c%integrator)
    c%snes_times(max(run, 1)) = snes_run(c%integrator, c%x0, c%snes_iterations, c%solves)
    c%factorizations = integrator_factorizations(c%integrator) - factorizations
    c%floor_times(max(run, 1)) = floor_run(c%floor, c%kernel, c%x0, c%floor_iterations)
  end subroutine repeat_case

  ! A run's start, as eme_run makes it (no LU factors from an earlier run); not timed.
  subroutine start_run(integrator, choice, model, constraints, z0, label)
    class(time_stepper), intent(inout), target :: integrator
    type(integrator_choice), intent(in) :: choice
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    character(len=*), intent(in) :: label

    call integrator%start(choice, model, constraints, z0, failure)
    if (failure%failed()) call fail('PETSc failed to set up '//trim(label))
  end subroutine start_run

  ! The LU factorizations of a discrete-gradient integrator's solver so far.
  integer function integrator_factorizations(integrator)
    class(time_stepper), intent(in) :: integrator

    integrator_factorizations = 0
    select type (integrator)
    type is (step_solver)
      integrator_factorizations = integrator%solver%factorizations()
    end select
  end function integrator_factorizations

  ! The stepping loop of a run through the integrator; us per step, its Newton iterations and solves.
  function snes_run(integrator, x0, iterations, solves) result(us)
    class(time_stepper), intent(inout), target :: integrator
    real(real64), intent(in) :: x0(:)
    integer, intent(out) :: iterations, solves
    real(real64) :: us
    type(step_report) :: report
    real(real64) :: x(size(x0)), x_previous(size(x0)), x_new(size(x0))
    integer(int64) :: start, finish, rate
    integer :: n

    x = x0
    x_previous = x0
    iterations = 0
    solves = 0
    call system_clock(start, rate)
    do n = 1, steps
      call integrator%advance(x, (n - 1)*dt, dt, 2*x - x_previous, x_new, report, failure)
      if (failure%failed() .or. .not. report%accepted) call fail('a step failed: '//report%reason)
      iterations = iterations + report%newton_iterations
      solves = solves + report%solves
      x_previous = x
      x = x_new
    end do
    call system_clock(finish)
    us = real(finish - start, real64)/real(rate, real64)*1.0e6_real64/steps
  end function snes_run

  ! The same steps on the floor: the stepper's search (src/integrator/discrete_gradient_stepper)
  ! on the kernel with the hand-written Newton loop as its root finder.
  function floor_run(floor, kernel, x0, iterations) result(us)
    type(newton_loop), intent(inout) :: floor
    type(pendulum_step), intent(inout), target :: kernel
    real(real64), intent(in) :: x0(:)
    integer, intent(out) :: iterations
    real(real64) :: us
    type(root_search) :: search
    real(real64) :: x(size(x0)), x_previous(size(x0)), guess(size(x0)), y(size(x0) - condensed_offset)
    integer(int64) :: start, finish, rate
    integer :: n

    x = x0
    x_previous = x0
    iterations = 0
    floor%lu%ready = .false.
    call system_clock(start, rate)
    do n = 1, steps
      call kernel%set_old_state(x)
      guess = 2*x - x_previous
      call find_root(floor, kernel, x(condensed_offset + 1:), kernel%condense(guess), y, search, failure)
      if (.not. search%accepted) call fail('a floor step failed: '//search%reason)
      iterations = iterations + search%newton_iterations
      x_previous = x
      x = kernel%expand(y)
    end do
    call system_clock(finish)
    us = real(finish - start, real64)/real(rate, real64)*1.0e6_real64/steps
  end function floor_run


  ! A TS baseline's stepping loop, timed; Newton iterations of the last run.
  subroutine time_ts(name, iterations)
    character(len=*), intent(in) :: name
    integer, intent(out) :: iterations
    class(time_stepper), allocatable, target :: integrator
    type(integrator_entry) :: entry
    type(integrator_choice) :: choice
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:), x0(:)
    type(constraint_slot), allocatable :: constraints(:)
    integer :: run, solves
    logical :: found

    call set_scene(bench_case(name, name, tau_temperature), model, z0, constraints, x0)
    choice%dt = dt
    choice%newton_tol = newton_tol
    choice%thermo_variable = tau_temperature
    call find_integrator(name, entry, found)
    if (.not. found) call fail('no integrator '//name)
    call build_integrator(entry, integrator)
    do run = 0, repeats
      call integrator%start(choice, model, constraints, z0, failure)    ! a TS carries its state
      if (failure%failed()) call fail('PETSc failed to set up '//name)
      times(max(run, 1)) = snes_run(integrator, x0, iterations, solves)
    end do
    call integrator%release(failure)
  end subroutine time_ts

end program eme_bench
