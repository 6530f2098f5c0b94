!> The input of one run: the namelist groups &model, &initial, &constraints, &integrator and
!> &output. Absent groups and names keep their defaults, which are the paper's data (empty
!> groups reproduce the paper's Fig. 4 scene with EME_theta). Every value is validated here,
!> before anything is written; errors come back as stat /= 0 with a message that names the
!> file, the group, the field and what is allowed.
!> Overrides ('name = value' items, e.g. from an ensemble study) are applied after the file's
!> items of the group the name belongs to, and validated with them.
module run_config
  use, intrinsic :: iso_fortran_env, only: real64
  use thermo_variable, only: tau_temperature, thermo_variable_names
  use discrete_gradient, only: gradient_gonzalez, discrete_gradient_names, metric_nondimensional, metric_names
  use step_residual, only: scheme_eme, scheme_names
  use ts_integrator, only: ts_scheme_names
  use number_text, only: integer_text
  use model_parameters, only: pendulum_parameters
  use namelist_text, only: field_spec, namelist_item, read_source_text, group_names, group_items, item_name, &
                           item_failure, invalid_value_message, reals_text
  implicit none (type, external)
  private
  public :: run_configuration, read_run_config, step_count, scheme_choices, is_ts_scheme

  character(len=*), parameter :: input_groups(5) = [character(len=11) :: 'model', 'initial', 'constraints', &
                                                   'integrator', 'output']

  !> The values of &integrator scheme: the structure-preserving schemes, then the PETSc TS
  !> baselines (config%scheme indexes this list).
  character(len=*), parameter :: scheme_choices(6) = [character(len=11) :: scheme_names, ts_scheme_names]

  !> Everything a run needs, in the namelists' names and units.
  type :: run_configuration
    character(len=:), allocatable :: input_file
    type(pendulum_parameters) :: model
    real(real64) :: q1(3) = [1.0_real64, 0.0_real64, 0.0_real64]
    real(real64) :: q2(3) = [3.0_real64, 0.0_real64, 0.0_real64]
    real(real64) :: p1(3) = [0.0_real64, 0.0_real64, 0.0_real64]
    real(real64) :: p2(3) = [-1.0_real64, -1.0_real64, 0.0_real64]
    real(real64) :: gamma = 0.0_real64
    real(real64) :: theta(2) = [280.0_real64, 350.0_real64]
    logical :: fix_length = .false.
    real(real64) :: length = 1.0_real64
    logical :: fix_temperature = .false.
    real(real64) :: temperature = 280.0_real64
    integer :: scheme = scheme_eme
    integer :: thermo_variable = tau_temperature
    integer :: discrete_gradient = gradient_gonzalez
    integer :: metric = metric_nondimensional
    real(real64) :: dt = 0.15_real64
    real(real64) :: t_end = 20.0_real64
    real(real64) :: newton_tol = 1.0e-8_real64
    real(real64) :: ts_tolerance = 1.0e-10_real64
    integer :: newton_max_iterations = 50
    character(len=:), allocatable :: output_file
    real(real64) :: theta_r = 300.0_real64
  end type run_configuration

  type(field_spec), parameter :: model_fields(14) = [ &
    field_spec('mass', 'two real numbers > 0 [kg]'), &
    field_spec('natural_length', 'two real numbers > 0 [m]'), &
    field_spec('mu_eq_const', 'two real numbers [J]'), &
    field_spec('mu_eq_slope', 'two real numbers [J/K]'), &
    field_spec('mu_neq_const', 'a real number'), &
    field_spec('mu_neq_slope', 'a real number'), &
    field_spec('heat_capacity', 'two real numbers > 0 [J/K]'), &
    field_spec('viscosity_const', 'a real number > 0'), &
    field_spec('viscosity_activation', 'a real number [K]'), &
    field_spec('conductivity', 'a real number >= 0 [J/(K s)]'), &
    field_spec('theta_ref', 'a real number > 0 [K]'), &
    field_spec('beta', 'a real number [J/K]'), &
    field_spec('beta_v', 'a real number >= 0'), &
    field_spec('gravity', 'three real numbers [m/s^2]')]
  type(field_spec), parameter :: initial_fields(6) = [ &
    field_spec('q1', 'three real numbers, not all zero [m]'), &
    field_spec('q2', 'three real numbers, not all zero [m]'), &
    field_spec('p1', 'three real numbers [N s]'), &
    field_spec('p2', 'three real numbers [N s]'), &
    field_spec('gamma', 'a real number [m]'), &
    field_spec('theta', 'two real numbers > 0 [K]')]
  type(field_spec), parameter :: constraint_fields(4) = [ &
    field_spec('fix_length', '.true. or .false.'), &
    field_spec('length', 'a real number > 0 equal to |q1| at t = 0 [m]'), &
    field_spec('fix_temperature', '.true. or .false.'), &
    field_spec('temperature', 'a real number > 0 equal to theta(1) at t = 0 [K]')]
  type(field_spec), parameter :: integrator_fields(9) = [ &
    field_spec('scheme', "'eme', 'midpoint', 'ts_midpoint', 'ts_bdf2', 'ts_rk4' or 'ts_rk5dp'"), &
    field_spec('thermo_variable', "'entropy', 'temperature' or 'internal_energy'"), &
    field_spec('discrete_gradient', "'gonzalez' or 'partitioned'"), &
    field_spec('metric', "'nondimensional' or 'euclidean'"), &
    field_spec('dt', 'a real number > 0 [s]'), &
    field_spec('t_end', 'a real number > 0 [s]'), &
    field_spec('newton_tol', 'a real number > 0'), &
    field_spec('ts_tolerance', 'a real number > 0 (absolute and relative, for ts_rk5dp)'), &
    field_spec('newton_max_iterations', 'an integer >= 1 (Newton iterations per solve)')]
  type(field_spec), parameter :: output_fields(2) = [ &
    field_spec('file', 'a path ending in .h5 (default results/<input name>.h5)'), &
    field_spec('theta_r', 'a real number > 0 [K] (default theta_ref, or the fixed temperature)')]

  integer, parameter :: text_length = 256

