!> The columns of a study's index (/cases of index.h5, src/run/study_index): the case figures
!> (metrics) a case's result holds, their names, units and kinds, which of them the index shows
!> (those the cases' models can have), and each case's parameter columns (its swept values).
module study_columns
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use study_config, only: study_definition
  use hdf5_table, only: table_columns, column_real, column_integer
  use run_config, only: run_configuration, read_run_config
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use study_journal, only: status_length, kind_length, metric_count
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: metric_names, metric_units, metric_is_integer, m_steps, m_cpu, m_solve_cpu, m_warned, m_rank, m_run_count, &
            m_entropy_increment, m_lyapunov_increment, m_momentum_drift, m_min_temperature
  public :: choose_metrics, define_columns, case_parameters

  ! metrics: steps_completed, steps_planned, newton_iterations, wall_time_seconds, solve_time_seconds,
  ! cpu_time_seconds, solve_cpu_time_seconds (the process's CPU time over the run and over its time
  ! loop, beside the wall times), energy_drift, min_entropy_increment, max_lyapunov_increment,
  ! angular_momentum_drift, min_temperature, halved_steps, rejected_steps (the run file's run_figures
  ! from energy_drift on), warned (1 if the complete case's file has the attribute warnings: its
  ! accuracy is in doubt), rank, run_count
  integer, parameter :: m_steps = 1, m_cpu = 6, m_solve_cpu = 7, m_warned = 15, m_rank = 16, m_run_count = 17
  !> The figures whose units are the model's.
  integer, parameter :: m_entropy_increment = 9, m_lyapunov_increment = 10, m_momentum_drift = 11, &
                        m_min_temperature = 12
  character(len=*), parameter :: metric_names(metric_count) = [character(len=24) :: 'steps_completed', &
    'steps_planned', 'newton_iterations', 'wall_time_seconds', 'solve_time_seconds', 'cpu_time_seconds', &
    'solve_cpu_time_seconds', 'energy_drift', 'min_entropy_increment', 'max_lyapunov_increment', &
    'angular_momentum_drift', 'min_temperature', 'halved_steps', 'rejected_steps', 'warned', 'rank', 'run_count']
  !> The metrics' units, in order.
  character(len=*), parameter :: metric_units(metric_count) = [character(len=3) :: '1', '1', '1', 's', 's', 's', &
                                                                's', '1', 'J/K', 'J', 'J s', 'K', '1', '1', '1', '1', '1']
  logical, parameter :: metric_is_integer(metric_count) = [.true., .true., .true., .false., .false., .false., &
                                                            .false., .false., .false., .false., .false., .false., &
                                                            .true., .true., .true., .true., .true.]

contains

  !> Which metrics the index shows, and their units. A figure that no case's model has (a drift of
  ! the conserved momentum, the thermal figures) would be a column of NaN: it is left out. Every
  ! case's model is asked, not only the base file's, since a sweep may change the model (a planar
  ! scene's dimension, gravity); the asking stops once every figure is shown (the pendulum's
  ! scenes: at case 1). Should no case's model build (a refused scene fails in its case), every
  ! figure is shown, as before models chose. Units: the base file's model's (as its sweeps').
  subroutine choose_metrics(study, shown, units)
    type(study_definition), intent(in) :: study
    integer, allocatable, intent(out) :: shown(:)
    character(len=24), intent(out) :: units(metric_count)
    type(run_configuration), target :: base
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    real(real64), allocatable :: z0(:)
    type(failure_type) :: building
    logical :: any_built, momentum, thermal
    integer :: c, m

    units = metric_units
    call read_run_config(study%base, base, building)
    if (.not. building%failed()) call base%scene%build(base%integrator%thermo_variable, model, z0, constraints, &
                                                       building)
    if (.not. building%failed()) then
      units(m_entropy_increment) = model%words%entropy_units
      units(m_lyapunov_increment) = model%words%energy_units
      units(m_momentum_drift) = '1'
      if (model%conserved_count() > 0) units(m_momentum_drift) = model%words%momentum_units
      units(m_min_temperature) = model%words%temperature_units
    end if
    any_built = .false.
    momentum = .false.
    thermal = .false.
    do c = 1, size(study%cases)
      if (allocated(model)) deallocate (model)
      associate (config => study%cases(c)%config)
        call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, building)
      end associate
      if (building%failed()) cycle
      any_built = .true.
      momentum = momentum .or. model%conserved_count() > 0
      thermal = thermal .or. model%temperature_count() > 0
      if (momentum .and. thermal) exit
    end do
    if (.not. any_built) then
      momentum = .true.
      thermal = .true.
    end if
    shown = pack([(m, m=1, metric_count)], [(m /= m_momentum_drift .or. momentum, m=1, metric_count)] .and. &
                 [(all(m /= [m_entropy_increment, m_lyapunov_increment, m_min_temperature]) .or. thermal, &
                   m=1, metric_count)])
  end subroutine choose_metrics

  !> The columns of /cases: case, file, one column per sweep, status, failure_kind, the shown
  !> metrics (rank and run_count last).
  subroutine define_columns(study, shown, columns)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: shown(:)
    type(table_columns), intent(out) :: columns
    integer :: s, m

    call columns%add('case', column_integer)
    call columns%add('file', 64)
    do s = 1, size(study%sweeps)
      associate (sweep => study%sweeps(s))
        if (sweep%textual) then
          call columns%add(sweep%field, 64)
        else if (sweep%elements == 1) then
          call columns%add(sweep%field, column_real)
        else
          ! An array or section: a column per element, name(i).
          do m = sweep%first_element, sweep%first_element + sweep%elements - 1
            call columns%add(element_name(sweep%field, m), column_real)
          end do
        end if
      end associate
    end do
    call columns%add('status', status_length)
    call columns%add('failure_kind', kind_length)
    do m = 1, size(shown)
      call columns%add(trim(metric_names(shown(m))), merge(column_integer, column_real, metric_is_integer(shown(m))))
    end do
  end subroutine define_columns

  !> The parameter columns of case c (case and sweep values): numbers and texts in column order.
  subroutine case_parameters(study, c, numbers, texts)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c
    real(real64), allocatable, intent(out) :: numbers(:)
    character(len=64), allocatable, intent(out) :: texts(:)
    real(real64), allocatable :: values(:)
    integer :: s, ios

    numbers = [real(c, real64)]
    allocate (texts(0))
    do s = 1, size(study%sweeps)
      associate (sweep => study%sweeps(s), item => study%cases(c)%overrides(s)%item)
        if (sweep%textual) then
          texts = [character(len=64) :: texts, unquoted(item(index(item, '=') + 1:))]
        else
          allocate (values(sweep%elements))
          read (item(index(item, '=') + 1:), *, iostat=ios) values
          if (ios /= 0) values = ieee_value(1.0_real64, ieee_quiet_nan)
          numbers = [numbers, values]
          deallocate (values)
        end if
      end associate
    end do
  end subroutine case_parameters

  !> 'name(i)' for element i of the swept array or section `field` ('mass' or 'p2(1:2)').
  pure function element_name(field, i) result(name)
    character(len=*), intent(in) :: field
    integer, intent(in) :: i
    character(len=:), allocatable :: name
    character(len=16) :: number
    integer :: open_at

    open_at = index(field, '(')
    if (open_at == 0) open_at = len(field) + 1
    write (number, '(i0)') i
    name = field(1:open_at - 1)//'('//trim(number)//')'
  end function element_name

  !> A namelist text value without its quotes.
  pure function unquoted(text) result(plain_text)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: plain_text

    plain_text = trim(adjustl(text))
    if (len(plain_text) >= 2) then
      if (index('''"', plain_text(1:1)) > 0) plain_text = plain_text(2:len(plain_text) - 1)
    end if
  end function unquoted

end module study_columns
