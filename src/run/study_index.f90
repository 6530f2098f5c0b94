!> The index of a study: output_dir/index.h5, whose dataset /cases has one row per case
!> (h5py: f['cases'][:]): case, file, one column per sweep, status ('complete', 'failed: <reason>'
!> or 'pending') and the case's figures. It is written with every case's row before any case
!> runs and updated row by row as cases end. Opening the index of an earlier run of the same
!> study keeps the cases it records as complete whose files exist; the others are pending again.
!> The dataset /integrators holds the integrator registry (name, label, family, capabilities), so
!> the scripts that chart a study name and order its schemes as the code does.
module study_index
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use study_config, only: study_definition
  use hdf5_series, only: hdf5_file
  use hdf5_table, only: table_columns, column_real, column_integer, table_rows
  use filesystem, only: make_directories
  use integrator_registry, only: integrator_entry, registered_integrators, integrator_count
  use build_info, only: code_version
  use number_text, only: integer_text
  implicit none (type, external)
  private
  public :: case_index, case_result, case_file, status_length, metric_count, m_rank, m_run_count

  integer, parameter :: status_length = 256
  integer, parameter :: metric_count = 11
  ! metrics: steps_completed, steps_planned, newton_iterations, wall_time_seconds, solve_time_seconds,
  ! energy_drift, min_entropy_increment, max_lyapunov_increment, angular_momentum_drift, rank, run_count
  integer, parameter :: m_rank = 10, m_run_count = 11

  !> What happened to one case (an index row without its parameters).
  type :: case_result
    character(len=status_length) :: status = 'pending'
    real(real64) :: metrics(metric_count) = 0.0_real64
  end type case_result

  !> The open index of a study and every case's result.
  type :: case_index
    type(study_definition), pointer :: study => null()
    type(hdf5_file) :: file
    type(table_columns) :: columns
    type(case_result), allocatable :: results(:)
  contains
    procedure :: open => open_index
    procedure :: record
    procedure :: close => close_index
  end type case_index

