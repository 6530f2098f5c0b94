!> One run from a validated configuration to its HDF5 file: the time loop shared by eme_run
!> and eme_ensemble. A step that cannot be solved ends the run cleanly: every step before it
!> stays in the file, whose `status` attribute then reads 'incomplete: <reason>'.
module simulation
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use thermo_variable, only: thermo_variable_names
  use pendulum_model, only: pendulum, make_pendulum
  use double_pendulum, only: state_size, state_column_names, angular_momentum
  use discrete_gradient, only: discrete_gradient_names, metric_names, metric_nondimensional, quotient_threshold
  use step_residual, only: step_problem, scheme_eme, scheme_names
  use step_solver, only: snes_solver
  use ts_integrator, only: ts_stepper
  use time_stepper, only: stepper, step_report
  use run_config, only: run_configuration, step_count, scheme_choices, is_ts_scheme
  use hdf5_series, only: hdf5_file, series_table
  use filesystem, only: make_parent_directories
  use build_info, only: code_version
  use number_text, only: integer_text, fixed_text
  implicit none
  private
  public :: run_summary, run_simulation, run_observer

  !> The figures a run is judged by, as the summary table prints them.
  type :: run_summary
    character(len=:), allocatable :: status       !! 'complete' or 'incomplete: <reason>'
    integer :: steps_planned = 0
    integer :: steps_completed = 0
    integer :: newton_iterations = 0
    real(real64) :: energy_drift = 0.0_real64            !! max_n |E_n - E_0 - Q_n| / |E_0|, Q: boundary heat
    real(real64) :: min_entropy_increment = huge(1.0_real64)    !! NaN without a completed step
    real(real64) :: max_lyapunov_increment = -huge(1.0_real64)  !! NaN without a completed step
    real(real64) :: angular_momentum_drift = 0.0_real64  !! max_n |J_z,n - J_z,0|
    real(real64) :: wall_seconds = 0.0_real64             !! the whole run, file set-up and closing included
    real(real64) :: solve_seconds = 0.0_real64            !! the time loop alone
  end type run_summary

  !> Something that wants control after every accepted step (the ensemble's scheduler serves
  !> other ranks from there while rank 0 computes a case).
  type, abstract :: run_observer
  contains
    procedure(after_step_interface), deferred :: after_step
  end type run_observer

  abstract interface
    !> Called after each accepted step.
    subroutine after_step_interface(self)
      import :: run_observer
      class(run_observer), intent(inout) :: self
    end subroutine after_step_interface
  end interface

