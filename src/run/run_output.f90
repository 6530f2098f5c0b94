!> The HDF5 file of one run (README, Output layout): its datasets, declared once in
!> `output_schema` with their names, rows (one per point t_n, or one per step), units and
!> descriptions, and its root attributes: the integrator (with its registry entry), every field
!> of the model's namelist groups under its namelist name, and provenance. `eme_run
!> --output-schema` prints the table; the Python tests check real files against it.
module run_output
  use, intrinsic :: iso_fortran_env, only: real64, output_unit
  use hdf5_series, only: hdf5_file, series_table
  use namelist_group, only: group_field, field_real, field_integer, field_logical
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry
  use thermo_variable, only: thermo_variable_names
  use discrete_gradient, only: discrete_gradient_names, metric_names, metric_nondimensional, quotient_threshold
  use run_config, only: run_configuration
  use stepper, only: step_report, step_diagnostic
  use build_info, only: code_version
  implicit none (type, external)
  private
  public :: run_file, output_dataset, output_schema, print_output_schema

  !> One dataset of the layout. `columns` names a vector's columns; the run fills in the
  !> entries of the model's state (<state>), of its subsystems (<subsystems>) and of the active
  !> constraints (<constraints>), prefixed as written (theta_<subsystems> gives theta_1 theta_2).
  !> Datasets of constraints exist only when a constraint is active.
  type :: output_dataset
    character(len=24) :: name
    character(len=5) :: rows                !! 'point' (N+1 rows) or 'step' (N rows)
    character(len=24) :: columns            !! '' for a (rows) dataset
    character(len=8) :: units
    logical :: integer_valued
    character(len=200) :: description
  end type output_dataset

  type(output_dataset), parameter :: output_schema(15) = [ &
    output_dataset('time', 'point', '', 's', .false., 'time t_n of each point'), &
    output_dataset('state', 'point', '<state>', 'SI', .false., &
                   'the state z in the run''s thermodynamic variable; `columns` names its entries'), &
    output_dataset('temperature', 'point', 'theta_<subsystems>', 'K', .false., 'spring temperatures'), &
    output_dataset('energy', 'point', '', 'J', .false., 'total energy E = T + V_g + U_1 + U_2'), &
    output_dataset('entropy', 'point', '', 'J/K', .false., 'total entropy S = S_1 + S_2'), &
    output_dataset('lyapunov', 'point', '', 'J', .false., 'V = E - theta_r S, eq. (14)'), &
    output_dataset('angular_momentum', 'point', 'J_x J_y J_z', 'J s', .false., 'J = q1 x p1 + q2 x p2'), &
    output_dataset('boundary_heat', 'point', '', 'J', .false., &
                   'heat supplied through constraints since t = 0, sum of dt times their heat supply (zero without)'), &
    output_dataset('constraint_residual', 'point', 'g_<constraints>', 'SI', .false., &
                   'g(z) of the active constraints (see the attribute constraint_meanings)'), &
    output_dataset('newton_iterations', 'step', '', '1', .true., &
                   'Newton iterations of the step, summed over every solve it took'), &
    output_dataset('scheme_temperature', 'step', 'Theta_<subsystems>', 'K', .false., &
                   '<the integrator''s entry in the registry says>'), &
    output_dataset('solver_strategy', 'step', '', '1', .true., &
                   'what found the root: 1 predictor, 2 old state, 3 continuation in dt (same dt); 4-6 the same with the &
                   &fallback line search; 0 for PETSc TS'), &
    output_dataset('snes_solves', 'step', '', '1', .true., &
                   'SNESSolve calls of the step (continuation stages included), or TS steps taken for PETSc TS'), &
    output_dataset('rejected_roots', 'step', '', '1', .true., &
                   'converged roots rejected as unphysical (non-positive temperature), or TS steps rejected'), &
    output_dataset('multiplier', 'step', 'lambda_<constraints>', 'SI', .false., &
                   'Lagrange multipliers of the active constraints (see the attribute constraint_meanings)')]

  !> An open run file and its two tables of rows (points and steps).
  type :: run_file
    type(hdf5_file) :: file
    type(series_table) :: points, steps
    integer :: constraint_count = 0
  contains
    procedure :: create
    procedure :: record_point
    procedure :: record_step
    procedure :: finish
  end type run_file

contains

  !> Creates the file at config%output_file with its attributes and empty datasets: the schema's,
  !> then one per step for each of the integrator's own diagnostics (attribute source = integrator).
  subroutine create(self, config, entry, model, constraints, diagnostics, steps_planned, stat)
    class(run_file), intent(inout) :: self
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    type(step_diagnostic), intent(in) :: diagnostics(:)
    integer, intent(in) :: steps_planned
    integer, intent(out) :: stat
    character(len=:), allocatable :: ignored
    type(output_dataset) :: spec
    integer :: k

    self%constraint_count = size(constraints)
    call self%file%create(config%output_file, stat, ignored)
    if (stat == 0) call write_run_attributes(self%file, config, entry, model, constraints, steps_planned, stat)
    do k = 1, size(output_schema)
      if (stat /= 0) return
      spec = output_schema(k)
      if (index(spec%columns, '<constraints>') > 0 .and. size(constraints) == 0) cycle
      if (spec%rows == 'point') then
        call define(self%points)
      else
        call define(self%steps)
      end if
    end do
    do k = 1, size(diagnostics)
      if (stat /= 0) return
      call self%steps%define(self%file, trim(diagnostics(k)%name), 1, .false., trim(diagnostics(k)%units), &
                             trim(diagnostics(k)%description), stat, rows='step', source='integrator')
    end do

  contains

    subroutine define(table)
      type(series_table), intent(inout) :: table
      character(len=:), allocatable :: columns, description
      integer :: width

      columns = expanded_columns(spec%columns, model, constraints)
      width = max(1, count_words(columns))
      description = trim(spec%description)
      if (spec%name == 'scheme_temperature') description = trim(entry%scheme_temperature)
      if (len(columns) > 0) then
        call table%define(self%file, trim(spec%name), width, .true., trim(spec%units), description, stat, &
                          integer_valued=spec%integer_valued, columns=columns, rows=trim(spec%rows))
      else
        call table%define(self%file, trim(spec%name), width, .false., trim(spec%units), description, stat, &
                          integer_valued=spec%integer_valued, rows=trim(spec%rows))
      end if
    end subroutine define
  end subroutine create

  !> One row of every per-point dataset, in the schema's order.
  subroutine record_point(self, time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals, stat)
    class(run_file), intent(inout) :: self
    real(real64), intent(in) :: time, z(:), theta(:), energy, entropy, lyapunov, momentum(3), heat, residuals(:)
    integer, intent(out) :: stat

    call self%points%append(self%file, [time, z, theta, energy, entropy, lyapunov, momentum, heat, residuals], stat)
  end subroutine record_point

  !> One row of every per-step dataset, in the schema's order, then the integrator's diagnostics.
  subroutine record_step(self, report, multipliers, stat)
    class(run_file), intent(inout) :: self
    type(step_report), intent(in) :: report
    real(real64), intent(in) :: multipliers(:)
    integer, intent(out) :: stat

    real(real64), allocatable :: diagnostics(:)

    allocate (diagnostics(0))
    if (allocated(report%diagnostics)) diagnostics = report%diagnostics
    call self%steps%append(self%file, [real(report%newton_iterations, real64), report%scheme_temperature, &
                                       real(report%strategy, real64), real(report%solves, real64), &
                                       real(report%rejected, real64), multipliers, diagnostics], stat)
  end subroutine record_step

  !> Writes what is buffered, the final status, step counts and times, and closes the file; stat
  !> reports the first failure.
  subroutine finish(self, status, steps_planned, steps_completed, solve_seconds, wall_seconds, stat)
    class(run_file), intent(inout) :: self
    character(len=*), intent(in) :: status
    integer, intent(in) :: steps_planned, steps_completed
    real(real64), intent(in) :: solve_seconds, wall_seconds
    integer, intent(out) :: stat
    integer :: close_stat

    call self%points%close(self%file, stat)
    call self%steps%close(self%file, close_stat)
    if (stat == 0) stat = close_stat
    call self%file%set_text('status', status, close_stat)
    if (stat == 0) stat = close_stat
    call self%file%set_integer('steps_planned', steps_planned, close_stat)
    if (stat == 0) stat = close_stat
    call self%file%set_integer('steps_completed', steps_completed, close_stat)
    if (stat == 0) stat = close_stat
    call self%file%set_real('solve_time_seconds', solve_seconds, close_stat)
    if (stat == 0) stat = close_stat
    call self%file%set_real('wall_time_seconds', wall_seconds, close_stat)
    if (stat == 0) stat = close_stat
    call self%file%close(close_stat)
    if (stat == 0) stat = close_stat
  end subroutine finish

  !> The schema as tab-separated lines: name, rows, columns, units, description.
  subroutine print_output_schema()
    type(output_dataset) :: spec
    integer :: k

    write (output_unit, '(a)') 'name'//achar(9)//'rows'//achar(9)//'columns'//achar(9)//'units'//achar(9)//'description'
    do k = 1, size(output_schema)
      spec = output_schema(k)
      write (output_unit, '(a)') trim(spec%name)//achar(9)//trim(spec%rows)//achar(9)//trim(spec%columns)//achar(9) &
        //trim(spec%units)//achar(9)//trim(spec%description)
    end do
  end subroutine print_output_schema

  ! The integrator, the model's input and provenance as root attributes, under the namelists'
  ! names.
  subroutine write_run_attributes(file, config, entry, model, constraints, steps_planned, stat)
    type(hdf5_file), intent(in) :: file
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    integer, intent(in) :: steps_planned
    integer, intent(out) :: stat
    character(len=16), allocatable :: groups(:)
    character(len=:), allocatable :: gradient, metric, names, meanings
    integer :: a, g, k

    gradient = 'none'
    metric = 'none'
    associate (choice => config%integrator)
      if (entry%uses_discrete_gradient) then
        gradient = trim(discrete_gradient_names(choice%discrete_gradient))
        metric = trim(metric_names(choice%metric))
        if (choice%metric == metric_nondimensional) metric = metric// &
          ': C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref'
      end if
      stat = 0
      call text('status', 'incomplete: running')
      call text('scheme', trim(entry%name))
      call text('scheme_family', trim(entry%family))
      call text('scheme_label', trim(entry%label))
      call text('scheme_description', trim(entry%description))
      call text('thermo_variable', trim(thermo_variable_names(choice%thermo_variable)))
      call text('discrete_gradient', gradient)
      call text('metric', metric)
      call text('input_file', config%input_file)
      call text('code_version', code_version)
      call real_attribute('dt', choice%dt)
      call real_attribute('t_end', choice%t_end)
      call real_attribute('theta_r', config%theta_r)
      call real_attribute('newton_tol', choice%newton_tol)
      call real_attribute('tolerance', choice%tolerance)
      call real_attribute('ts_tolerance', choice%tolerance)   ! the old name, for old scripts
      if (stat == 0) call file%set_integer('newton_max_iterations', choice%newton_max_iterations, stat)
    end associate
    call real_attribute('quotient_threshold', quotient_threshold)
    if (stat == 0) call file%set_integer('steps_planned', steps_planned, stat)
    if (stat == 0) call file%set_integer('unknowns', model%state_size + size(constraints), stat)
    do a = 1, model%subsystem_count()
      associate (part => model%subsystems(a))
        if (stat == 0) call file%set_reals('metric_scale_'//squeezed(part%name), part%metric_scale, stat)
      end associate
    end do
    call config%scene%group_names(groups)
    do g = 1, size(groups)
      call field_attributes(config%scene%fields(trim(groups(g))))
    end do
    names = ''
    meanings = ''
    do k = 1, size(constraints)
      associate (c => constraints(k)%item)
        if (k > 1) names = names//', '
        names = names//trim(c%name)
        meanings = meanings//trim(c%name)//': '//trim(c%meaning)//' [g: '//trim(c%value_units)//', lambda: ' &
                   //trim(c%multiplier_units)//']; '
      end associate
    end do
    if (len(names) == 0) names = 'none'
    call text('constraints', names)
    if (len(meanings) > 0) call text('constraint_meanings', meanings(1:len(meanings) - 2))

  contains

    ! Each field of a namelist group as an attribute under its name (logicals as 0 or 1).
    subroutine field_attributes(fields)
      type(group_field), intent(in) :: fields(:)
      integer :: i

      do i = 1, size(fields)
        if (stat /= 0) return
        select case (fields(i)%kind)
        case (field_real)
          if (associated(fields(i)%real_value)) then
            call file%set_real(trim(fields(i)%name), fields(i)%real_value, stat)
          else
            call file%set_reals(trim(fields(i)%name), fields(i)%real_values, stat)
          end if
        case (field_integer)
          call file%set_integer(trim(fields(i)%name), fields(i)%integer_value, stat)
        case (field_logical)
          call file%set_integer(trim(fields(i)%name), merge(1, 0, fields(i)%logical_value), stat)
        case default
          call file%set_text(trim(fields(i)%name), trim(fields(i)%text_value), stat)
        end select
      end do
    end subroutine field_attributes

    subroutine text(name, value)
      character(len=*), intent(in) :: name, value
      if (stat == 0) call file%set_text(name, value, stat)
    end subroutine text

    subroutine real_attribute(name, value)
      character(len=*), intent(in) :: name
      real(real64), intent(in) :: value
      if (stat == 0) call file%set_real(name, value, stat)
    end subroutine real_attribute
  end subroutine write_run_attributes

  ! The columns of a schema entry for this run.
  function expanded_columns(template, model, constraints) result(columns)
    character(len=*), intent(in) :: template
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    character(len=:), allocatable :: columns
    character(len=:), allocatable :: prefix
    integer :: at, i

    columns = ''
    if (template == '<state>') then
      do i = 1, model%state_size
        columns = columns//' '//trim(model%column_names(i))
      end do
    else if (index(template, '<subsystems>') > 0) then
      at = index(template, '<subsystems>')
      prefix = template(1:at - 1)
      do i = 1, model%subsystem_count()
        columns = columns//' '//prefix//achar(iachar('0') + i)
      end do
    else if (index(template, '<constraints>') > 0) then
      at = index(template, '<constraints>')
      prefix = template(1:at - 1)
      do i = 1, size(constraints)
        columns = columns//' '//prefix//trim(constraints(i)%item%name)
      end do
    else
      columns = trim(template)
    end if
    columns = trim(adjustl(columns))
  end function expanded_columns

  pure integer function count_words(text)
    character(len=*), intent(in) :: text
    integer :: i

    count_words = 0
    do i = 1, len(text)
      if (text(i:i) /= ' ' .and. (i == 1)) count_words = count_words + 1
      if (i > 1) then
        if (text(i:i) /= ' ' .and. text(i - 1:i - 1) == ' ') count_words = count_words + 1
      end if
    end do
  end function count_words

  ! A name without blanks ('spring 1' -> 'spring1').
  pure function squeezed(name) result(plain)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: plain
    integer :: i

    plain = ''
    do i = 1, len_trim(name)
      if (name(i:i) /= ' ') plain = plain//name(i:i)
    end do
  end function squeezed

end module run_output
