!> The input of one run: the model's groups (its scene, src/model/model_registry; for the double
!> pendulum &model, &initial, &constraints), then &integrator and &output. Absent groups and names
!> keep their defaults, which are the paper's data (empty groups reproduce the paper's Fig. 4
!> scene with EME_theta). Every value is validated here, before anything is written; errors come
!> back as stat /= 0 with a message that names the file, the group, the field and what is allowed.
!> Overrides ('name = value' items, e.g. from an ensemble study) are applied after the file's
!> items of the group the name belongs to, and validated with them.
module run_config
  use, intrinsic :: iso_fortran_env, only: real64
  use thermo_variable_kinds, only: thermo_variable_names
  use discrete_gradient, only: discrete_gradient_names, metric_names
  use integrator_settings, only: integrator_choice, step_count, default_step_budget
  use integrator_registry, only: integrator_entry, find_integrator, integrator_names
  use model_scene, only: scene
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use constrained_flow, only: initial_inconsistency
  use model_registry, only: select_scene
  use hdf5_array_reader, only: hdf5_arrays
  use failures, only: failure_type, fail, failure_input
  use namelist_text, only: namelist_item, read_source_text, group_names, group_items, item_name, joined
  use number_text, only: integer_text, reals_text
  use namelist_field, only: group_field, real_field, integer_field, text_field, logical_field, field_names, &
                            invalid_value_message, choices_text, absolute_temperature
  use namelist_group, only: read_group, value_origin, celsius_suspects, given_origin
  implicit none (type, external)
  private
  public :: run_configuration, read_run_config, integrator_fields, output_fields, run_groups, same_variable, field_length
  public :: field_units

  !> The run-level groups, read after the model's.
  character(len=*), parameter :: run_groups(2) = [character(len=16) :: 'integrator', 'output']
  !> The loosest Newton tolerance: at newton_tol = 100 the paper scene's Newton accepts its
  !> predictor on every step and nothing moves; at 1 its energy error is 4e-4.
  real(real64), parameter :: max_newton_tol = 1.0e-2_real64
  integer, parameter :: max_compression = 9     !! gzip's highest level

  !> Everything a run needs.
  type :: run_configuration
    character(len=:), allocatable :: input_file
    class(scene), allocatable :: scene           !! the model's groups
    type(integrator_choice) :: integrator
    character(len=:), allocatable :: output_file
    real(real64) :: theta_r = 300.0_real64       !! the Lyapunov reference temperature [K]
    logical :: overwrite = .false.               !! replace an existing complete output file
    integer :: output_every = 1                  !! a file row per this many steps (&output every)
    !> A file row at every multiple of this time [s], 0 for none (&output interval): for the
    !> integrators that choose their times, whose steps then land on those times.
    real(real64) :: output_interval = 0.0_real64
    logical :: chooses_times = .false.           !! the integrator chooses its times (registry, or a tolerance)
    integer :: compression = 0                   !! deflate level of the datasets, 0 (none) to 9
    !> A split run's snapshot of the state every this many steps, 0 for the first and last only
    !> (&output snapshot_every; src/run/distributed_simulation)
    integer :: snapshot_every = 0
    ! The texts of the &integrator and &output fields, as read.
    character(len=16) :: thermo_variable = 'temperature'
    character(len=16) :: discrete_gradient = 'gonzalez'
    character(len=16) :: metric = 'nondimensional'
    character(len=4096) :: file = ''                 !! PATH_MAX
    !> Settings the input gave that the chosen integrator does not read (the drivers warn).
    character(len=400), allocatable :: warnings(:)
  end type run_configuration