contains

  !> Runs `config` and writes its HDF5 file. stat /= 0 only if the file could not be written
  !> or PETSc failed; a run that stops early is reported through summary%status.
  !> With `solver`, the caller's PETSc objects are reused (and left for the next run);
  !> without, the run creates and frees its own.
  subroutine run_simulation(config, summary, stat, message, observer, solver)
    type(run_configuration), intent(in) :: config
    type(run_summary), intent(out) :: summary
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    class(run_observer), intent(inout), optional :: observer
    type(snes_solver), intent(inout), target, optional :: solver
    type(pendulum) :: model
    type(step_problem) :: problem
    type(snes_solver), target :: own_solver
    type(snes_solver), pointer :: active
    type(ts_stepper), target :: ts
    class(stepper), pointer :: integrator
    type(step_report) :: report
    type(hdf5_file) :: file
    type(series_table) :: points, steps
    real(real64), allocatable :: x(:), x_previous(:), x_new(:)
    real(real64) :: z(state_size), boundary_heat
    real(real64) :: energy, entropy, lyapunov, energy_0, entropy_old, lyapunov_old, jz_0, theta(2), time
    integer(int64) :: clock_start, clock_loop, clock_now, clock_rate
    integer :: n, io_stat
    PetscErrorCode :: ierr

    call system_clock(clock_start, clock_rate)
    message = ''
    summary%status = 'incomplete: running'
    summary%steps_planned = step_count(config)
    model = make_pendulum(config%model, config%thermo_variable)
    call model%state_from_temperatures(config%q1, config%q2, config%p1, config%p2, config%gamma, config%theta, z, stat)
    if (stat /= 0) then
      message = config%input_file//': &initial: the initial state lies outside the model''s domain'
      return
    end if
    problem%model = model
    if (.not. is_ts_scheme(config%scheme)) problem%scheme = config%scheme
    problem%gradient = config%discrete_gradient
    problem%metric = config%metric
    problem%dt = config%dt
    problem%z_old = z
    problem%fix_length = config%fix_length
    problem%length = config%length
    problem%fix_temperature = config%fix_temperature
    problem%temperature = config%temperature
    ! The unknowns: the state and the multipliers of the active constraints (initial guess 0).
    allocate (x(problem%unknowns()), x_previous(problem%unknowns()), x_new(problem%unknowns()))
    x = 0.0_real64
    x(1:state_size) = z
    boundary_heat = 0.0_real64

    call open_output(stat, message)
    if (stat /= 0) return
    if (is_ts_scheme(config%scheme)) then
      call ts%create(model, config%scheme - size(scheme_names), z, config%dt, config%newton_tol, config%newton_max_iterations, &
                     config%ts_tolerance, ierr)
      integrator => ts
    else
      if (present(solver)) then
        active => solver
      else
        active => own_solver
      end if
      call active%prepare(problem, config%newton_tol, config%newton_max_iterations, ierr)
      integrator => active
    end if
    if (ierr /= 0) then
      stat = int(ierr)
      message = 'PETSc failed to set up the solver'
      if (.not. is_ts_scheme(config%scheme) .and. .not. present(solver) .and. own_solver%created) &
        call own_solver%destroy(ierr)
      call close_output('incomplete: PETSc failed to set up the solver')
      return
    end if

    call observe(z, energy, entropy, lyapunov, theta)
    energy_0 = energy
    jz_0 = angular_momentum_z(z)
    call record_point(0.0_real64, z, energy, entropy, lyapunov, theta)
    x_previous = x
    call system_clock(clock_loop)
    do n = 1, summary%steps_planned
      ! Predictor: linear extrapolation of the last step (the old state on the first step).
      call integrator%advance(x, (n - 1)*config%dt, config%dt, 2*x - x_previous, x_new, report, ierr)
      summary%newton_iterations = summary%newton_iterations + report%newton_iterations
      if (ierr /= 0) then
        stat = int(ierr)
        message = 'PETSc failed during the solve'
        summary%status = 'incomplete: PETSc error in step '//integer_text(n)
        exit
      end if
      time = n*config%dt
      if (.not. report%accepted) then
        summary%status = 'incomplete: step '//integer_text(n)//' (t = '//fixed_text(time, 4)//' s): '//report%reason
        exit
      end if
      call steps%append(file, [real(report%newton_iterations, real64), report%scheme_temperature, &
                               real(report%strategy, real64), &
                               real(report%solves, real64), real(report%rejected_roots, real64), &
                               x_new(state_size + 1:)], io_stat)
      if (io_stat /= 0) exit
      if (problem%fix_temperature) boundary_heat = boundary_heat + config%dt*x_new(problem%temperature_multiplier())
      entropy_old = entropy
      lyapunov_old = lyapunov
      x_previous = x
      x = x_new
      z = x(1:state_size)
      call observe(z, energy, entropy, lyapunov, theta)
      call record_point(time, z, energy, entropy, lyapunov, theta)
      if (io_stat /= 0) exit
      summary%steps_completed = n
      summary%energy_drift = max(summary%energy_drift, abs(energy - energy_0 - boundary_heat)/abs(energy_0))
      summary%min_entropy_increment = min(summary%min_entropy_increment, entropy - entropy_old)
      summary%max_lyapunov_increment = max(summary%max_lyapunov_increment, lyapunov - lyapunov_old)
      summary%angular_momentum_drift = max(summary%angular_momentum_drift, abs(angular_momentum_z(z) - jz_0))
      if (present(observer)) call observer%after_step()
    end do
    if (summary%steps_completed == 0) then
      summary%min_entropy_increment = ieee_value(1.0_real64, ieee_quiet_nan)
      summary%max_lyapunov_increment = ieee_value(1.0_real64, ieee_quiet_nan)
    end if
    if (io_stat /= 0) then
      stat = io_stat
      message = 'cannot write to '//config%output_file
      summary%status = 'incomplete: cannot write the output file'
    else if (summary%steps_completed == summary%steps_planned) then
      summary%status = 'complete'
    end if
    call system_clock(clock_now)
    summary%solve_seconds = real(clock_now - clock_loop, real64)/real(clock_rate, real64)
    ierr = 0
    if (is_ts_scheme(config%scheme)) then
      call ts%destroy(ierr)
    else if (.not. present(solver)) then
      call own_solver%destroy(ierr)
    end if
    if (ierr /= 0 .and. stat == 0) then
      stat = int(ierr)
      message = 'PETSc failed to free the solver'
    end if
    call close_output(summary%status)
    call system_clock(clock_now)
    summary%wall_seconds = real(clock_now - clock_start, real64)/real(clock_rate, real64)

  contains

    subroutine observe(z, energy, entropy, lyapunov, theta)
      real(real64), intent(in) :: z(state_size)
      real(real64), intent(out) :: energy, entropy, lyapunov, theta(2)
      integer :: domain

      call model%observe(z, energy, entropy, theta, domain)
      lyapunov = energy - config%theta_r*entropy
    end subroutine observe

    subroutine record_point(time, z, energy, entropy, lyapunov, theta)
      real(real64), intent(in) :: time, z(state_size), energy, entropy, lyapunov, theta(2)
      real(real64) :: residuals(2)
      integer :: k

      ! g1 = (q1.q1 - length^2)/2 and g2 = Theta_1 - temperature, for the active constraints.
      k = 0
      if (problem%fix_length) then
        k = k + 1
        residuals(k) = 0.5_real64*(dot_product(z(1:3), z(1:3)) - problem%length**2)
      end if
      if (problem%fix_temperature) then
        k = k + 1
        residuals(k) = theta(1) - problem%temperature
      end if
      call points%append(file, [time, z, theta, energy, entropy, lyapunov, angular_momentum(z), boundary_heat, &
                                residuals(1:k)], io_stat)
    end subroutine record_point

    subroutine open_output(stat, message)
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: message

      call make_parent_directories(config%output_file, stat)
      if (stat == 0) call file%create(config%output_file, stat, message)
      if (stat /= 0) then
        message = 'cannot create the output file '''//config%output_file//''' (&output: file)'
        return
      end if
      call write_run_attributes(file, config, summary%steps_planned, problem%unknowns(), stat)
      if (stat == 0) call define_datasets(file, points, steps, problem, config%scheme, stat)
      if (stat /= 0) message = 'cannot write to '//config%output_file
    end subroutine open_output

    subroutine close_output(status)
      character(len=*), intent(in) :: status
      integer :: close_stat

      call points%close(file, close_stat)
      call steps%close(file, close_stat)
      call file%set_text('status', status, close_stat)
      call file%set_integer('steps_completed', summary%steps_completed, close_stat)
      call file%set_real('solve_time_seconds', summary%solve_seconds, close_stat)
      call system_clock(clock_now)
      call file%set_real('wall_time_seconds', real(clock_now - clock_start, real64)/real(clock_rate, real64), close_stat)
      call file%close(close_stat)
    end subroutine close_output
  end subroutine run_simulation

  ! The datasets, in the order of the rows that feed them. h5py shows (rows) or (rows, columns).
  subroutine define_datasets(file, points, steps, problem, scheme, stat)
    type(hdf5_file), intent(in) :: file
    type(series_table), intent(inout) :: points, steps
    type(step_problem), intent(in) :: problem
    integer, intent(in) :: scheme    !! index into scheme_choices
    integer, intent(out) :: stat
    character(len=:), allocatable :: columns, temperature_meaning, multipliers, residuals
    integer :: i

    columns = trim(state_column_names(1))
    do i = 2, state_size
      columns = columns//' '//trim(state_column_names(i))
    end do
    if (scheme > size(scheme_choices) - 4) then
      temperature_meaning = 'temperatures at the end of the step (PETSc TS baselines have no discrete temperature)'
    else if (scheme == scheme_eme) then
      temperature_meaning = 'discrete temperatures D_tau U_a / D_tau S_a of the step, where K0 is evaluated'
    else
      temperature_meaning = 'temperatures at the step''s midpoint, where K0 is evaluated'
    end if
    stat = 0
    call points%define(file, 'time', 1, .false., 's', 'time t_n = n dt', stat)
    if (stat == 0) call points%define(file, 'state', state_size, .true., 'SI', &
      'z = (q1, q2, p1, p2, gamma, tau1, tau2) in the run''s thermodynamic variable', stat, columns=columns)
    if (stat == 0) call points%define(file, 'temperature', 2, .true., 'K', 'spring temperatures', stat, &
                                      columns='theta_1 theta_2')
    if (stat == 0) call points%define(file, 'energy', 1, .false., 'J', 'total energy E = T + V_g + U_1 + U_2', stat)
    if (stat == 0) call points%define(file, 'entropy', 1, .false., 'J/K', 'total entropy S = S_1 + S_2', stat)
    if (stat == 0) call points%define(file, 'lyapunov', 1, .false., 'J', 'V = E - theta_r S, eq. (14)', stat)
    if (stat == 0) call points%define(file, 'angular_momentum', 3, .true., 'J s', 'J = q1 x p1 + q2 x p2', stat, &
                                      columns='J_x J_y J_z')
    if (stat == 0) call points%define(file, 'boundary_heat', 1, .false., 'J', &
      'heat supplied through constraint g2 since t = 0, sum of dt lambda_2 (zero without it)', stat)
    ! Constraint data exist only when a constraint is active (FORMULATION section 7).
    multipliers = ''
    residuals = ''
    if (problem%fix_length) then
      multipliers = 'lambda_length'
      residuals = 'g_length'
    end if
    if (problem%fix_temperature) then
      multipliers = trim(multipliers//' lambda_temperature')
      residuals = trim(residuals//' g_temperature')
    end if
    if (problem%constraint_count() > 0) then
      if (stat == 0) call points%define(file, 'constraint_residual', problem%constraint_count(), .true., 'SI', &
        'g_length = (q1.q1 - length^2)/2 [m^2], g_temperature = Theta_1 - temperature [K], for the active '// &
        'constraints', stat, columns=adjustl(residuals))
    end if
    if (stat == 0) call steps%define(file, 'newton_iterations', 1, .false., '1', &
      'Newton iterations of the step, summed over every solve it took', stat, integer_valued=.true.)
    if (stat == 0) call steps%define(file, 'scheme_temperature', 2, .true., 'K', temperature_meaning, stat, &
                                     columns='Theta_1 Theta_2')
    if (stat == 0) call steps%define(file, 'solver_strategy', 1, .false., '1', &
      'what found the root: 1 predictor, 2 old state, 3 continuation in dt (same dt); 4-6 the same with the '// &
      'fallback line search; 0 for PETSc TS', stat, &
      integer_valued=.true.)
    if (stat == 0) call steps%define(file, 'snes_solves', 1, .false., '1', &
      'SNESSolve calls of the step (continuation stages included), or TS steps taken for PETSc TS', stat, &
      integer_valued=.true.)
    if (stat == 0) call steps%define(file, 'rejected_roots', 1, .false., '1', &
      'converged roots rejected as unphysical (non-positive temperature), or TS steps rejected', stat, &
      integer_valued=.true.)
    if (problem%constraint_count() > 0) then
      if (stat == 0) call steps%define(file, 'multiplier', problem%constraint_count(), .true., 'SI', &
        'Lagrange multipliers: lambda_length [N/m] (force -lambda q1_mid), lambda_temperature [W] (heat supply)', &
        stat, columns=adjustl(multipliers))
    end if
  end subroutine define_datasets

  ! Scheme, data and provenance as root attributes, under the namelists' names.
  subroutine write_run_attributes(file, config, steps_planned, unknowns, stat)
    type(hdf5_file), intent(in) :: file
    type(run_configuration), intent(in) :: config
    integer, intent(in) :: steps_planned, unknowns
    integer, intent(out) :: stat
    type(pendulum) :: model
    character(len=:), allocatable :: gradient, metric

    model = make_pendulum(config%model, config%thermo_variable)
    if (is_ts_scheme(config%scheme)) then
      gradient = 'none (PETSc TS)'
      metric = 'none (PETSc TS)'
    else if (config%scheme == scheme_eme) then
      gradient = trim(discrete_gradient_names(config%discrete_gradient))
      metric = trim(metric_names(config%metric))
      if (config%metric == metric_nondimensional) metric = metric// &
        ': C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref'
    else
      gradient = 'none (midpoint rule)'
      metric = 'none (midpoint rule)'
    end if
    stat = 0
    call text('status', 'incomplete: running')
    call text('scheme', trim(scheme_choices(config%scheme)))
    call text('thermo_variable', trim(thermo_variable_names(config%thermo_variable)))
    call text('discrete_gradient', gradient)
    call text('metric', metric)
    call text('input_file', config%input_file)
    call text('code_version', code_version)
    call real_attribute('dt', config%dt)
    call real_attribute('t_end', config%t_end)
    call real_attribute('theta_r', config%theta_r)
    call real_attribute('newton_tol', config%newton_tol)
    call real_attribute('ts_tolerance', config%ts_tolerance)
    if (stat == 0) call file%set_integer('newton_max_iterations', config%newton_max_iterations, stat)
    call real_attribute('quotient_threshold', quotient_threshold)
    if (stat == 0) call file%set_integer('steps_planned', steps_planned, stat)
    if (stat == 0) call file%set_integer('unknowns', unknowns, stat)
    if (stat == 0) call file%set_reals('metric_scale_spring1', model%spring(1)%metric_scale(), stat)
    if (stat == 0) call file%set_reals('metric_scale_spring2', model%spring(2)%metric_scale(), stat)
    associate (p => config%model)
      call reals('mass', p%mass)
      call reals('natural_length', p%natural_length)
      call reals('mu_eq_const', p%mu_eq_const)
      call reals('mu_eq_slope', p%mu_eq_slope)
      call real_attribute('mu_neq_const', p%mu_neq_const)
      call real_attribute('mu_neq_slope', p%mu_neq_slope)
      call reals('heat_capacity', p%heat_capacity)
      call real_attribute('viscosity_const', p%viscosity_const)
      call real_attribute('viscosity_activation', p%viscosity_activation)
      call real_attribute('conductivity', p%conductivity)
      call real_attribute('theta_ref', p%theta_ref)
      call real_attribute('beta', p%beta)
      call real_attribute('beta_v', p%beta_v)
      call reals('gravity', p%gravity)
    end associate
    if (config%fix_length .and. config%fix_temperature) then
      call text('constraints', 'length, temperature')
    else if (config%fix_length) then
      call text('constraints', 'length')
    else if (config%fix_temperature) then
      call text('constraints', 'temperature')
    else
      call text('constraints', 'none')
    end if
    if (stat == 0) call file%set_integer('fix_length', merge(1, 0, config%fix_length), stat)
    call real_attribute('length', config%length)
    if (stat == 0) call file%set_integer('fix_temperature', merge(1, 0, config%fix_temperature), stat)
    call real_attribute('temperature', config%temperature)
    call reals('q1', config%q1)
    call reals('q2', config%q2)
    call reals('p1', config%p1)
    call reals('p2', config%p2)
    call real_attribute('gamma', config%gamma)
    call reals('theta', config%theta)

  contains

    subroutine text(name, value)
      character(len=*), intent(in) :: name, value
      if (stat == 0) call file%set_text(name, value, stat)
    end subroutine text

    subroutine real_attribute(name, value)
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: value
      if (stat == 0) call file%set_real(name, value, stat)
    end subroutine real_attribute

    subroutine reals(name, values)
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: values(:)
      if (stat == 0) call file%set_reals(name, values, stat)
    end subroutine reals
  end subroutine write_run_attributes

  pure function angular_momentum_z(z) result(jz)
    real(real64), intent(in) :: z(state_size)
    real(real64) :: jz
    real(real64) :: j(3)

    j = angular_momentum(z)
    jz = j(3)
  end function angular_momentum_z

end module simulation
