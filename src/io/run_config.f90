!> The input of one run: the namelist groups &model, &initial, &constraints, &integrator and &output.
!> Absent groups and names keep their defaults, which are the paper's data (empty groups
!> reproduce the paper's Fig. 4 scene with EME_theta). Every value is validated here, before
!> anything is written; errors come back as stat /= 0 with a message that names the file, the
!> group, the field and what is allowed.
module run_config
  use, intrinsic :: iso_fortran_env, only: real64, iostat_end
  use model_parameters, only: pendulum_parameters
  use thermo_variable, only: tau_temperature, thermo_variable_names
  use discrete_gradient, only: gradient_gonzalez, discrete_gradient_names, metric_nondimensional, metric_names
  use step_residual, only: scheme_eme, scheme_names
  implicit none (type, external)
  private
  public :: run_configuration, read_run_config, step_count, input_groups

  character(len=*), parameter :: input_groups(5) = [character(len=11) :: 'model', 'initial', 'constraints', &
                                                   'integrator', 'output']

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
    integer :: scheme = scheme_eme
    integer :: thermo_variable = tau_temperature
    integer :: discrete_gradient = gradient_gonzalez
    integer :: metric = metric_nondimensional
    real(real64) :: dt = 0.15_real64
    real(real64) :: t_end = 20.0_real64
    real(real64) :: newton_tol = 1.0e-8_real64
    logical :: fix_length = .false.
    real(real64) :: length = 1.0_real64
    logical :: fix_temperature = .false.
    real(real64) :: temperature = 280.0_real64
    character(len=:), allocatable :: output_file
    real(real64) :: theta_r = 300.0_real64
  end type run_configuration

  !> What a field accepts, for error messages.
  type :: field_spec
    character(len=24) :: name
    character(len=80) :: allowed
  end type field_spec

  !> One item of a group as written, and as a one-item namelist record.
  type :: item_text
    character(len=:), allocatable :: item
    character(len=:), allocatable :: text
  end type item_text

  integer, parameter :: text_length = 256

