!> The layout of a run file (docs/output.md): every dataset a run writes, declared once in
!> `output_schema` with its name, rows (one per point t_n, or one per step), units, description
!> and how a row that stands for several steps combines them (&output every); the columns and
!> column units a dataset takes for a run's model and constraints; and the CF auxiliary
!> coordinate of the per-step datasets. `eme_run --output-schema` prints the table; the Python
!> tests check real files against it.
module run_schema
  use, intrinsic :: iso_fortran_env, only: output_unit
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use step_balances, only: balance_count, balance_names, applicable_balances
  implicit none (type, external)
  private
  public :: output_dataset, output_schema, per_column, print_output_schema, dataset_coordinates, column_units, &
            expanded_columns, count_words, schema_version, model_says, dataset_description, dataset_units, thermal_only

  !> The version of this layout, the run file's root attribute schema_version (absent before 2).
  !> 2: the model describes its datasets (model_says), and a model without momenta has no
  !> angular_momentum dataset.
  integer, parameter :: schema_version = 2

  !> One dataset of the layout. `columns` names a vector's columns; the run fills in the
  !> entries of the model's state (<state>), of its subsystems (<subsystems>), of its momenta
  !> (<momenta>) and of the active constraints (<constraints>), prefixed as written
  !> (theta_<subsystems> gives theta_1 theta_2). A description (or units) model_says comes from
  !> the model's words (dataset_description).
  !> Units '<columns>': per column (the attribute column_units, from the model or the
  !> constraints). Datasets of constraints exist only when a constraint is active. `combine`: what
  !> a row holds that stands for several steps (&output every = N): the last step's value, or the
  !> sum, min, max or mean over the steps.
  type :: output_dataset
    character(len=24) :: name
    character(len=5) :: rows                !! 'point' (N+1 rows) or 'step' (N rows)
    character(len=24) :: columns            !! '' for a (rows) dataset
    character(len=9) :: units
    logical :: integer_valued
    character(len=4) :: combine
    character(len=240) :: description
  end type output_dataset

  !> Units of a dataset whose columns differ in units.
  character(len=*), parameter :: per_column = '<columns>'
  !> A description or units the run's model gives (src/structure/model_interface, model_words).
  character(len=*), parameter :: model_says = '<the model says>'
  !> The model's units of energy, entropy and temperature (J, J/K and K for the pendulum).
  character(len=*), parameter :: energy_units = '<E>', entropy_units = '<S>', theta_units = '<theta>'

  type(output_dataset), parameter :: output_schema(24) = [ &
    output_dataset('time', 'point', '', 's', .false., 'last', &
                   'time t_n of each point; the dimension scale of every per-point dataset'), &
    output_dataset('state', 'point', '<state>', per_column, .false., 'last', &
                   'the state z in the run''s thermodynamic variable; `columns` names its entries'), &
    output_dataset('temperature', 'point', 'theta_<subsystems>', theta_units, .false., 'last', model_says), &
    output_dataset('energy', 'point', '', energy_units, .false., 'last', model_says), &
    output_dataset('entropy', 'point', '', entropy_units, .false., 'last', model_says), &
    output_dataset('lyapunov', 'point', '', energy_units, .false., 'last', 'V = E - theta_r S, eq. (14)'), &
    output_dataset('angular_momentum', 'point', '<momenta>', per_column, .false., 'last', &
                   model_says//'; only for a model with momenta'), &
    output_dataset('boundary_heat', 'point', '', energy_units, .false., 'last', &
                   'heat supplied through constraints since t = 0, sum of dt times their heat supply (zero without)'), &
    output_dataset('constraint_residual', 'point', 'g_<constraints>', per_column, .false., 'last', &
                   'g(z) of the active constraints (see the attribute constraint_meanings)'), &
    output_dataset('step', 'step', '', '1', .true., 'last', &
                   'the number n (from 1) of the last step the row stands for: the row''s step, or with &output '// &
                   'every = N the N steps up to n; the dimension scale of every per-step dataset'), &
    output_dataset('step_end_time', 'step', '', 's', .false., 'last', &
                   'the time at the end of the row''s (last) step: the time coordinate of every per-step dataset '// &
                   '(their attribute coordinates)'), &
    output_dataset('newton_iterations', 'step', '', '1', .true., 'sum', &
                   'Newton iterations of the step, summed over every solve it took (retries, continuation stages, '// &
                   'substeps); newton_iterations_total / steps_completed is the mean per step'), &
    output_dataset('scheme_temperature', 'step', 'Theta_<subsystems>', theta_units, .false., 'last', &
                   '<the integrator''s entry in the registry says>'), &
    output_dataset('solver_strategy', 'step', '', '1', .true., 'max', &
                   'what found the root: 1 predictor, 2 old state, 3 continuation in dt (same dt); 4-6 the same with the &
                   &fallback line search; 0 for PETSc TS'), &
    output_dataset('snes_solves', 'step', '', '1', .true., 'sum', &
                   'SNESSolve calls of the step (continuation stages included), or TS steps taken for PETSc TS'), &
    output_dataset('rejected_roots', 'step', '', '1', .true., 'sum', &
                   'converged roots rejected as unphysical (non-positive temperature), or TS steps rejected'), &
    output_dataset('residual_norm', 'step', '', '1', .false., 'max', &
                   '2-norm of the final residual of the step''s last nonlinear solve, as the solver''s convergence '// &
                   'test measured it (root attribute solver_snes_atol); NaN where the step solves no nonlinear system '// &
                   '(explicit stages, CVODE)'), &
    output_dataset('converged_reason', 'step', '', '1', .true., 'last', &
                   'the solver''s converged reason of the step''s last solve, in its own numbering (flag_values, '// &
                   'flag_meanings): SNESConvergedReason, TSConvergedReason, CVode''s flag; 0 without a solver'), &
    output_dataset('step_seconds', 'step', '', 's', .false., 'sum', 'wall-clock time of the step (the integrator''s advance)'), &
    output_dataset('min_entropy_increment', 'step', '', entropy_units, .false., 'min', &
                   'S_n - S_(n-1) of the step; of a row that stands for several steps, the smallest of theirs'), &
    output_dataset('max_lyapunov_increment', 'step', '', energy_units, .false., 'max', &
                   'V_n - V_(n-1) of the step; of a row that stands for several steps, the largest of theirs'), &
    output_dataset('balance', 'step', '<balances>', '1', .false., 'max', &
                   'the balances |dE - Q|, max |dJ_k| (conserved), -dS and dV in ulps of their scales '// &
                   '(docs/faults.md); a guaranteed one (balance_guarantees) above balance_bound_ulps stops the run'), &
    output_dataset('resolved', 'step', '', '1', .true., 'sum', &
                   '1 where the accepted step broke a guaranteed balance and was solved again with the model''s '// &
                   'default solver settings (the balance figures are the second solve''s), else 0'), &
    output_dataset('multiplier', 'step', 'lambda_<constraints>', per_column, .false., 'mean', &
                   'Lagrange multipliers of the active constraints (see the attribute constraint_meanings)')]

  !> The datasets of a model with temperatures and an entropy (a mechanical model has none).
  character(len=*), parameter :: thermal_datasets(6) = [character(len=24) :: 'temperature', 'entropy', 'lyapunov', &
                                                       'scheme_temperature', 'min_entropy_increment', &
                                                       'max_lyapunov_increment']

contains

  !> True for a dataset only a model with temperatures and an entropy has.
  pure logical function thermal_only(name)
    character(len=*), intent(in) :: name

    thermal_only = any(thermal_datasets == name)
  end function thermal_only

  !> The schema as tab-separated lines: name, rows, columns, units, description.
  subroutine print_output_schema()
    type(output_dataset) :: spec
    integer :: k

    write (output_unit, '(a)') 'name'//achar(9)//'rows'//achar(9)//'columns'//achar(9)//'units'//achar(9)// &
      'combine'//achar(9)//'description'
    do k = 1, size(output_schema)
      spec = output_schema(k)
      write (output_unit, '(a)') trim(spec%name)//achar(9)//trim(spec%rows)//achar(9)//trim(spec%columns)//achar(9) &
        //trim(spec%units)//achar(9)//trim(spec%combine)//achar(9)//trim(spec%description)
    end do
  end subroutine print_output_schema

  ! The CF auxiliary coordinate of a dataset: step_end_time for a per-step one (but the step
  ! scale and step_end_time itself), none for the others.
  pure function dataset_coordinates(name, rows) result(text)
    character(len=*), intent(in) :: name, rows
    character(len=:), allocatable :: text

    text = ''
    if (rows == 'step' .and. name /= 'step' .and. name /= 'step_end_time') text = 'step_end_time'
  end function dataset_coordinates

  !> A dataset's description for this run: the model's words where the schema says model_says.
  function dataset_description(spec, model) result(text)
    type(output_dataset), intent(in) :: spec
    class(generic_model), intent(in) :: model
    character(len=:), allocatable :: text

    text = trim(spec%description)
    if (index(spec%description, model_says) /= 1) return
    select case (spec%name)
    case ('temperature')
      text = trim(model%words%temperature)
    case ('energy')
      text = trim(model%words%energy)
    case ('entropy')
      text = trim(model%words%entropy)
    case ('angular_momentum')
      text = trim(model%words%momenta)
    end select
  end function dataset_description

  !> A dataset's units for this run: the model's where the schema names a model's units.
  function dataset_units(spec, model) result(units)
    type(output_dataset), intent(in) :: spec
    class(generic_model), intent(in) :: model
    character(len=:), allocatable :: units

    select case (spec%units)
    case (energy_units)
      units = trim(model%words%energy_units)
    case (entropy_units)
      units = trim(model%words%entropy_units)
    case (theta_units)
      units = trim(model%words%temperature_units)
    case default
      units = trim(spec%units)
    end select
  end function dataset_units

  ! The units of a vector dataset's `count` columns: the model's (<state>; <momenta>), the
  ! constraints' (<constraints>: g's for constraint_residual, lambda's for multiplier), else the schema's.
  function column_units(spec, model, constraints, count) result(units)
    type(output_dataset), intent(in) :: spec
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    integer, intent(in) :: count
    character(len=16) :: units(count)
    integer :: k

    if (spec%columns == '<state>') then
      call model%column_units(units)
    else if (spec%columns == '<momenta>') then
      units = model%words%momentum_units
    else if (index(spec%columns, '<constraints>') > 0) then
      do k = 1, count
        if (spec%name == 'multiplier') then
          units(k) = constraints(k)%item%multiplier_units
        else
          units(k) = constraints(k)%item%value_units
        end if
      end do
    else
      units = dataset_units(spec, model)
    end if
  end function column_units

  ! The columns of a schema entry for this run.
  function expanded_columns(template, model, constraints) result(columns)
    character(len=*), intent(in) :: template
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    character(len=:), allocatable :: columns
    character(len=:), allocatable :: prefix
    logical :: mask(balance_count)
    integer :: at, i

    columns = ''
    if (template == '<state>') then
      do i = 1, model%state_size
        columns = columns//' '//trim(model%column_names(i))
      end do
    else if (template == '<momenta>') then
      do i = 1, model%momentum_count()
        columns = columns//' '//trim(model%momentum_names(i))
      end do
    else if (template == '<balances>') then
      mask = applicable_balances(model)
      do i = 1, balance_count
        if (mask(i)) columns = columns//' '//trim(balance_names(i))
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

end module run_schema
