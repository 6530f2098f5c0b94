!> The index of a study: output_dir/index.h5, whose dataset /cases has one row per case
!> (h5py: f['cases'][:]): case, file, one column per sweep, status ('complete', 'failed: <reason>',
!> 'incomplete: interrupted by <signal>' or 'pending'), failure_kind and the case's figures. The
!> dataset /integrators holds the integrator registry (name, label, family, capabilities), so
!> the scripts that chart a study name and order its schemes as the code does. The attribute
!> case_1_input is case 1's input as namelist text (all groups and fields, defaults included):
!> every case shares it but for the swept fields, so the scene is known without a case file.
!>
!> Crash safety. index.h5 is never written in place: a new one is written as index.h5.tmp and
!> renamed over it, when the study starts, every 2 s while cases end, and at the end. A case's
!> result counts as recorded once its line is appended to output_dir/index.journal (one line
!> per result, appended whole); a restart replays the journal over index.h5. A case file holds
!> its case number, overrides and figures too, so a missing or damaged index is rebuilt from the
!> case files (and the journal). On a restart every case recorded complete is checked against its
!> file (it opens, says complete, and its datasets have the recorded number of rows), and a case
!> that fails the check runs again. In an index-only study (&study index_only) there are no case
!> files: index.h5 and the journal are the record.
module study_index
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use study_config, only: study_definition
  use hdf5_files, only: hdf5_file
  use hdf5_table, only: table_columns, column_real, column_integer, table_rows
  use filesystem, only: make_directories, remove_file, file_exists, append_text, os_error_text
  use integrator_registry, only: integrator_entry, registered_integrators, integrator_count
  use build_info, only: code_version
  use provenance, only: write_provenance, iso_time
  use run_options, only: petsc_options_in_force
  use run_config, only: field_units
  use effective_namelist, only: namelist_of_run
  use namelist_text, only: blanked, item_name
  use study_case_files, only: case_file, case_name, case_overrides, case_file_checks_out, case_from_file
  use study_journal, only: case_result, journal_entry, status_length, kind_length, metric_count, journal_line, &
                           read_journal, start_journal
  use number_text, only: integer_text
  implicit none (type, external)
  private
  public :: case_index, case_result, status_length, kind_length, metric_count, m_rank, &
            m_run_count

  ! metrics: steps_completed, steps_planned, newton_iterations, wall_time_seconds, solve_time_seconds,
  ! energy_drift, min_entropy_increment, max_lyapunov_increment, angular_momentum_drift, min_temperature,
  ! halved_steps, rejected_steps (the run file's run_figures from energy_drift on), rank, run_count
  integer, parameter :: m_steps = 1, m_rank = 13, m_run_count = 14
  character(len=*), parameter :: metric_names(metric_count) = [character(len=24) :: 'steps_completed', &
    'steps_planned', 'newton_iterations', 'wall_time_seconds', 'solve_time_seconds', 'energy_drift', &
    'min_entropy_increment', 'max_lyapunov_increment', 'angular_momentum_drift', 'min_temperature', &
    'halved_steps', 'rejected_steps', 'rank', 'run_count']
  !> The metrics' units, in order.
  character(len=*), parameter :: metric_units(metric_count) = [character(len=3) :: '1', '1', '1', 's', 's', '1', &
                                                                'J/K', 'J', 'J s', 'K', '1', '1', '1', '1']
  logical, parameter :: metric_is_integer(metric_count) = [.true., .true., .true., .false., .false., .false., &
                                                            .false., .false., .false., .false., .true., .true., .true., &
                                                            .true.]
  real(real64), parameter :: index_interval = 2.0_real64   !! seconds between rewrites of index.h5

  !> The open index of a study and every case's result.
  type :: case_index
    type(study_definition), pointer :: study => null()
    type(table_columns) :: columns
    type(case_result), allocatable :: results(:)
    character(len=:), allocatable :: index_path, journal_path
    character(len=:), allocatable :: started       !! when this run of the study began (ISO 8601)
    integer(int64) :: last_write = 0, clock_rate = 1
  contains
    procedure :: open => open_index
    procedure :: record
    procedure :: close => close_index
  end type case_index

contains

  !> Creates the output directory and a fresh index.h5 with a row per case, keeping the results
  !> of earlier runs of the same study (from index.h5, the journal and the case files) that still
  !> check out; pending(c) says which cases are to run. `notes` tells the user what the restart
  !> found (empty if nothing to say). A different study in output_dir is an error.
  subroutine open_index(self, study, pending, notes, stat, message)
    class(case_index), intent(inout) :: self
    type(study_definition), intent(in), target :: study
    logical, allocatable, intent(out) :: pending(:)
    character(len=:), allocatable, intent(out) :: notes
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(case_result) :: from_file
    integer :: c, rebuilt, rejected
    logical :: found

    self%study => study
    self%started = iso_time()
    self%index_path = study%output_dir//'/index.h5'
    self%journal_path = study%output_dir//'/index.journal'
    notes = ''
    allocate (self%results(size(study%cases)), pending(size(study%cases)))
    call define_columns(study, self%columns)
    call make_directories(study%output_dir, stat)
    if (stat /= 0) then
      message = study%input_file//': cannot create the output directory '''//study%output_dir//''': '// &
                os_error_text(stat)
      return
    end if
    call read_previous_index(self, notes, stat, message)
    if (stat /= 0) return
    call replay_journal(self, notes, stat, message)
    if (stat /= 0) return
    rebuilt = 0
    rejected = 0
    if (.not. study%index_only) then
      do c = 1, size(study%cases)
        if (self%results(c)%status == 'complete') then
          if (.not. case_file_checks_out(study, c, nint(self%results(c)%metrics(m_steps)))) then
            rejected = rejected + 1
            self%results(c)%status = 'pending'
          end if
        else if (file_exists(case_file(study, c))) then
          call case_from_file(study, c, from_file, found)
          if (found) then
            self%results(c) = from_file
            rebuilt = rebuilt + 1
          end if
        end if
      end do
    end if
    if (rebuilt > 0) call add_note(notes, integer_text(rebuilt)//' complete cases recovered from their files')
    if (rejected > 0) call add_note(notes, integer_text(rejected)//' cases recorded complete whose files do not ' &
                                    //'check out (missing, unreadable, incomplete or short) run again')
    do c = 1, size(study%cases)
      pending(c) = self%results(c)%status /= 'complete'
      if (pending(c)) self%results(c)%status = 'pending'
      if (pending(c)) self%results(c)%failure_kind = 'none'
    end do
    call system_clock(self%last_write, self%clock_rate)
    call write_index(self, stat, message)
    if (stat == 0) then
      call start_journal(self%journal_path, 'eme_ensemble results of '//study%input_file//', '// &
                         integer_text(size(self%results))//' cases: case, failure_kind, metrics, status, overrides', stat)
      if (stat /= 0) message = 'cannot write '//self%journal_path//' ('//study%input_file//'): '//os_error_text(stat)
    end if
  end subroutine open_index

  !> Stores case c's result (its run count one higher): appended to the journal at once, and in
  !> index.h5 at the next rewrite (at most index_interval seconds later, or at close).
  subroutine record(self, c, result, stat, message)
    class(case_index), intent(inout) :: self
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    integer(int64) :: now

    message = ''
    self%results(c)%status = result%status
    self%results(c)%failure_kind = result%failure_kind
    self%results(c)%metrics(1:m_rank) = result%metrics(1:m_rank)
    self%results(c)%metrics(m_run_count) = self%results(c)%metrics(m_run_count) + 1
    call append_text(self%journal_path, journal_line(c, self%results(c), case_overrides(self%study, c)), .false., stat)
    if (stat /= 0) then
      message = 'cannot append to '//self%journal_path//' ('//self%study%input_file//'): '//os_error_text(stat)
      return
    end if
    call system_clock(now)
    if (real(now - self%last_write, real64) >= index_interval*real(self%clock_rate, real64)) then
      call write_index(self, stat, message)
      self%last_write = now
    end if
  end subroutine record

  !> Writes the final index.h5 and empties the journal, whose lines it now holds.
  subroutine close_index(self, stat, message)
    class(case_index), intent(inout) :: self
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message

    call write_index(self, stat, message)
    if (stat == 0) call remove_file(self%journal_path, stat)
    if (stat /= 0 .and. len(message) == 0) message = 'cannot remove '//self%journal_path//': '//os_error_text(stat)
  end subroutine close_index

  ! case, file, one column per sweep, status, failure_kind, the metrics (rank and run_count last).
  subroutine define_columns(study, columns)
    type(study_definition), intent(in) :: study
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
    do m = 1, metric_count
      call columns%add(trim(metric_names(m)), merge(column_integer, column_real, metric_is_integer(m)))
    end do
  end subroutine define_columns

  ! The parameter columns of case c (case and sweep values): numbers and texts in column order.
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

  ! The attribute column_units of /cases: the units of every column, in order ('' for a text).
  subroutine column_units(file, study, stat)
    type(hdf5_file), intent(in) :: file
    type(study_definition), intent(in) :: study
    integer, intent(out) :: stat
    character(len=24) :: units(2 + sum(study%sweeps%elements) + 2 + metric_count)
    integer :: s, next

    units = ''
    units(1) = '1'                        ! case; file is a text
    next = 3
    do s = 1, size(study%sweeps)
      associate (sweep => study%sweeps(s))
        if (.not. sweep%textual) units(next:next + sweep%elements - 1) = field_units(item_name(sweep%field))
        next = next + sweep%elements
      end associate
    end do
    units(next + 2:) = metric_units       ! after status and failure_kind
    call file%set_dataset_texts('cases', 'column_units', units, stat)
  end subroutine column_units

  ! 'name(i)' for element i of the swept array or section `field` ('mass' or 'p2(1:2)').
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

  ! Writes index.h5: built in memory, written as index.h5.tmp (synced) and renamed over index.h5.
  subroutine write_index(self, stat, message)
    type(case_index), intent(inout) :: self
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(hdf5_file) :: file
    real(real64), allocatable :: numbers(:, :), parameters(:)
    character(len=status_length), allocatable :: texts(:, :)
    character(len=64), allocatable :: parameter_texts(:)
    integer :: c, n_numbers, n_texts, ignored

    message = ''
    n_numbers = self%columns%numeric_count()
    n_texts = self%columns%text_count()
    allocate (numbers(n_numbers, size(self%results)), texts(n_texts, size(self%results)))
    do c = 1, size(self%results)
      call case_parameters(self%study, c, parameters, parameter_texts)
      numbers(:, c) = [parameters, self%results(c)%metrics]
      texts(1, c) = ''
      if (.not. self%study%index_only) texts(1, c) = case_name(c)
      texts(2:n_texts - 2, c) = parameter_texts
      texts(n_texts - 1, c) = self%results(c)%status
      texts(n_texts, c) = self%results(c)%failure_kind
    end do
    call file%create_in_memory(stat)
    if (stat == 0) call self%columns%write(file%id, 'cases', numbers, texts, stat)
    if (stat == 0) call file%set_text('study', self%study%input_file, stat)
    if (stat == 0) call file%set_text('base', self%study%base, stat)
    if (stat == 0) call file%set_text('combine', self%study%combine, stat)
    ! What every case shares (all but the swept fields): the scene without opening a case file.
    if (stat == 0) call file%set_text('case_1_input', namelist_of_run(self%study%cases(1)%config), stat)
    if (stat == 0) call file%set_integer('index_only', merge(1, 0, self%study%index_only), stat)
    if (stat == 0) call file%set_integer('repeats', self%study%repeats, stat)
    if (stat == 0) call file%set_text('code_version', code_version, stat)
    if (stat == 0) call write_provenance(file, 'EME study '//self%study%input_file//': '// &
                                         integer_text(size(self%results))//' cases', petsc_options_in_force(), stat, &
                                         started=self%started)
    if (stat == 0) call column_units(file, self%study, stat)
    if (stat == 0) call write_registry(file, stat)
    if (stat == 0) call file%store(self%index_path, .true., stat)
    call file%close(ignored)
    if (stat > 0) then
      message = 'cannot write '//self%index_path//' ('//self%study%input_file//'): '//os_error_text(stat)
    else if (stat /= 0) then
      message = 'HDF5 failed to build '//self%index_path
    end if
  end subroutine write_index

  ! The dataset /integrators: one row per registered integrator.
  subroutine write_registry(file, stat)
    type(hdf5_file), intent(in) :: file
    integer, intent(out) :: stat
    type(table_columns) :: columns
    type(integrator_entry) :: entries(integrator_count)
    character(len=status_length) :: texts(4, integrator_count)
    real(real64) :: numbers(4, integrator_count)
    integer :: i

    call columns%add('name', len(entries(1)%name))
    call columns%add('label', len(entries(1)%label))
    call columns%add('family', len(entries(1)%family))
    call columns%add('description', len(entries(1)%description))
    call columns%add('takes_constraints', column_integer)
    call columns%add('uses_discrete_gradient', column_integer)
    call columns%add('adaptive', column_integer)
    call columns%add('error_control', column_integer)
    entries = registered_integrators()
    do i = 1, size(entries)
      texts(:, i) = [character(len=status_length) :: entries(i)%name, entries(i)%label, entries(i)%family, &
                     entries(i)%description]
      numbers(:, i) = merge(1.0_real64, 0.0_real64, [entries(i)%takes_constraints, entries(i)%uses_discrete_gradient, &
                                                     entries(i)%adaptive, entries(i)%error_control])
    end do
    call columns%write(file%id, 'integrators', numbers, texts, stat)
  end subroutine write_registry

  ! Results of an earlier run of the same study from its index.h5, if there is one. A damaged
  ! index is set aside (the journal and case files rebuild it); a different case list (other
  ! sweeps or values) is an error: the old files would not match their rows.
  subroutine read_previous_index(self, notes, stat, message)
    type(case_index), intent(inout) :: self
    character(len=:), allocatable, intent(inout) :: notes
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(hdf5_file) :: old
    real(real64), allocatable :: numbers(:, :), parameters(:)
    character(len=status_length), allocatable :: texts(:, :)
    character(len=64), allocatable :: parameter_texts(:)
    integer :: c, rows, n_numbers, n_texts, ignored

    stat = 0
    message = ''
    if (.not. file_exists(self%index_path)) return
    call old%open_existing(self%index_path, .false., stat)
    rows = -1
    if (stat == 0) rows = table_rows(old%id, 'cases')
    if (stat /= 0 .or. rows < 0) then
      call old%close(ignored)
      stat = 0
      call add_note(notes, self%index_path//' cannot be read; it is rebuilt from the journal and the case files')
      return
    end if
    if (rows /= size(self%results)) then
      call old%close(ignored)
      stat = 1
      message = self%index_path//' belongs to a different study (its case count differs); use another output_dir '// &
                'or remove it'
      return
    end if
    n_numbers = self%columns%numeric_count()
    n_texts = self%columns%text_count()
    allocate (numbers(n_numbers, rows), texts(n_texts, rows))
    call self%columns%read(old%id, 'cases', numbers, texts, stat)
    call old%close(ignored)
    if (stat /= 0) then
      stat = 0
      call add_note(notes, self%index_path//' cannot be read; it is rebuilt from the journal and the case files')
      return
    end if
    do c = 1, rows
      call case_parameters(self%study, c, parameters, parameter_texts)
      if (any(abs(numbers(1:size(parameters), c) - parameters) > 0.0_real64) .or. &
          any(texts(2:n_texts - 2, c) /= parameter_texts)) then
        stat = 1
        message = self%index_path//' belongs to a different study (case '//integer_text(c)// &
                  ' differs); use another output_dir or remove it'
        return
      end if
      self%results(c)%status = texts(n_texts - 1, c)
      self%results(c)%failure_kind = texts(n_texts, c)(1:kind_length)
      self%results(c)%metrics = numbers(size(parameters) + 1:, c)
    end do
  end subroutine read_previous_index

  ! Applies the journal's lines (each the latest result of its case) over what index.h5 gave. A
  ! line that does not parse, or names no case of the study, is skipped; one of another study
  ! (its overrides differ) is an error.
  subroutine replay_journal(self, notes, stat, message)
    type(case_index), intent(inout) :: self
    character(len=:), allocatable, intent(inout) :: notes
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: message
    type(journal_entry), allocatable :: entries(:)
    integer :: k, c, applied, skipped

    call read_journal(self%journal_path, entries, skipped, stat, message)
    if (stat /= 0) return
    applied = 0
    do k = 1, size(entries)
      c = entries(k)%case_number
      if (c < 1 .or. c > size(self%results)) then
        skipped = skipped + 1
        cycle
      end if
      if (entries(k)%overrides /= blanked(case_overrides(self%study, c))) then
        stat = 1
        message = self%journal_path//' belongs to a different study (case '//integer_text(c)//' differs); use ' &
                  //'another output_dir or remove it'
        return
      end if
      self%results(c) = entries(k)%result
      applied = applied + 1
    end do
    if (applied > 0) call add_note(notes, integer_text(applied)//' results taken from '//self%journal_path)
    if (skipped > 0) call add_note(notes, integer_text(skipped)//' damaged lines of '//self%journal_path//' skipped')
  end subroutine replay_journal

  subroutine add_note(notes, text)
    character(len=:), allocatable, intent(inout) :: notes
    character(len=*), intent(in) :: text

    if (len(notes) > 0) notes = notes//new_line('a')
    notes = notes//text
  end subroutine add_note

  pure function unquoted(text) result(plain_text)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: plain_text

    plain_text = trim(adjustl(text))
    if (len(plain_text) >= 2) then
      if (index('''"', plain_text(1:1)) > 0) plain_text = plain_text(2:len(plain_text) - 1)
    end if
  end function unquoted

end module study_index