contains

  !> The file of case c: output_dir/case_NNNNN.h5.
  pure function case_file(study, c) result(path)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: c
    character(len=:), allocatable :: path
    character(len=16) :: name

    write (name, '("case_", i5.5, ".h5")') c
    path = study%output_dir//'/'//trim(name)
  end function case_file

  !> Creates the output directory and index.h5 with a row per case, keeping the results of an
  !> earlier run of the same study; pending(c) says which cases are still to run.
  subroutine open_index(self, study, pending, stat, message)
    class(case_index), intent(inout) :: self
    type(study_definition), intent(in), target :: study
    logical, allocatable, intent(out) :: pending(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    integer :: c

    self%study => study
    allocate (self%results(size(study%cases)), pending(size(study%cases)))
    call define_columns(study, self%columns)
    call make_directories(study%output_dir, stat)
    if (stat /= 0) then
      message = study%input_file//': cannot create the output directory '''//study%output_dir//''''
      return
    end if
    call read_previous_index(self, stat, message)
    if (stat /= 0) return
    ! A case is done if an earlier run completed it and its file is still there.
    do c = 1, size(study%cases)
      inquire (file=case_file(study, c), exist=pending(c), iostat=stat)
      pending(c) = .not. (stat == 0 .and. pending(c) .and. self%results(c)%status == 'complete')
      if (pending(c)) self%results(c)%status = 'pending'
    end do
    call write_index(self, stat, message)
  end subroutine open_index

  !> Stores case c's result (its run count one higher) and writes its row to disk.
  subroutine record(self, c, result, stat)
    class(case_index), intent(inout) :: self
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    integer, intent(out) :: stat

    self%results(c)%status = result%status
    self%results(c)%metrics(1:m_rank) = result%metrics(1:m_rank)
    self%results(c)%metrics(m_run_count) = self%results(c)%metrics(m_run_count) + 1
    call write_row(self, c, stat)
    if (stat == 0) call self%file%flush(stat)
  end subroutine record

  !> Closes index.h5.
  subroutine close_index(self, stat)
    class(case_index), intent(inout) :: self
    integer, intent(out) :: stat

    call self%file%close(stat)
  end subroutine close_index

  ! case, file, one column per sweep, status, the metrics, rank and run_count.
  subroutine define_columns(study, columns)
    type(study_definition), intent(in) :: study
    type(table_columns), intent(out) :: columns
    integer :: s

    call columns%add('case', column_integer)
    call columns%add('file', 64)
    do s = 1, size(study%sweeps)
      if (study%sweeps(s)%textual) then
        call columns%add(study%sweeps(s)%field, 64)
      else
        call columns%add(study%sweeps(s)%field, column_real)
      end if
    end do
    call columns%add('status', status_length)
    call columns%add('steps_completed', column_integer)
    call columns%add('steps_planned', column_integer)
    call columns%add('newton_iterations', column_integer)
    call columns%add('wall_time_seconds', column_real)
    call columns%add('solve_time_seconds', column_real)
    call columns%add('energy_drift', column_real)
    call columns%add('min_entropy_increment', column_real)
    call columns%add('max_lyapunov_increment', column_real)
    call columns%add('angular_momentum_drift', column_real)
    call columns%add('rank', column_integer)
    call columns%add('run_count', column_integer)
  end subroutine define_columns

  ! The row of case c: numbers and texts in column order.
  subroutine row_values(self, c, numbers, texts)
    type(case_index), intent(in) :: self
    integer, intent(in) :: c
    real(real64), allocatable, intent(out) :: numbers(:)
    character(len=status_length), allocatable, intent(out) :: texts(:)
    character(len=16) :: name
    real(real64) :: value
    integer :: s, ios

    write (name, '("case_", i5.5, ".h5")') c
    numbers = [real(c, real64)]
    texts = [character(len=status_length) :: name]
    do s = 1, size(self%study%sweeps)
      associate (sweep => self%study%sweeps(s), item => self%study%cases(c)%overrides(s)%item)
        if (sweep%textual) then
          texts = [character(len=status_length) :: texts, unquoted(item(index(item, '=') + 1:))]
        else
          read (item(index(item, '=') + 1:), *, iostat=ios) value
          if (ios /= 0) value = ieee_value(value, ieee_quiet_nan)
          numbers = [numbers, value]
        end if
      end associate
    end do
    texts = [texts, self%results(c)%status]
    numbers = [numbers, self%results(c)%metrics]
  end subroutine row_values

  subroutine write_row(self, c, stat)
    type(case_index), intent(inout) :: self
    integer, intent(in) :: c
    integer, intent(out) :: stat
    real(real64), allocatable :: numbers(:)
    character(len=status_length), allocatable :: texts(:)

    call row_values(self, c, numbers, texts)
    call self%columns%write_row(self%file%id, 'cases', c, numbers, texts, stat)
  end subroutine write_row

  ! Creates index.h5 with every case's row (pending, or kept from an earlier run).
  subroutine write_index(self, stat, message)
    type(case_index), intent(inout) :: self
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    integer :: c
    character(len=:), allocatable :: path, ignored

    path = self%study%output_dir//'/index.h5'
    message = 'cannot write '//path
    call self%file%create(path, stat, ignored)
    if (stat /= 0) return
    call self%columns%create(self%file%id, 'cases', size(self%results), stat)
    if (stat == 0) call self%file%set_text('study', self%study%input_file, stat)
    if (stat == 0) call self%file%set_text('base', self%study%base, stat)
    if (stat == 0) call self%file%set_text('combine', self%study%combine, stat)
    if (stat == 0) call self%file%set_text('code_version', code_version, stat)
    do c = 1, size(self%results)
      if (stat == 0) call write_row(self, c, stat)
    end do
    if (stat == 0) call write_registry(self%file, stat)
    if (stat == 0) call self%file%flush(stat)
    if (stat == 0) message = ''
  end subroutine write_index

  ! The dataset /integrators: one row per registered integrator.
  subroutine write_registry(file, stat)
    type(hdf5_file), intent(in) :: file
    integer, intent(out) :: stat
    type(table_columns) :: columns
    type(integrator_entry) :: entries(integrator_count)
    character(len=status_length) :: texts(4)
    real(real64) :: numbers(3)
    integer :: i

    call columns%add('name', len(entries(1)%name))
    call columns%add('label', len(entries(1)%label))
    call columns%add('family', len(entries(1)%family))
    call columns%add('description', len(entries(1)%description))
    call columns%add('takes_constraints', column_integer)
    call columns%add('uses_discrete_gradient', column_integer)
    call columns%add('adaptive', column_integer)
    entries = registered_integrators()
    call columns%create(file%id, 'integrators', size(entries), stat)
    do i = 1, size(entries)
      if (stat /= 0) return
      texts(1) = entries(i)%name
      texts(2) = entries(i)%label
      texts(3) = entries(i)%family
      texts(4) = entries(i)%description
      numbers = merge(1.0_real64, 0.0_real64, [entries(i)%takes_constraints, entries(i)%uses_discrete_gradient, &
                                               entries(i)%adaptive])
      call columns%write_row(file%id, 'integrators', i, numbers, texts, stat)
    end do
  end subroutine write_registry

  ! Results of an earlier run of the same study, if its index.h5 exists. A different case list
  ! (other sweeps or values) is an error: the old files would not match their rows.
  subroutine read_previous_index(self, stat, message)
    type(case_index), intent(inout) :: self
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(hdf5_file) :: old
    real(real64), allocatable :: numbers(:), old_numbers(:)
    character(len=status_length), allocatable :: texts(:), old_texts(:)
    character(len=:), allocatable :: path
    integer :: c, rows, n_sweep_numbers, close_stat
    logical :: exists

    stat = 0
    message = ''
    path = self%study%output_dir//'/index.h5'
    inquire (file=path, exist=exists, iostat=close_stat)
    if (close_stat /= 0 .or. .not. exists) return
    call old%open_existing(path, .false., stat)
    if (stat /= 0) then
      message = 'cannot read '//path//' of an earlier run; remove it to start the study afresh'
      return
    end if
    rows = table_rows(old%id, 'cases')
    if (rows /= size(self%results)) then
      stat = 1
      message = path//' belongs to a different study (its case count differs); use another output_dir or remove it'
    end if
    do c = 1, rows
      if (stat /= 0) exit
      call row_values(self, c, numbers, texts)
      allocate (old_numbers(size(numbers)), old_texts(size(texts)))
      call self%columns%read_row(old%id, 'cases', c, old_numbers, old_texts, stat)
      ! The parameters (case, file, sweep values) must be the same; keep status and metrics.
      n_sweep_numbers = size(numbers) - metric_count
      if (stat /= 0 .or. any(abs(old_numbers(1:n_sweep_numbers) - numbers(1:n_sweep_numbers)) > 0.0_real64) .or. &
          any(old_texts(1:size(texts) - 1) /= texts(1:size(texts) - 1))) then
        stat = 1
        message = path//' belongs to a different study (case '//integer_text(c)// &
                  ' differs); use another output_dir or remove it'
      else
        self%results(c)%status = old_texts(size(texts))
        self%results(c)%metrics = old_numbers(n_sweep_numbers + 1:)
      end if
      deallocate (old_numbers, old_texts)
    end do
    call old%close(close_stat)
  end subroutine read_previous_index

  pure function unquoted(text) result(plain)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: plain

    plain = trim(adjustl(text))
    if (len(plain) >= 2) then
      if (index('''"', plain(1:1)) > 0) plain = plain(2:len(plain) - 1)
    end if
  end function unquoted

end module study_index
