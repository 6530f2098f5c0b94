!> The root attributes of a run file that say what was run: the integrator (its registry entry,
!> thermodynamic variable, discrete gradient and metric, step settings), every field of the
!> model's namelist groups under its namelist name with its units (<name>_units), the output
!> settings and the active constraints (docs/output.md).
module run_attributes
  use, intrinsic :: iso_fortran_env, only: real64
  use hdf5_files, only: hdf5_file
  use failures, only: failure_type
  use namelist_field, only: group_field, field_real, field_integer, field_logical
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry
  use thermo_variable_kinds, only: thermo_variable_names
  use discrete_gradient, only: discrete_gradient_names, metric_names, metric_nondimensional, quotient_threshold
  use run_config, only: run_configuration
  use build_info, only: code_version
  use run_schema, only: schema_version
  implicit none (type, external)
  private
  public :: write_run_attributes

contains

  !> The integrator, the model's input and the output settings as root attributes of `file`,
  !> under the namelists' names.
  subroutine write_run_attributes(file, config, entry, model, constraints, failure)
    type(hdf5_file), intent(in) :: file
    type(run_configuration), intent(in) :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    type(failure_type), intent(out) :: failure
    character(len=16), allocatable :: groups(:)
    character(len=:), allocatable :: gradient, metric, names, meanings
    integer :: a, g, k

    gradient = 'none'
    metric = 'none'
    associate (choice => config%integrator)
      if (entry%uses_discrete_gradient) then
        gradient = trim(discrete_gradient_names(choice%discrete_gradient))
        metric = trim(metric_names(choice%metric))
        if (choice%metric == metric_nondimensional) metric = metric//': '//trim(model%words%metric_scales)
      end if
      call text('scheme', trim(entry%name))
      call text('scheme_family', trim(entry%family))
      call text('scheme_label', trim(entry%label))
      call text('scheme_description', trim(entry%description))
      ! A model without temperatures (elastic springs) has no thermodynamic variable and no V.
      if (model%temperature_count() > 0) then
        call text('thermo_variable', trim(thermo_variable_names(choice%thermo_variable)))
      else
        call text('thermo_variable', 'none')
      end if
      call text('discrete_gradient', gradient)
      call text('metric', metric)
      call text('input_file', config%input_file)
      call text('code_version', code_version)
      call real_attribute('dt', choice%dt, 's')
      call real_attribute('t_end', choice%t_end, 's')
      if (model%temperature_count() > 0) call real_attribute('theta_r', config%theta_r, 'K')
      call real_attribute('newton_tol', choice%newton_tol, '1')
      call real_attribute('tolerance', choice%tolerance, '1')
      call real_attribute('ts_tolerance', choice%tolerance, '1')   ! the old name, for old scripts
      if (.not. failure%failed()) call file%set_integer('newton_max_iterations', choice%newton_max_iterations, failure, units='1')
      if (.not. failure%failed()) call file%set_integer('max_steps', choice%max_steps, failure, units='1')
    end associate
    call real_attribute('quotient_threshold', quotient_threshold, '1')
    if (.not. failure%failed()) call file%set_integer('unknowns', model%state_size + size(constraints), failure, units='1')
    if (.not. failure%failed()) call file%set_integer('schema_version', schema_version, failure, units='1')
    ! The conserved momentum components whose largest drift run_figures reports, by name separated
    ! by blanks (a column of /angular_momentum, or J_g), 'none' if none, and their axes: component
    ! k's value is /angular_momentum's J_x, J_y, J_z dotted with axis k (a planar J: J itself).
    names = ''
    do k = 1, model%conserved_count()
      if (k > 1) names = names//' '
      names = names//trim(model%conserved(k)%name)
    end do
    if (len(names) == 0) names = 'none'
    call text('conserved_momentum', names)
    if (model%conserved_count() > 0 .and. .not. failure%failed()) &
      call file%set_reals('conserved_momentum_axes', [(model%conserved(k)%axis, k=1, model%conserved_count())], &
                          failure, units='1')
    if (.not. failure%failed()) call file%set_integer('output_every', config%output_every, failure, units='1')
    if (.not. failure%failed()) call file%set_real('output_interval', config%output_interval, failure, units='s')
    if (.not. failure%failed()) call file%set_integer('compression', config%compression, failure, units='1')
    if (.not. failure%failed()) call file%set_integer('snapshot_every', config%snapshot_every, failure, units='1')
    ! The metric's scales: one attribute per subsystem for the scene-sized models (at most two
    ! subsystems, named: metric_scale_spring1), one of a row per subsystem beyond (a chain of N
    ! springs: metric_scale, N x n; 2 N attributes would crowd the file's root at 1e5 springs).
    if (model%subsystem_count() > 2 .and. all([(size(model%subsystems(a)%metric_scale), a=1, model%subsystem_count())] &
                                              == size(model%subsystems(1)%metric_scale))) then
      if (.not. failure%failed()) &
        call file%set_reals('metric_scale', [(model%subsystems(a)%metric_scale, a=1, model%subsystem_count())], failure, &
                            units='those of the subsystems'' invariants (attribute metric), a row per subsystem', &
                            row_length=size(model%subsystems(1)%metric_scale))
    else
      do a = 1, model%subsystem_count()
        associate (part => model%subsystems(a))
          if (.not. failure%failed()) call file%set_reals('metric_scale_'//squeezed(part%name), part%metric_scale, &
                                             failure, units='those of the subsystem''s invariants (attribute metric)')
        end associate
      end do
    end if
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
        if (failure%failed()) return
        select case (fields(i)%kind)
        case (field_real)
          if (associated(fields(i)%real_value)) then
            call file%set_real(trim(fields(i)%name), fields(i)%real_value, failure, units=trim(fields(i)%units))
          else
            call file%set_reals(trim(fields(i)%name), fields(i)%real_values, failure, units=trim(fields(i)%units))
          end if
        case (field_integer)
          call file%set_integer(trim(fields(i)%name), fields(i)%integer_value, failure, units='1')
        case (field_logical)
          call file%set_integer(trim(fields(i)%name), merge(1, 0, fields(i)%logical_value), failure, units='1')
        case default
          call file%set_text(trim(fields(i)%name), trim(fields(i)%text_value), failure)
        end select
      end do
    end subroutine field_attributes

    subroutine text(name, value)
      character(len=*), intent(in) :: name, value
      if (.not. failure%failed()) call file%set_text(name, value, failure)
    end subroutine text

    subroutine real_attribute(name, value, units)
      character(len=*), intent(in) :: name, units
      real(real64), intent(in) :: value
      if (.not. failure%failed()) call file%set_real(name, value, failure, units=units)
    end subroutine real_attribute
  end subroutine write_run_attributes

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

end module run_attributes