contains

  !> Number of steps that cover [0, t_end]: the last time is the first n dt >= t_end
  !> (the paper's 20 s with dt = 0.15 s gives 134 steps ending at 20.1 s).
  pure function step_count(config) result(n)
    type(run_configuration), intent(in) :: config
    integer :: n

    n = ceiling(config%t_end/config%dt - 1.0e-9_real64)
  end function step_count

  !> Reads and validates `path` (then `overrides`, if any); on failure stat /= 0 and `message`
  !> says what and where.
  subroutine read_run_config(path, config, stat, message, overrides)
    character(len=*), intent(in) :: path
    type(run_configuration), intent(out) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(namelist_item), intent(in), optional :: overrides(:)
    type(namelist_item), allocatable :: extra(:)
    character(len=:), allocatable :: text, name
    character(len=32), allocatable :: groups(:)
    integer :: i

    config%input_file = path
    call read_source_text(path, text, stat, message)
    if (stat /= 0) return
    call group_names(text, groups)
    do i = 1, size(groups)
      if (.not. any(input_groups == groups(i))) then
        stat = 1
        message = path//': unknown namelist group &'//trim(groups(i))// &
                  '; allowed groups: &model, &initial, &constraints, &integrator, &output'
        return
      end if
    end do
    allocate (extra(0))
    if (present(overrides)) extra = overrides
    do i = 1, size(extra)
      name = item_name(extra(i)%item)
      if (.not. any([model_fields%name, initial_fields%name, constraint_fields%name, integrator_fields%name, &
                     output_fields%name] == name)) then
        stat = 1
        message = extra(i)%origin//': '''//name//''' is not a field of an eme_run namelist group'
        return
      end if
    end do
    call read_model(text, extra, config, stat, message)
    if (stat == 0) call read_initial(text, extra, config, stat, message)
    if (stat == 0) call read_constraints(text, extra, config, stat, message)
    if (stat == 0) call read_integrator(text, extra, config, stat, message)
    if (stat == 0) call read_output(text, extra, config, stat, message)
  end subroutine read_run_config

  ! ------------------------------------------------------------------ the groups
  ! Each group applies its items one namelist read at a time (file first, then overrides), so a
  ! failing item is known by name; then it validates the values.

  subroutine read_model(text, extra, config, stat, message)
    character(len=*), intent(in) :: text
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    real(real64) :: mass(2), natural_length(2), mu_eq_const(2), mu_eq_slope(2), mu_neq_const, mu_neq_slope
    real(real64) :: heat_capacity(2), viscosity_const, viscosity_activation, conductivity, theta_ref
    real(real64) :: beta, beta_v, gravity(3)
    type(namelist_item), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /model/ mass, natural_length, mu_eq_const, mu_eq_slope, mu_neq_const, mu_neq_slope, &
      heat_capacity, viscosity_const, viscosity_activation, conductivity, theta_ref, beta, beta_v, gravity

    associate (p => config%model)
      mass = p%mass; natural_length = p%natural_length; mu_eq_const = p%mu_eq_const
      mu_eq_slope = p%mu_eq_slope; mu_neq_const = p%mu_neq_const; mu_neq_slope = p%mu_neq_slope
      heat_capacity = p%heat_capacity; viscosity_const = p%viscosity_const
      viscosity_activation = p%viscosity_activation; conductivity = p%conductivity
      theta_ref = p%theta_ref; beta = p%beta; beta_v = p%beta_v; gravity = p%gravity
    end associate
    stat = 0
    message = ''
    call group_items(text, 'model', model_fields, config%input_file, items, extra)
    do i = 1, size(items)
      read (items(i)%record, nml=model, iostat=ios, iomsg=io_message)
      if (ios /= 0) then
        stat = 1
        message = item_failure(items(i), 'model', model_fields)
        return
      end if
    end do
    associate (p => config%model)
      p%mass = mass; p%natural_length = natural_length; p%mu_eq_const = mu_eq_const
      p%mu_eq_slope = mu_eq_slope; p%mu_neq_const = mu_neq_const; p%mu_neq_slope = mu_neq_slope
      p%heat_capacity = heat_capacity; p%viscosity_const = viscosity_const
      p%viscosity_activation = viscosity_activation; p%conductivity = conductivity
      p%theta_ref = theta_ref; p%beta = beta; p%beta_v = beta_v; p%gravity = gravity
    end associate
    config%theta_r = theta_ref
    call require(all(mass > 0), 'mass', reals_text(mass))
    call require(all(natural_length > 0), 'natural_length', reals_text(natural_length))
    call require(all(heat_capacity > 0), 'heat_capacity', reals_text(heat_capacity))
    call require(viscosity_const > 0, 'viscosity_const', reals_text([viscosity_const]))
    call require(conductivity >= 0, 'conductivity', reals_text([conductivity]))
    call require(theta_ref > 0, 'theta_ref', reals_text([theta_ref]))
    call require(beta_v >= 0, 'beta_v', reals_text([beta_v]))

  contains

    subroutine require(condition, field, value)
      logical, intent(in) :: condition
      character(len=*), intent(in) :: field, value
      if (stat /= 0 .or. condition) return
      stat = 1
      message = invalid_value_message(origin_of(items, field, config%input_file), 'model', field, value, model_fields)
    end subroutine require
  end subroutine read_model

  subroutine read_initial(text, extra, config, stat, message)
    character(len=*), intent(in) :: text
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    real(real64) :: q1(3), q2(3), p1(3), p2(3), gamma, theta(2)
    type(namelist_item), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /initial/ q1, q2, p1, p2, gamma, theta

    q1 = config%q1; q2 = config%q2; p1 = config%p1; p2 = config%p2
    gamma = config%gamma; theta = config%theta
    stat = 0
    message = ''
    call group_items(text, 'initial', initial_fields, config%input_file, items, extra)
    do i = 1, size(items)
      read (items(i)%record, nml=initial, iostat=ios, iomsg=io_message)
      if (ios /= 0) then
        stat = 1
        message = item_failure(items(i), 'initial', initial_fields)
        return
      end if
    end do
    config%q1 = q1; config%q2 = q2; config%p1 = p1; config%p2 = p2
    config%gamma = gamma; config%theta = theta
    call require(norm2(q1) > 0, 'q1', reals_text(q1))
    call require(norm2(q2) > 0, 'q2', reals_text(q2))
    call require(all(theta > 0), 'theta', reals_text(theta))

  contains

    subroutine require(condition, field, value)
      logical, intent(in) :: condition
      character(len=*), intent(in) :: field, value
      if (stat /= 0 .or. condition) return
      stat = 1
      message = invalid_value_message(origin_of(items, field, config%input_file), 'initial', field, value, &
                                      initial_fields)
    end subroutine require
  end subroutine read_initial

  subroutine read_constraints(text, extra, config, stat, message)
    character(len=*), intent(in) :: text
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    logical :: fix_length, fix_temperature
    real(real64) :: length, temperature
    type(namelist_item), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /constraints/ fix_length, length, fix_temperature, temperature

    ! Defaults make both constraints hold at t = 0 (FORMULATION section 7).
    fix_length = .false.
    fix_temperature = .false.
    length = norm2(config%q1)
    temperature = config%theta(1)
    stat = 0
    message = ''
    call group_items(text, 'constraints', constraint_fields, config%input_file, items, extra)
    do i = 1, size(items)
      read (items(i)%record, nml=constraints, iostat=ios, iomsg=io_message)
      if (ios /= 0) then
        stat = 1
        message = item_failure(items(i), 'constraints', constraint_fields)
        return
      end if
    end do
    config%fix_length = fix_length
    config%length = length
    config%fix_temperature = fix_temperature
    config%temperature = temperature
    ! A constraint must hold at t = 0, or the first step would jump onto it and do work.
    call require(length > 0 .and. abs(length - norm2(config%q1)) <= 1.0e-12_real64*length, &
                 'length', reals_text([length]))
    call require(temperature > 0 .and. abs(temperature - config%theta(1)) <= 1.0e-12_real64*temperature, &
                 'temperature', reals_text([temperature]))
    if (fix_temperature) config%theta_r = temperature

  contains

    subroutine require(condition, field, value)
      logical, intent(in) :: condition
      character(len=*), intent(in) :: field, value
      if (stat /= 0 .or. condition) return
      stat = 1
      message = invalid_value_message(origin_of(items, field, config%input_file), 'constraints', field, value, &
                                      constraint_fields)
    end subroutine require
  end subroutine read_constraints

  subroutine read_integrator(text, extra, config, stat, message)
    character(len=*), intent(in) :: text
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    character(len=text_length) :: scheme, thermo_variable, discrete_gradient, metric
    real(real64) :: dt, t_end, newton_tol, ts_tolerance
    integer :: newton_max_iterations
    type(namelist_item), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /integrator/ scheme, thermo_variable, discrete_gradient, metric, dt, t_end, newton_tol, ts_tolerance, &
      newton_max_iterations

    scheme = scheme_choices(config%scheme)
    thermo_variable = thermo_variable_names(config%thermo_variable)
    discrete_gradient = discrete_gradient_names(config%discrete_gradient)
    metric = metric_names(config%metric)
    dt = config%dt; t_end = config%t_end; newton_tol = config%newton_tol; ts_tolerance = config%ts_tolerance
    newton_max_iterations = config%newton_max_iterations
    stat = 0
    message = ''
    call group_items(text, 'integrator', integrator_fields, config%input_file, items, extra)
    do i = 1, size(items)
      read (items(i)%record, nml=integrator, iostat=ios, iomsg=io_message)
      if (ios /= 0) then
        stat = 1
        message = item_failure(items(i), 'integrator', integrator_fields)
        return
      end if
    end do
    config%scheme = choice(scheme, scheme_choices, 'scheme')
    config%thermo_variable = choice(thermo_variable, thermo_variable_names, 'thermo_variable')
    config%discrete_gradient = choice(discrete_gradient, discrete_gradient_names, 'discrete_gradient')
    config%metric = choice(metric, metric_names, 'metric')
    config%dt = dt; config%t_end = t_end; config%newton_tol = newton_tol; config%ts_tolerance = ts_tolerance
    config%newton_max_iterations = newton_max_iterations
    call require(dt > 0, 'dt', reals_text([dt]))
    call require(newton_max_iterations >= 1, 'newton_max_iterations', integer_text(newton_max_iterations))
    call require(ts_tolerance > 0, 'ts_tolerance', reals_text([ts_tolerance]))
    if (stat == 0 .and. is_ts_scheme(config%scheme) .and. (config%fix_length .or. config%fix_temperature)) then
      stat = 1
      message = origin_of(items, 'scheme', config%input_file)//': &integrator: scheme = '''//trim(scheme)// &
                ''' integrates the unconstrained model only; allowed with &constraints: ''eme'' or ''midpoint'''
    end if
    call require(t_end > 0, 't_end', reals_text([t_end]))
    call require(newton_tol > 0, 'newton_tol', reals_text([newton_tol]))

  contains

    integer function choice(value, names, field)
      character(len=*), intent(in) :: value, names(:), field
      integer :: i
      choice = 1
      do i = 1, size(names)
        if (trim(value) == trim(names(i))) then
          choice = i
          return
        end if
      end do
      call require(.false., field, "'"//trim(value)//"'")
    end function choice

    subroutine require(condition, field, value)
      logical, intent(in) :: condition
      character(len=*), intent(in) :: field, value
      if (stat /= 0 .or. condition) return
      stat = 1
      message = invalid_value_message(origin_of(items, field, config%input_file), 'integrator', field, value, &
                                      integrator_fields)
    end subroutine require
  end subroutine read_integrator

  subroutine read_output(text, extra, config, stat, message)
    character(len=*), intent(in) :: text
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    character(len=text_length) :: file
    real(real64) :: theta_r
    type(namelist_item), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /output/ file, theta_r

    file = default_output_file(config%input_file)
    theta_r = config%theta_r
    stat = 0
    message = ''
    call group_items(text, 'output', output_fields, config%input_file, items, extra)
    do i = 1, size(items)
      read (items(i)%record, nml=output, iostat=ios, iomsg=io_message)
      if (ios /= 0) then
        stat = 1
        message = item_failure(items(i), 'output', output_fields)
        return
      end if
    end do
    config%output_file = trim(file)
    config%theta_r = theta_r
    call require(len_trim(file) > 3 .and. index(file, '.h5', back=.true.) == len_trim(file) - 2, 'file', &
                 "'"//trim(file)//"'")
    call require(theta_r > 0, 'theta_r', reals_text([theta_r]))

  contains

    subroutine require(condition, field, value)
      logical, intent(in) :: condition
      character(len=*), intent(in) :: field, value
      if (stat /= 0 .or. condition) return
      stat = 1
      message = invalid_value_message(origin_of(items, field, config%input_file), 'output', field, value, &
                                      output_fields)
    end subroutine require
  end subroutine read_output

  ! ------------------------------------------------------------------ helpers

  !> Whether scheme (an index into scheme_choices) is a PETSc TS baseline.
  pure logical function is_ts_scheme(scheme)
    integer, intent(in) :: scheme

    is_ts_scheme = scheme > size(scheme_names)
  end function is_ts_scheme

  ! Where the last value of `field` came from: an override's origin, or the input file.
  pure function origin_of(items, field, input_file) result(origin)
    type(namelist_item), intent(in) :: items(:)
    character(len=*), intent(in) :: field, input_file
    character(len=:), allocatable :: origin
    integer :: i

    origin = input_file
    do i = 1, size(items)
      if (item_name(items(i)%item) == field) origin = items(i)%origin
    end do
  end function origin_of

  pure function default_output_file(input_file) result(file)
    character(len=*), intent(in) :: input_file
    character(len=:), allocatable :: file
    integer :: slash, dot

    slash = index(input_file, '/', back=.true.)
    dot = index(input_file, '.', back=.true.)
    if (dot <= slash) dot = len(input_file) + 1
    file = 'results/'//input_file(slash + 1:dot - 1)//'.h5'
  end function default_output_file

end module run_config