contains

  !> Reads and validates `path` (then `overrides`, if any); a failure (failure_input, or
  !> failure_io for an unreadable file) whose message says what and where.
  subroutine read_run_config(path, config, failure, overrides)
    character(len=*), intent(in) :: path
    type(run_configuration), intent(out), target :: config
    type(failure_type), intent(out) :: failure
    type(namelist_item), intent(in), optional :: overrides(:)
    type(namelist_item), allocatable :: extra(:)
    type(group_field), allocatable :: outputs(:)
    type(integrator_entry) :: entry
    character(len=:), allocatable :: text
    character(len=32), allocatable :: groups(:)
    character(len=16), allocatable :: allowed_groups(:)
    logical :: found
    integer :: i

    config%input_file = path
    call read_source_text(path, text, failure)
    if (failure%failed()) return
    allocate (extra(0))
    if (present(overrides)) extra = overrides
    call select_scene(text, path, extra, config%scene, failure)
    if (failure%failed()) return
    call config%scene%group_names(allowed_groups)
    allowed_groups = [character(len=16) :: allowed_groups, run_groups]
    call group_names(text, groups)
    if (size(groups) == 0) then
      call fail(failure, failure_input, path &
          //': no namelist group found (an empty file, only comments, or not a namelist); allowed groups: ' &
                //'&'//joined(allowed_groups, ', &')//', each written &name field = value, ... /')
      return
    end if
    do i = 1, size(groups)
      if (.not. any(allowed_groups == groups(i))) then
        call fail(failure, failure_input, path//': unknown namelist group &'//trim(groups(i))//'; allowed groups: &' &
            //joined(allowed_groups, ', &'))
        return
      else if (count(groups == groups(i)) > 1) then
        call fail(failure, failure_input, path//': &'//trim(groups(i))//' appears '//integer_text(count(groups == groups(i)))// &
                  ' times; allowed: each group once (put all its fields in one group)')
        return
      end if
    end do
    do i = 1, size(extra)
      if (is_field(config, allowed_groups, item_name(extra(i)%item))) cycle
      call fail(failure, failure_input, extra(i)%origin//': '''//item_name(extra(i)%item) &
          //''' is not a field of an eme_run namelist group')
      return
    end do

    ! The files the input names (a chain's &initial file), relative to its folder.
    allocate (config%scene%arrays, source=hdf5_arrays(path(1:index(path, '/', back=.true.))))
    call config%scene%read(text, path, extra, failure)
    if (failure%failed()) return
    call read_group(text, 'integrator', integrator_fields(config), path, failure, extra)
    if (failure%failed()) return
    associate (choice => config%integrator)
      choice%thermo_variable = findloc(thermo_variable_names, config%thermo_variable, dim=1)
      choice%discrete_gradient = findloc(discrete_gradient_names, config%discrete_gradient, dim=1)
      choice%metric = findloc(metric_names, config%metric, dim=1)
      call find_integrator(choice%scheme, entry, found)
      if (.not. entry%thermo_variables(choice%thermo_variable)) then
        call fail(failure, failure_input, value_origin(text, 'integrator', 'thermo_variable', path, extra) &
            //': &integrator: scheme = '''// &
                  trim(choice%scheme)//''' does not take thermo_variable = '''//trim(config%thermo_variable)//'''')
        return
      end if
      if (.not. entry%takes_constraints .and. config%scene%constraint_count() > 0) then
        call fail(failure, failure_input, value_origin(text, 'integrator', 'scheme', path, extra)//': &integrator: scheme = '''// &
                  trim(choice%scheme)//''' integrates the unconstrained model only; allowed with &constraints: ' &
                  //choices_text(integrator_names(.true.)))
        return
      end if
      call note_unused_settings(text, path, extra, entry, config)
      config%chooses_times = entry%chooses_time .or. (entry%error_control .and. choice%tolerance_given)
      call check_step_plan(text, path, extra, config, failure)
      if (failure%failed()) return
      if (entry%continuous_constraints .and. config%scene%constraint_count() > 0) then
        call check_continuous_start(config, entry, failure)
      else if (entry%error_control .and. choice%tolerance_given .and. config%scene%constraint_count() > 0) then
        call check_controllable_constraints(config, entry, failure)
      end if
      if (failure%failed()) then
        failure%message = value_origin(text, 'integrator', 'scheme', path, extra)//': '//failure%message
        return
      end if
    end associate

    config%theta_r = config%scene%default_theta_r()
    config%file = default_output_file(path)
    call read_group(text, 'output', output_fields(config), path, failure, extra)
    if (failure%failed()) return
    config%output_file = trim(config%file)
    outputs = output_fields(config)
    if (.not. (len_trim(config%file) > 3 .and. index(config%file, '.h5', back=.true.) == len_trim(config%file) - 2)) then
      call fail(failure, failure_input, invalid_value_message(value_origin(text, 'output', 'file', path, extra), 'output', &
          outputs(1)))
    else if (config%compression > max_compression) then
      call fail(failure, failure_input, invalid_value_message(value_origin(text, 'output', 'compression', path, extra), 'output', &
                                      outputs(findloc(outputs%name, 'compression', dim=1))))
    else if (config%output_interval > 0.0_real64 .and. .not. config%chooses_times) then
      call fail(failure, failure_input, value_origin(text, 'output', 'interval', path, extra)//': &output: interval = '// &
                reals_text([config%output_interval])//' needs an integrator that chooses its steps (a relaxed '// &
                'scheme, or eme or midpoint with a tolerance); scheme = '''//trim(config%integrator%scheme)// &
                ''' writes on the grid of dt: set dt to the output interval, or use every')
    else if (config%output_interval > 0.0_real64 .and. config%output_every > 1) then
      call fail(failure, failure_input, value_origin(text, 'output', 'interval', path, extra) &
          //': &output: interval and every both '// &
                'choose the rows written; allowed: one of them')
    end if
    if (failure%failed()) return
    call refuse_thermal_settings(text, path, extra, config, failure)
    if (failure%failed()) return
    call note_celsius_temperatures(text, path, extra, config)
  end subroutine read_run_config

  ! A scene without temperatures (elastic springs) takes no thermodynamic variable and no
  ! Lyapunov reference temperature: either, if given, is refused with the scene's reason.
  subroutine refuse_thermal_settings(text, path, extra, config, failure)
    character(len=*), intent(in) :: text, path
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(in), target :: config
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: reason, where

    reason = config%scene%without_temperatures()
    if (len(reason) == 0) return
    where = given_origin(text, 'integrator', integrator_fields(config), path, 'thermo_variable', extra)
    if (len(where) > 0) then
      call fail(failure, failure_input, where//': &integrator: thermo_variable is not allowed: '//reason// &
                '; allowed: leave it out', 'thermo_variable')
      return
    end if
    where = given_origin(text, 'output', output_fields(config), path, 'theta_r', extra)
    if (len(where) > 0) call fail(failure, failure_input, where//': &output: theta_r is not allowed: '//reason// &
                                  '; allowed: leave it out', 'theta_r')
  end subroutine refuse_thermal_settings

  ! A temperature level the input set below 150 K (theta = 7, 77) is most likely degrees Celsius:
  ! each such field gets a warning (the run goes on: 100 K is a possible, if unusual, scene).
  subroutine note_celsius_temperatures(text, path, extra, config)
    character(len=*), intent(in) :: text, path
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout), target :: config
    character(len=16), allocatable :: groups(:)
    character(len=400), allocatable :: suspects(:)
    integer :: g

    call config%scene%group_names(groups)
    do g = 1, size(groups)
      call celsius_suspects(text, trim(groups(g)), config%scene%fields(trim(groups(g))), path, suspects, extra)
      config%warnings = [character(len=400) :: config%warnings, suspects]
    end do
    call celsius_suspects(text, 'output', output_fields(config), path, suspects, extra)
    config%warnings = [character(len=400) :: config%warnings, suspects]
  end subroutine note_celsius_temperatures

  ! One rule for dt and t_end: a fixed-step integrator takes ceiling(t_end/dt) steps of dt, so a dt
  ! above t_end (a run that would step past its end) is refused, and so is a plan above the step
  ! budget; for an integrator that chooses its steps dt is the first trial step (or the output
  ! interval), capped at t_end.
  subroutine check_step_plan(text, path, extra, config, failure)
    character(len=*), intent(in) :: text, path
    type(namelist_item), intent(in) :: extra(:)
    type(run_configuration), intent(inout) :: config
    type(failure_type), intent(out) :: failure

    associate (choice => config%integrator)
      if (config%chooses_times) then
        choice%dt = min(choice%dt, choice%t_end)
      else if (choice%dt > choice%t_end) then
        call fail(failure, failure_input, value_origin(text, 'integrator', 'dt', path, extra)//': &integrator: dt = '// &
                  reals_text([choice%dt])//' is longer than t_end = '//reals_text([choice%t_end])//'; allowed: '// &
                  'dt <= t_end (scheme = '''//trim(choice%scheme)//''' takes fixed steps of dt)')
      else if (step_count(choice) > choice%max_steps) then
        call fail(failure, failure_input, value_origin(text, 'integrator', 't_end', path, extra)//': &integrator: t_end = '// &
                  reals_text([choice%t_end])//' with dt = '//reals_text([choice%dt])//' needs '// &
                  reals_text([choice%t_end/choice%dt])//' steps, more than max_steps = '// &
                  integer_text(choice%max_steps)//'; allowed: t_end/dt <= max_steps (raise max_steps, up to '// &
                  integer_text(huge(1))//', or choose a longer dt)')
      end if
    end associate
  end subroutine check_step_plan

  ! The &integrator fields the input set (file or overrides): `tolerance` switches step control on
  ! for the integrators with error control; each one the chosen integrator does not read is
  ! named in a warning, with what reads it.
  subroutine note_unused_settings(text, path, extra, entry, config)
    character(len=*), intent(in) :: text, path
    type(namelist_item), intent(in) :: extra(:)
    type(integrator_entry), intent(in) :: entry
    type(run_configuration), intent(inout) :: config
    type(namelist_item), allocatable :: items(:)
    character(len=24), parameter :: watched(6) = [character(len=24) :: 'tolerance', 'ts_tolerance', &
      'discrete_gradient', 'metric', 'newton_tol', 'newton_max_iterations']
    character(len=:), allocatable :: name, readers
    integer :: i

    allocate (config%warnings(0))
    call group_items(text, 'integrator', watched, path, items, extra)
    do i = 1, size(items)
      name = item_name(items(i)%item)
      if (.not. any(watched == name)) cycle
      select case (name)
      case ('tolerance', 'ts_tolerance')
        config%integrator%tolerance_given = .true.
        if (entry%adaptive .or. entry%error_control) cycle
        readers = 'the adaptive integrators and those with error control'
      case ('discrete_gradient', 'metric')
        if (entry%uses_discrete_gradient) cycle
        readers = 'scheme = ''eme'''
      case default
        if (entry%reads_newton_settings) cycle
        readers = 'the integrators that solve nonlinear systems by Newton''s method'
      end select
      if (any(index(config%warnings, items(i)%origin//': &integrator: '//name//' ') == 1)) cycle
      config%warnings = [character(len=400) :: config%warnings, items(i)%origin//': &integrator: '//name// &
                         ' is not used by scheme = '''//trim(entry%name)//''' (read by '//readers//')']
    end do
  end subroutine note_unused_settings

  ! An integrator of the continuous constrained flow needs constraints with a continuous-time
  ! form and an initial state that satisfies their hidden constraints (dg/dt = 0).
  subroutine check_continuous_start(config, entry, failure)
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    type(failure_type), intent(out) :: failure
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:)
    character(len=:), allocatable :: why
    integer :: k

    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, failure)
    if (failure%failed()) return
    do k = 1, size(constraints)
      if (constraints(k)%item%continuous_form) cycle
      call fail(failure, failure_input, '&constraints: scheme = '''//trim(entry%name) &
          //''' integrates the constrained flow in continuous '// &
                'time, and the '//trim(constraints(k)%item%name)//' constraint has no continuous-time form')
      return
    end do
    why = initial_inconsistency(model, constraints, z0)
    if (len(why) > 0) then
      call fail(failure, failure_input, '&initial: scheme = '''//trim(entry%name) &
          //''' integrates the constrained motion in continuous '// &
                'time (EME and the midpoint rule enforce the constraints at each step''s end and take any initial '// &
                'velocity): '//why)
    end if
  end subroutine check_continuous_start

  ! Step-size control of a discrete-gradient step measures its error against the continuous flow
  ! (src/integrator/local_error_estimate): a constraint without a continuous form, or with a hidden
  ! constraint that the step does not enforce (g1: q1.v1 = 0), is refused with a tolerance.
  subroutine check_controllable_constraints(config, entry, failure)
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    type(failure_type), intent(out) :: failure
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:), gradient(:)
    real(real64) :: value
    logical :: hidden
    integer :: k

    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, failure)
    if (failure%failed()) return
    allocate (gradient(size(z0)))
    do k = 1, size(constraints)
      call constraints(k)%item%momentum_condition(model, z0, hidden, value, gradient)
      if (constraints(k)%item%continuous_form .and. .not. hidden) cycle
      call fail(failure, failure_input, '&integrator: tolerance with scheme = '''//trim(entry%name)//''' and the '// &
                trim(constraints(k)%item%name)//' constraint: step-size control is not available with it (the '// &
                'step keeps the constraint on positions but not its hidden constraint on velocities, whose error '// &
                'no step size reduces); allowed: fixed steps (no tolerance), or relaxed_dp853, which chooses its '// &
                'steps with this constraint')
      return
    end do
  end subroutine check_controllable_constraints

  !> The fields of &integrator (docs/input.md).
  function integrator_fields(config) result(fields)
    type(run_configuration), intent(in), target :: config
    type(group_field), allocatable :: fields(:)
    character(len=:), allocatable :: schemes

    schemes = integrator_names(.false.)
    associate (c => config%integrator)
      fields = [ &
        text_field('scheme', c%scheme, choices_text(schemes), schemes), &
        text_field('thermo_variable', config%thermo_variable, choices_text(joined(thermo_variable_names, ' ')), &
                   joined(thermo_variable_names, ' ')), &
        text_field('discrete_gradient', config%discrete_gradient, choices_text(joined(discrete_gradient_names, ' ')), &
                   joined(discrete_gradient_names, ' ')), &
        text_field('metric', config%metric, choices_text(joined(metric_names, ' ')), joined(metric_names, ' ')), &
        real_field('dt', c%dt, 'a real number > 0 [s]', 's', minimum=0.0_real64, exclusive=.true.), &
        real_field('t_end', c%t_end, 'a real number > 0 [s]', 's', minimum=0.0_real64, exclusive=.true.), &
        real_field('newton_tol', c%newton_tol, 'a real number > 0 and <= 0.01 (Newton''s tolerance; a looser one '// &
                   'accepts a step that has hardly moved)', '1', minimum=0.0_real64, exclusive=.true., &
                   maximum=max_newton_tol), &
        real_field('tolerance', c%tolerance, 'a real number > 0: the absolute and relative error per step of the '// &
                   'adaptive integrators', '1', minimum=0.0_real64, exclusive=.true.), &
        real_field('ts_tolerance', c%tolerance, 'the same as tolerance (its old name)', '1', minimum=0.0_real64, &
                   exclusive=.true.), &
        integer_field('newton_max_iterations', c%newton_max_iterations, &
                      'an integer >= 1 (Newton iterations per solve)', minimum=1), &
        integer_field('max_steps', c%max_steps, 'an integer >= 1 (default '//integer_text(default_step_budget)// &
                      '): the most accepted steps of the whole run (with -eme_continue, the steps before count '// &
                      'too); a fixed-step run that needs more is refused, one that chooses its steps stops there '// &
                      '(exit status 3)', minimum=1)]
    end associate
  end function integrator_fields

  !> The fields of &output (docs/input.md).
  function output_fields(config) result(fields)
    type(run_configuration), intent(in), target :: config
    type(group_field), allocatable :: fields(:)

    fields = [ &
      text_field('file', config%file, 'a path ending in .h5 (default results/<input name>.h5)', ''), &
      absolute_temperature(real_field('theta_r', config%theta_r, 'a real number > 0 [K] (default theta_ref, or the '// &
                                      'fixed temperature)', 'K', minimum=0.0_real64, exclusive=.true.)), &
      logical_field('overwrite', config%overwrite, '.true. or .false. (default): replace an existing complete file'), &
      integer_field('every', config%output_every, 'an integer >= 1 (default 1): write every N-th point, each step '// &
                    'row standing for the N steps before it (sums, extremes; docs/output.md)', minimum=1), &
      real_field('interval', config%output_interval, 'a real number >= 0 [s] (default 0: off): with an '// &
                 'integrator that chooses its steps, they land on every multiple of it and a row is written there '// &
                 '(and at t_end), each step row standing for the steps since the last', 's', minimum=0.0_real64), &
      integer_field('compression', config%compression, 'an integer 0 (default: none) to 9: gzip level of the '// &
                    'datasets (with the shuffle filter)', minimum=0), &
      integer_field('snapshot_every', config%snapshot_every, 'an integer >= 0 (default 0: the first and last '// &
                    'states only): a run split over ranks (a spring chain on the sparse path) writes the state '// &
                    'to /snapshots at t = 0, every K-th step and the last (with interval: at the output times '// &
                    'instead, and this is left out); other runs keep it in /state', minimum=0)]
  end function output_fields

  !> Whether fields `name_a` and `name_b` of the eme_run groups set the same variable: the same
  !> name, or a field and its old name (tolerance and ts_tolerance). False if either is unknown.
  logical function same_variable(name_a, name_b)
    character(len=*), intent(in) :: name_a, name_b
    type(run_configuration), target :: defaults
    type(group_field) :: x, y
    logical :: found_a, found_b

    call default_run(defaults)
    call find_field(defaults, name_a, x, found_a)
    call find_field(defaults, name_b, y, found_b)
    same_variable = found_a .and. found_b
    if (.not. same_variable) return
    same_variable = x%name == y%name .or. associated(x%real_value, y%real_value) .or. &
                    associated(x%real_values, y%real_values) .or. associated(x%integer_value, y%integer_value) .or. &
                    associated(x%logical_value, y%logical_value) .or. associated(x%text_value, y%text_value)
  end function same_variable

  !> The number of values field `name` of the eme_run groups holds: 1 for a scalar, the array's
  !> size for an array of reals (mass: 2, gravity: 3), 0 if there is no such field.
  integer function field_length(name)
    character(len=*), intent(in) :: name
    type(run_configuration), target :: defaults
    type(group_field) :: field
    logical :: found

    call default_run(defaults)
    call find_field(defaults, name, field, found)
    field_length = 0
    if (.not. found) return
    field_length = 1
    if (associated(field%real_values)) field_length = size(field%real_values)
  end function field_length

  !> The units of field `name` of the eme_run groups ('' for a text or logical field, or none).
  function field_units(name, config) result(units)
    character(len=*), intent(in) :: name
    type(run_configuration), intent(in), target, optional :: config   !! whose model's fields (default: the default model's)
    character(len=:), allocatable :: units
    type(run_configuration), target :: defaults
    type(group_field) :: field
    logical :: found

    if (present(config)) then
      call find_field(config, name, field, found)
    else
      call default_run(defaults)
      call find_field(defaults, name, field, found)
    end if
    units = ''
    if (found) units = trim(field%units)
  end function field_units

  ! A run configuration with the default scene, whose fields hold the defaults.
  subroutine default_run(defaults)
    type(run_configuration), intent(out) :: defaults
    type(namelist_item) :: no_items(0)
    type(failure_type) :: failure

    call select_scene(' ', 'defaults', no_items, defaults%scene, failure)
  end subroutine default_run

  ! The field `name` of the eme_run groups, bound to the variables of `defaults` (found =
  ! .false. if there is none).
  subroutine find_field(defaults, name, field, found)
    type(run_configuration), intent(in), target :: defaults
    character(len=*), intent(in) :: name
    type(group_field), intent(out) :: field
    logical, intent(out) :: found
    type(group_field), allocatable :: table(:)
    character(len=16), allocatable :: groups(:)
    integer :: g, k

    found = .false.
    call defaults%scene%group_names(groups)
    do g = 1, size(groups) + 2
      if (g <= size(groups)) then
        table = defaults%scene%fields(trim(groups(g)))
      else if (g == size(groups) + 1) then
        table = integrator_fields(defaults)
      else
        table = output_fields(defaults)
      end if
      k = findloc(table%name, name, dim=1)
      if (k == 0) cycle
      field = table(k)
      found = .true.
      return
    end do
  end subroutine find_field

  ! Whether `name` is a field of one of the groups.
  logical function is_field(config, groups, name)
    type(run_configuration), intent(in), target :: config
    character(len=*), intent(in) :: groups(:), name
    integer :: g

    is_field = any(field_names(integrator_fields(config)) == name)
    if (.not. is_field) is_field = any(field_names(output_fields(config)) == name)
    do g = 1, size(groups)
      if (.not. is_field) is_field = any(field_names(config%scene%fields(trim(groups(g)))) == name)
    end do
  end function is_field

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