contains

  !> Number of steps that cover [0, t_end]: the last time is the first n dt >= t_end
  !> (the paper's 20 s with dt = 0.15 s gives 134 steps ending at 20.1 s).
  pure function step_count(config) result(n)
    type(run_configuration), intent(in) :: config
    integer :: n

    n = ceiling(config%t_end/config%dt - 1.0e-9_real64)
  end function step_count

  !> Reads and validates `path`; on failure stat /= 0 and `message` says what and where.
  subroutine read_run_config(path, config, stat, message)
    character(len=*), intent(in) :: path
    type(run_configuration), intent(out) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    integer :: unit
    character(len=text_length) :: io_message

    config%input_file = path
    message = ''
    open (newunit=unit, file=path, status='old', action='read', iostat=stat, iomsg=io_message)
    if (stat /= 0) then
      message = path//': cannot read the input file: '//trim(io_message)
      return
    end if
    call check_group_names(unit, path, stat, message)
    if (stat == 0) call read_model(unit, config, stat, message)
    if (stat == 0) call read_initial(unit, config, stat, message)
    if (stat == 0) call read_constraints(unit, config, stat, message)
    if (stat == 0) call read_integrator(unit, config, stat, message)
    if (stat == 0) call read_output(unit, config, stat, message)
    close (unit)
  end subroutine read_run_config

  ! ------------------------------------------------------------------ the groups

  subroutine read_model(unit, config, stat, message)
    integer, intent(in) :: unit
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    real(real64) :: mass(2), natural_length(2), mu_eq_const(2), mu_eq_slope(2), mu_neq_const, mu_neq_slope
    real(real64) :: heat_capacity(2), viscosity_const, viscosity_activation, conductivity, theta_ref
    real(real64) :: beta, beta_v, gravity(3)
    type(item_text), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /model/ mass, natural_length, mu_eq_const, mu_eq_slope, mu_neq_const, mu_neq_slope, &
      heat_capacity, viscosity_const, viscosity_activation, conductivity, theta_ref, beta, beta_v, gravity
    type(field_spec), parameter :: fields(14) = [ &
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

    associate (p => config%model)
      mass = p%mass; natural_length = p%natural_length; mu_eq_const = p%mu_eq_const
      mu_eq_slope = p%mu_eq_slope; mu_neq_const = p%mu_neq_const; mu_neq_slope = p%mu_neq_slope
      heat_capacity = p%heat_capacity; viscosity_const = p%viscosity_const
      viscosity_activation = p%viscosity_activation; conductivity = p%conductivity
      theta_ref = p%theta_ref; beta = p%beta; beta_v = p%beta_v; gravity = p%gravity
    end associate
    stat = 0
    message = ''
    rewind (unit)
    read (unit, nml=model, iostat=ios, iomsg=io_message)
    if (ios /= 0 .and. ios /= iostat_end) then
      ! Read the group's items one at a time to find the one gfortran rejected.
      call group_items(unit, 'model', items)
      do i = 1, size(items)
        read (items(i)%text, nml=model, iostat=ios, iomsg=io_message)
        if (ios /= 0) exit
      end do
      call explain_failure(config%input_file, 'model', fields, items, i, io_message, stat, message)
      return
    end if
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
      call invalid_value(config%input_file, 'model', field, value, fields, stat, message)
    end subroutine require
  end subroutine read_model

  subroutine read_initial(unit, config, stat, message)
    integer, intent(in) :: unit
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    real(real64) :: q1(3), q2(3), p1(3), p2(3), gamma, theta(2)
    type(item_text), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /initial/ q1, q2, p1, p2, gamma, theta
    type(field_spec), parameter :: fields(6) = [ &
      field_spec('q1', 'three real numbers, not all zero [m]'), &
      field_spec('q2', 'three real numbers, not all zero [m]'), &
      field_spec('p1', 'three real numbers [N s]'), &
      field_spec('p2', 'three real numbers [N s]'), &
      field_spec('gamma', 'a real number [m]'), &
      field_spec('theta', 'two real numbers > 0 [K]')]

    q1 = config%q1; q2 = config%q2; p1 = config%p1; p2 = config%p2
    gamma = config%gamma; theta = config%theta
    stat = 0
    message = ''
    rewind (unit)
    read (unit, nml=initial, iostat=ios, iomsg=io_message)
    if (ios /= 0 .and. ios /= iostat_end) then
      ! Read the group's items one at a time to find the one gfortran rejected.
      call group_items(unit, 'initial', items)
      do i = 1, size(items)
        read (items(i)%text, nml=initial, iostat=ios, iomsg=io_message)
        if (ios /= 0) exit
      end do
      call explain_failure(config%input_file, 'initial', fields, items, i, io_message, stat, message)
      return
    end if
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
      call invalid_value(config%input_file, 'initial', field, value, fields, stat, message)
    end subroutine require
  end subroutine read_initial

  subroutine read_constraints(unit, config, stat, message)
    integer, intent(in) :: unit
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    logical :: fix_length, fix_temperature
    real(real64) :: length, temperature
    type(item_text), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /constraints/ fix_length, length, fix_temperature, temperature
    type(field_spec), parameter :: fields(4) = [ &
      field_spec('fix_length', '.true. or .false.'), &
      field_spec('length', 'a real number > 0 equal to |q1| at t = 0 [m]'), &
      field_spec('fix_temperature', '.true. or .false.'), &
      field_spec('temperature', 'a real number > 0 equal to theta(1) at t = 0 [K]')]

    ! Defaults make both constraints hold at t = 0 (FORMULATION section 7).
    fix_length = .false.
    fix_temperature = .false.
    length = norm2(config%q1)
    temperature = config%theta(1)
    stat = 0
    message = ''
    rewind (unit)
    read (unit, nml=constraints, iostat=ios, iomsg=io_message)
    if (ios /= 0 .and. ios /= iostat_end) then
      ! Read the group's items one at a time to find the one gfortran rejected.
      call group_items(unit, 'constraints', items)
      do i = 1, size(items)
        read (items(i)%text, nml=constraints, iostat=ios, iomsg=io_message)
        if (ios /= 0) exit
      end do
      call explain_failure(config%input_file, 'constraints', fields, items, i, io_message, stat, message)
      return
    end if
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
      call invalid_value(config%input_file, 'constraints', field, value, fields, stat, message)
    end subroutine require
  end subroutine read_constraints

  subroutine read_integrator(unit, config, stat, message)
    integer, intent(in) :: unit
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    character(len=text_length) :: scheme, thermo_variable, discrete_gradient, metric
    real(real64) :: dt, t_end, newton_tol
    type(item_text), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /integrator/ scheme, thermo_variable, discrete_gradient, metric, dt, t_end, newton_tol
    type(field_spec), parameter :: fields(7) = [ &
      field_spec('scheme', "'eme' or 'midpoint'"), &
      field_spec('thermo_variable', "'entropy', 'temperature' or 'internal_energy'"), &
      field_spec('discrete_gradient', "'gonzalez' or 'partitioned'"), &
      field_spec('metric', "'nondimensional' or 'euclidean'"), &
      field_spec('dt', 'a real number > 0 [s]'), &
      field_spec('t_end', 'a real number > 0 [s]'), &
      field_spec('newton_tol', 'a real number > 0')]

    scheme = scheme_names(config%scheme)
    thermo_variable = thermo_variable_names(config%thermo_variable)
    discrete_gradient = discrete_gradient_names(config%discrete_gradient)
    metric = metric_names(config%metric)
    dt = config%dt; t_end = config%t_end; newton_tol = config%newton_tol
    stat = 0
    message = ''
    rewind (unit)
    read (unit, nml=integrator, iostat=ios, iomsg=io_message)
    if (ios /= 0 .and. ios /= iostat_end) then
      ! Read the group's items one at a time to find the one gfortran rejected.
      call group_items(unit, 'integrator', items)
      do i = 1, size(items)
        read (items(i)%text, nml=integrator, iostat=ios, iomsg=io_message)
        if (ios /= 0) exit
      end do
      call explain_failure(config%input_file, 'integrator', fields, items, i, io_message, stat, message)
      return
    end if
    config%scheme = choice(scheme, scheme_names, 'scheme')
    config%thermo_variable = choice(thermo_variable, thermo_variable_names, 'thermo_variable')
    config%discrete_gradient = choice(discrete_gradient, discrete_gradient_names, 'discrete_gradient')
    config%metric = choice(metric, metric_names, 'metric')
    config%dt = dt; config%t_end = t_end; config%newton_tol = newton_tol
    call require(dt > 0, 'dt', reals_text([dt]))
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
      call invalid_value(config%input_file, 'integrator', field, value, fields, stat, message)
    end subroutine require
  end subroutine read_integrator

  subroutine read_output(unit, config, stat, message)
    integer, intent(in) :: unit
    type(run_configuration), intent(inout) :: config
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    character(len=text_length) :: file
    real(real64) :: theta_r
    type(item_text), allocatable :: items(:)
    character(len=text_length) :: io_message
    integer :: ios, i
    namelist /output/ file, theta_r
    type(field_spec), parameter :: fields(2) = [ &
      field_spec('file', 'a path ending in .h5 (default results/<input name>.h5)'), &
      field_spec('theta_r', 'a real number > 0 [K] (default theta_ref, or the fixed temperature)')]

    file = default_output_file(config%input_file)
    theta_r = config%theta_r
    stat = 0
    message = ''
    rewind (unit)
    read (unit, nml=output, iostat=ios, iomsg=io_message)
    if (ios /= 0 .and. ios /= iostat_end) then
      ! Read the group's items one at a time to find the one gfortran rejected.
      call group_items(unit, 'output', items)
      do i = 1, size(items)
        read (items(i)%text, nml=output, iostat=ios, iomsg=io_message)
        if (ios /= 0) exit
      end do
      call explain_failure(config%input_file, 'output', fields, items, i, io_message, stat, message)
      return
    end if
    config%output_file = trim(file)
    config%theta_r = theta_r
    call require(len_trim(file) > 3 .and. index(file, '.h5', back=.true.) == len_trim(file) - 2, 'file', "'"//trim(file)//"'")
    call require(theta_r > 0, 'theta_r', reals_text([theta_r]))

  contains


    subroutine require(condition, field, value)
      logical, intent(in) :: condition
      character(len=*), intent(in) :: field, value
      if (stat /= 0 .or. condition) return
      call invalid_value(config%input_file, 'output', field, value, fields, stat, message)
    end subroutine require
  end subroutine read_output

  ! ------------------------------------------------------------------ reading and diagnosis

  ! The group's `name = value` items, each wrapped as a one-item namelist record.
  subroutine group_items(unit, group, items)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: group
    type(item_text), allocatable, intent(out) :: items(:)
    character(len=:), allocatable :: body
    integer :: start, finish, next

    allocate (items(0))
    call group_text(unit, group, body)
    start = 1
    do while (start <= len(body))
      call next_item(body, start, finish, next)
      if (finish < start) exit
      items = [items, item_text(body(start:finish), '&'//group//' '//body(start:finish)//' /')]
      start = next
    end do
  end subroutine group_items

  ! The message for a group that failed to read: item `failed` is the first that fails alone
  ! (an unknown name, or a value of the wrong kind); if none does, gfortran's own message.
  subroutine explain_failure(path, group, fields, items, failed, io_message, stat, message)
    character(len=*), intent(in) :: path, group, io_message
    type(field_spec), intent(in) :: fields(:)
    type(item_text), intent(in) :: items(:)
    integer, intent(in) :: failed
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    character(len=:), allocatable :: name, item, value

    stat = 1
    if (failed > size(items)) then
      message = path//': &'//group//': '//trim(io_message)
      return
    end if
    item = items(failed)%item
    name = item_name(item)
    if (.not. any(fields%name == name)) then
      message = path//': &'//group//': unknown field '''//name//'''; allowed: '//names_list(fields)
    else
      value = trim(adjustl(item(index(item, '=') + 1:)))
      if (verify(value(1:1), '''"') /= 0) value = ''''//value//''''
      message = path//': &'//group//': field '''//name//''' cannot take the value '//value// &
                '; allowed: '//trim(allowed_of(fields, name))
    end if
  end subroutine explain_failure

  subroutine invalid_value(path, group, field, value, fields, stat, message)
    character(len=*), intent(in) :: path, group, field, value
    type(field_spec), intent(in) :: fields(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(inout) :: message

    stat = 1
    message = path//': &'//group//': '//field//' = '//trim(value)//' is not allowed; allowed: ' &
              //trim(allowed_of(fields, field))
  end subroutine invalid_value

  ! Every group name in the file must be a known one; Fortran would silently skip the others.
  subroutine check_group_names(unit, path, stat, message)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: path
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(inout) :: message
    character(len=text_length) :: line
    character(len=:), allocatable :: name
    integer :: ios, first, last

    stat = 0
    rewind (unit)
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      line = adjustl(line)
      if (line(1:1) /= '&') cycle
      first = 2
      last = verify(line(first:)//' ', 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_') + first - 2
      name = lowercase(line(first:last))
      if (.not. any(input_groups == name)) then
        stat = 1
        message = path//': unknown namelist group &'//name// &
                  '; allowed groups: &model, &initial, &constraints, &integrator, &output'
        return
      end if
    end do
  end subroutine check_group_names

  ! The text between '&group' and the closing '/', with comments removed and lines joined.
  subroutine group_text(unit, group, body)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: group
    character(len=:), allocatable, intent(out) :: body
    character(len=text_length) :: line
    integer :: ios, i
    logical :: inside, quoted
    character :: quote

    body = ''
    inside = .false.
    rewind (unit)
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) return
      if (.not. inside) then
        line = adjustl(line)
        if (lowercase(line(1:len(group) + 1)) /= '&'//group) cycle
        if (verify(line(len(group) + 2:len(group) + 2), ' ') /= 0) cycle
        inside = .true.
        line = line(len(group) + 2:)
      end if
      quoted = .false.
      quote = ' '
      do i = 1, len_trim(line)
        if (quoted) then
          if (line(i:i) == quote) quoted = .false.
        else if (line(i:i) == '''' .or. line(i:i) == '"') then
          quoted = .true.
          quote = line(i:i)
        else if (line(i:i) == '!') then
          line(i:) = ''
          exit
        else if (line(i:i) == '/') then
          body = body//' '//line(1:i - 1)
          return
        end if
      end do
      body = body//' '//trim(line)
    end do
  end subroutine group_text

  ! The next item 'name[(...)] = values' of a group body starting at `start`: it ends where the
  ! next 'name =' begins (outside quotes). Returns finish < start when no item is left.
  subroutine next_item(body, start, finish, next)
    character(len=*), intent(in) :: body
    integer, intent(inout) :: start
    integer, intent(out) :: finish, next
    integer :: i, equals
    logical :: quoted
    character :: quote

    do while (start <= len(body))
      if (index(' ,', body(start:start)) == 0) exit
      start = start + 1
    end do
    finish = start - 1
    next = len(body) + 1
    if (start > len(body)) return
    equals = index(body(start:), '=')
    if (equals == 0) then
      finish = len_trim(body)
      return
    end if
    equals = start + equals - 1
    quoted = .false.
    quote = ' '
    do i = equals + 1, len(body)
      if (quoted) then
        if (body(i:i) == quote) quoted = .false.
        cycle
      end if
      if (body(i:i) == '''' .or. body(i:i) == '"') then
        quoted = .true.
        quote = body(i:i)
      else if (body(i:i) == '=') then
        ! back up over the name (and any subscript) in front of this '='
        next = i - 1
        do while (next > equals .and. body(next:next) == ' ')
          next = next - 1
        end do
        if (body(next:next) == ')') next = index(body(1:next), '(', back=.true.) - 1
        do while (next > equals .and. index(' ,', body(next:next)) == 0)
          next = next - 1
        end do
        finish = next
        next = next + 1
        return
      end if
    end do
    finish = len_trim(body)
  end subroutine next_item

  pure function item_name(item) result(name)
    character(len=*), intent(in) :: item
    character(len=:), allocatable :: name
    integer :: stop_at

    stop_at = scan(item, '=(')
    if (stop_at == 0) stop_at = len(item) + 1
    name = lowercase(trim(adjustl(item(1:stop_at - 1))))
  end function item_name

  pure function names_list(fields) result(list)
    type(field_spec), intent(in) :: fields(:)
    character(len=:), allocatable :: list
    integer :: i

    list = trim(fields(1)%name)
    do i = 2, size(fields)
      list = list//', '//trim(fields(i)%name)
    end do
  end function names_list

  pure function allowed_of(fields, name) result(allowed)
    type(field_spec), intent(in) :: fields(:)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: allowed
    integer :: i

    allowed = ''
    do i = 1, size(fields)
      if (fields(i)%name == name) allowed = trim(fields(i)%allowed)
    end do
  end function allowed_of

  pure function default_output_file(input_file) result(file)
    character(len=*), intent(in) :: input_file
    character(len=:), allocatable :: file
    integer :: slash, dot

    slash = index(input_file, '/', back=.true.)
    dot = index(input_file, '.', back=.true.)
    if (dot <= slash) dot = len(input_file) + 1
    file = 'results/'//input_file(slash + 1:dot - 1)//'.h5'
  end function default_output_file

  ! Values as a user would write them: 6 significant digits, trailing zeros dropped.
  pure function reals_text(values) result(text)
    real(real64), intent(in) :: values(:)
    character(len=:), allocatable :: text
    character(len=32) :: one
    integer :: i, exponent_at, last

    text = ''
    do i = 1, size(values)
      write (one, '(g0.6)') values(i)
      exponent_at = scan(one, 'Ee')
      if (exponent_at == 0) exponent_at = len_trim(one) + 1
      last = exponent_at - 1
      do while (last > 1 .and. one(last:last) == '0' .and. one(last - 1:last - 1) /= '.')
        last = last - 1
      end do
      if (i > 1) text = text//', '
      text = text//one(1:last)//trim(one(exponent_at:))
    end do
  end function reals_text

  pure function lowercase(text) result(lower)
    character(len=*), intent(in) :: text
    character(len=len(text)) :: lower
    integer :: i, code

    lower = text
    do i = 1, len(text)
      code = iachar(text(i:i))
      if (code >= iachar('A') .and. code <= iachar('Z')) lower(i:i) = achar(code + 32)
    end do
  end function lowercase

end module run_config
