!> The run file made in memory (src/run/run_output's create): its root attributes, provenance and
!> the layout of its datasets, from the schema (src/run/run_schema), the model and the integrator.
submodule (run_output) run_output_layout
  use hdf5_series, only: series_table
  use thermo_variable_kinds, only: thermo_variable_names
  use effective_namelist, only: namelist_of_run
  use provenance, only: write_provenance
  use run_schema, only: output_dataset, output_schema, dataset_coordinates, column_units, expanded_columns, count_words, &
                        thermal_only, &
                        dataset_description, dataset_units
  use run_attributes, only: write_run_attributes
  use step_check, only: checked_balances
  use step_balances, only: balance_names, balance_bound_ulps
  implicit none

contains

  module procedure create
    type(output_dataset) :: spec
    integer :: k

    call self%store%start(path, 2, failure, template)
    self%enabled = .true.
    self%every = config%output_every
    self%thermal = model%temperature_count() > 0
    self%by_interval = config%output_interval > 0.0_real64
    if (present(state_rows)) self%state_rows = state_rows
    self%store%tables(point_rows)%compression = config%compression
    self%store%tables(step_rows)%compression = config%compression
    self%store%tables(point_rows)%scale = .true.
    self%store%tables(step_rows)%scale = .true.
    if (.not. failure%failed()) call write_run_attributes(self%store%file, config, entry, model, constraints, failure)
    if (.not. failure%failed()) call write_provenance(self%store%file, 'EME run of '//config%input_file//': '// &
                                         trim(entry%label)//', '// &
                                         trim(thermo_variable_names(config%integrator%thermo_variable)), &
                                         petsc_options, failure)
    if (.not. failure%failed()) call self%store%file%set_text('namelist', namelist_of_run(config), failure)
    if (.not. failure%failed()) call self%store%file%set_text('balance_guarantees', &
                                  checked_names(checked_balances(entry, model, constraints)), failure)
    if (.not. failure%failed()) call self%store%file%set_reals('balance_bound_ulps', balance_bound_ulps, failure)
    if (.not. failure%failed()) call self%store%file%set_text('balance_bound_ulps_units', '1', failure)
    do k = 1, size(extras)
      if (failure%failed()) exit
      if (allocated(extras(k)%text)) then
        call self%store%file%set_text(trim(extras(k)%name), extras(k)%text, failure)
      else
        call self%store%file%set_integer(trim(extras(k)%name), extras(k)%number, failure, units='1')
      end if
    end do
    do k = 1, size(output_schema)
      spec = output_schema(k)
      if (index(spec%columns, '<constraints>') > 0 .and. size(constraints) == 0) cycle
      if (spec%columns == '<momenta>' .and. model%momentum_count() == 0) cycle
      if (thermal_only(spec%name) .and. model%temperature_count() == 0) cycle
      if (.not. self%state_rows .and. any(spec%name == [character(len=18) :: 'state', 'temperature', &
                                                         'scheme_temperature'])) cycle
      if (spec%rows == 'point') then
        call define(self%store%tables(point_rows))
      else
        call define(self%store%tables(step_rows))
      end if
    end do
    do k = 1, size(diagnostics)
      call self%store%tables(step_rows)%define(trim(diagnostics(k)%name), 1, .false., trim(diagnostics(k)%units), &
                             trim(diagnostics(k)%description), rows='step', source='integrator', &
                             combine=diagnostics(k)%combine, coordinates=dataset_coordinates(diagnostics(k)%name, 'step'))
    end do
    ! Both tables gain a row per step: together they buffer at most buffer_bytes.
    associate (points => self%store%tables(point_rows), steps => self%store%tables(step_rows))
      points%capacity_rows = max(1024, buffer_bytes/(8*(points%row_width + steps%row_width)))
      steps%capacity_rows = points%capacity_rows
    end associate

  contains

    subroutine define(table)
      type(series_table), intent(inout) :: table
      character(len=:), allocatable :: columns, description
      character(len=16), allocatable :: units(:)
      character(len=:), allocatable :: common

      columns = expanded_columns(spec%columns, model, constraints)
      description = dataset_description(spec, model)
      if (spec%name == 'scheme_temperature') description = trim(entry%scheme_temperature)
      if (len(columns) == 0) then
        call table%define(trim(spec%name), 1, .false., dataset_units(spec, model), description, &
                          integer_valued=spec%integer_valued, rows=trim(spec%rows), combine=spec%combine, &
                          coordinates=dataset_coordinates(spec%name, spec%rows))
        return
      end if
      units = column_units(spec, model, constraints, count_words(columns))
      ! Columns of different units (the state) carry column_units only: no one units is right.
      common = trim(units(1))
      if (any(units /= units(1))) common = ''
      call table%define(trim(spec%name), count_words(columns), .true., common, description, &
                        integer_valued=spec%integer_valued, columns=columns, rows=trim(spec%rows), &
                        column_units=units, combine=spec%combine, coordinates=dataset_coordinates(spec%name, spec%rows))
    end subroutine define
  end procedure create

  ! The balances checked on every step, blank-separated ('none' if none).
  function checked_names(checked) result(names)
    logical, intent(in) :: checked(:)
    character(len=:), allocatable :: names
    integer :: k

    names = ''
    do k = 1, size(checked)
      if (checked(k)) names = names//' '//trim(balance_names(k))
    end do
    names = trim(adjustl(names))
    if (len(names) == 0) names = 'none'
  end function checked_names

end submodule run_output_layout
