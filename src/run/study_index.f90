!> The index of a study: output_dir/index.h5, whose dataset /cases has one row per case
!> (h5py: f['cases'][:]): case, file, one column per sweep, status ('complete', 'failed: <reason>',
!> 'incomplete: interrupted by <signal>' or 'pending'), failure_kind and the case's figures: those
!> the cases' models can have (no angular_momentum_drift column when no case's model has a conserved
!> momentum, no min_entropy_increment, max_lyapunov_increment or min_temperature when none has
!> temperatures; the journal, the ranks' messages and a case's result keep all metric_count
!> figures, NaN where a model has none, so that only the file's columns depend on the model). The
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
!> file (it opens, says complete, its datasets have the recorded number of rows and pass their
!> checksums, its summary attributes are what its datasets give, and it names the case's
!> overrides), and a case that fails the check runs again. An earlier run's cases are matched
!> to this study's by their swept values (index.h5) or overrides (journal, case files), so a
!> study whose sweeps grew keeps its finished cases and renames their files. In an index-only study (&study index_only) there are no case
!> files: index.h5 and the journal are the record.
!> The columns and their figures are src/run/study_columns's; matching an earlier run's cases to
!> this study's is src/run/study_case_matching's.
module study_index
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use study_config, only: study_definition
  use hdf5_files, only: hdf5_file
  use hdf5_table, only: table_columns, column_integer, table_rows
  use filesystem, only: make_directories, remove_file, file_exists, append_text, rename_file
  use integrator_registry, only: integrator_entry, registered_integrators
  use build_info, only: code_version
  use provenance, only: write_provenance, iso_time, machine_load, machine_load_now
  use run_options, only: petsc_options_in_force
  use run_config, only: field_units, run_configuration, read_run_config
  use effective_namelist, only: namelist_of_run
  use namelist_text, only: blanked, item_name
  use study_case_files, only: case_file, case_name, case_overrides, case_file_checks_out, read_case_file
  use study_journal, only: case_result, journal_entry, status_length, kind_length, metric_count, journal_line, &
                           read_journal, start_journal
  use study_columns, only: m_steps, m_cpu, m_solve_cpu, m_warned, m_rank, m_run_count, choose_metrics, define_columns, &
                           case_parameters
  use study_case_matching, only: case_lookup, values_key, values_lookup, overrides_lookup, find_case
  use number_text, only: integer_text
  use failures, only: failure_type, fail, failure_input, failure_io, failure_library
  implicit none (type, external)
  private
  public :: case_index, case_result, status_length, kind_length, metric_count, m_rank, &
            m_run_count, m_warned

  real(real64), parameter :: index_interval = 2.0_real64   !! seconds between rewrites of index.h5

  !> The open index of a study and every case's result.
  type :: case_index
    type(study_definition), pointer :: study => null()
    type(table_columns) :: columns
    type(case_result), allocatable :: results(:)
    integer, allocatable :: shown(:)               !! the metrics that are columns of /cases, in order
    character(len=24) :: units(metric_count) = ''  !! the metrics' units in the base file's model
    character(len=:), allocatable :: index_path, journal_path
    character(len=:), allocatable :: started       !! when this run of the study began (ISO 8601)
    !> The machine's load when this run of the study began and ended (end: once it has), and the
    !> study's ranks, which the load counts among its processes (docs/studies.md, Timings).
    type(machine_load) :: load_start, load_end
    logical :: ended = .false.
    integer :: ranks = 1
    integer(int64) :: last_write = 0, clock_rate = 1
  contains
    procedure :: open => open_index
    procedure :: record
    procedure :: close => close_index
  end type case_index

contains

  !> Creates the output directory and a fresh index.h5 with a row per case, keeping the results
  !> of earlier runs of the same study (from index.h5, the journal and the case files) that still
  !> check out; pending(c) says which cases are to run. An earlier run's cases are matched to
  !> this study's by their swept values, not their numbers: a study whose sweeps grew keeps every
  !> finished case and renames its file where its number moved. `notes` tells the user what the
  !> restart found (empty if nothing to say). A failure: failure_input (refused) if output_dir
  !> holds a finished case that this study does not have (a changed value) or ran from another
  !> base scene; failure_io (or failure_library: HDF5) if the output directory cannot be written.
  !> `ranks`: the study's MPI ranks (default 1), recorded beside the machine's load.
  subroutine open_index(self, study, pending, notes, failure, ranks)
    class(case_index), intent(inout) :: self
    type(study_definition), intent(in), target :: study
    logical, allocatable, intent(out) :: pending(:)
    character(len=:), allocatable, intent(out) :: notes
    type(failure_type), intent(out) :: failure
    integer, intent(in), optional :: ranks
    character(len=:), allocatable :: reason
    type(case_result) :: from_file
    type(case_lookup) :: by_overrides
    character(len=:), allocatable :: overrides
    integer, allocatable :: earlier(:)    !! each case's number in the earlier run whose result it holds (0: none)
    integer :: c, k, rebuilt, rejected, moved
    logical :: found
    logical, allocatable :: claimed(:)

    self%study => study
    self%started = iso_time()
    self%load_start = machine_load_now()
    if (present(ranks)) self%ranks = ranks
    self%index_path = study%output_dir//'/index.h5'
    self%journal_path = study%output_dir//'/index.journal'
    notes = ''
    allocate (self%results(size(study%cases)), pending(size(study%cases)))
    allocate (earlier(size(study%cases)), source=0)
    call choose_metrics(study, self%shown, self%units)
    call define_columns(study, self%shown, self%columns)
    call make_directories(study%output_dir, failure)
    if (failure%failed()) then
      reason = failure%message
      call fail(failure, failure_io, study%input_file//': cannot create the output directory '''//study%output_dir// &
                ''': '//reason, study%output_dir)
      return
    end if
    call overrides_lookup(study, by_overrides)
    call read_previous_index(self, earlier, notes, failure)
    if (failure%failed()) return
    call replay_journal(self, by_overrides, earlier, notes, failure)
    if (failure%failed()) return
    rebuilt = 0
    rejected = 0
    moved = 0
    if (.not. study%index_only) then
      call move_files(study, earlier, self%results, moved, failure)
      if (failure%failed()) return
      do c = 1, size(study%cases)
        if (self%results(c)%status == 'complete') then
          if (.not. case_file_checks_out(study, c, nint(self%results(c)%metrics(m_steps)))) then
            rejected = rejected + 1
            self%results(c)%status = 'pending'
          end if
        end if
      end do
      ! Complete case files that no recorded result accounts for (a damaged or removed index):
      ! each is matched to its case by its overrides, and renamed if its number moved.
      allocate (claimed(size(study%cases)), source=.false.)
      do c = 1, size(study%cases)
        if (self%results(c)%status == 'complete') claimed(c) = .true.
      end do
      do k = 1, size(study%cases)
        if (claimed(k)) cycle
        if (.not. file_exists(case_file(study, k))) cycle
        call read_case_file(case_file(study, k), from_file, overrides, found)
        if (.not. found) cycle
        c = find_case(by_overrides, blanked(overrides))
        if (c == 0) cycle
        if (self%results(c)%status == 'complete') cycle
        if (c /= k) then
          if (claimed(c)) cycle                                  ! taken already
          if (file_exists(case_file(study, c))) cycle           ! another file there: the case runs again
          call rename_file(case_file(study, k), case_file(study, c), failure)
          if (failure%failed()) then
            reason = failure%message
            call fail(failure, failure_io, 'cannot rename '//case_file(study, k)//' to '//case_file(study, c)//': '// &
                      reason, case_file(study, k))
            return
          end if
          moved = moved + 1
        end if
        from_file%metrics(m_run_count) = max(1.0_real64, self%results(c)%metrics(m_run_count))
        self%results(c) = from_file
        claimed(c) = .true.
        rebuilt = rebuilt + 1
      end do
    end if
    if (rebuilt > 0) call add_note(notes, integer_text(rebuilt)//' complete cases recovered from their files')
    if (moved > 0) call add_note(notes, integer_text(moved)//' case files renamed: their cases'' numbers moved as ' &
                                 //'the sweeps grew')
    if (rejected > 0) call add_note(notes, integer_text(rejected)//' cases recorded complete whose files do not ' &
                                    //'check out (missing, unreadable, damaged, incomplete, short, or with figures ' &
                                    //'that their data do not give) run again')
    do c = 1, size(study%cases)
      pending(c) = self%results(c)%status /= 'complete'
      if (pending(c)) self%results(c)%status = 'pending'
      if (pending(c)) self%results(c)%failure_kind = 'none'
    end do
    call system_clock(self%last_write, self%clock_rate)
    call write_index(self, failure)
    if (.not. failure%failed()) then
      call start_journal(self%journal_path, 'eme_ensemble results of '//study%input_file//', '// &
                         integer_text(size(self%results))//' cases: case, failure_kind, metrics, status, overrides', &
                         failure)
      if (failure%failed()) then
        reason = failure%message
        call fail(failure, failure_io, 'cannot write '//self%journal_path//' ('//study%input_file//'): '//reason, &
                  self%journal_path)
      end if
    end if
  end subroutine open_index

  ! Renames the file of each complete result taken from an earlier run whose case number moved
  ! (earlier(c) /= c) to the case's new name: first every one to case_NNNNN.h5.moving, then each
  ! to its name, so that no file is replaced before it moved. A .moving file left by a killed
  ! restart is finished first.
  subroutine move_files(study, earlier, results, moved, failure)
    type(study_definition), intent(in) :: study
    integer, intent(in) :: earlier(:)
    type(case_result), intent(in) :: results(:)
    integer, intent(out) :: moved
    type(failure_type), intent(out) :: failure
    integer :: c

    moved = 0
    do c = 1, size(study%cases)
      if (failure%failed()) exit
      if (file_exists(case_file(study, c)//'.moving')) call move(case_file(study, c)//'.moving', case_file(study, c))
    end do
    do c = 1, size(study%cases)
      if (failure%failed()) exit
      if (earlier(c) == 0 .or. earlier(c) == c .or. results(c)%status /= 'complete') cycle
      if (.not. file_exists(case_file(study, earlier(c)))) cycle      ! the check then finds it missing
      call move(case_file(study, earlier(c)), case_file(study, c)//'.moving')
    end do
    do c = 1, size(study%cases)
      if (failure%failed()) exit
      if (.not. file_exists(case_file(study, c)//'.moving')) cycle
      call move(case_file(study, c)//'.moving', case_file(study, c))
      moved = moved + 1
    end do

  contains

    subroutine move(from, to)
      character(len=*), intent(in) :: from, to
      character(len=:), allocatable :: reason

      call rename_file(from, to, failure)
      if (failure%failed()) then
        reason = failure%message
        call fail(failure, failure_io, 'cannot rename '//from//' to '//to//' ('//study%input_file//'): '//reason, from)
      end if
    end subroutine move
  end subroutine move_files

  !> Stores case c's result (its run count one higher): appended to the journal at once, and in
  !> index.h5 at the next rewrite (at most index_interval seconds later, or at close).
  subroutine record(self, c, result, failure)
    class(case_index), intent(inout) :: self
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: reason
    integer(int64) :: now

    self%results(c)%status = result%status
    self%results(c)%failure_kind = result%failure_kind
    self%results(c)%metrics(1:m_rank) = result%metrics(1:m_rank)
    self%results(c)%metrics(m_run_count) = self%results(c)%metrics(m_run_count) + 1
    call append_text(self%journal_path, journal_line(c, self%results(c), case_overrides(self%study, c)), .false., &
                     failure)
    if (failure%failed()) then
      reason = failure%message
      call fail(failure, failure_io, 'cannot append to '//self%journal_path//' ('//self%study%input_file//'): '// &
                reason, self%journal_path)
      return
    end if
    call system_clock(now)
    if (real(now - self%last_write, real64) >= index_interval*real(self%clock_rate, real64)) then
      call write_index(self, failure)
      self%last_write = now
    end if
  end subroutine record

  !> Writes the final index.h5, with the machine's load at the end, and empties the journal,
  !> whose lines it now holds.
  subroutine close_index(self, failure)
    class(case_index), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: reason

    self%load_end = machine_load_now()
    self%ended = .true.
    call write_index(self, failure)
    if (failure%failed()) return
    call remove_file(self%journal_path, failure)
    if (failure%failed()) then
      reason = failure%message
      call fail(failure, failure_io, 'cannot remove '//self%journal_path//': '//reason, self%journal_path)
    end if
  end subroutine close_index

  ! The attribute column_units of /cases: the units of every column, in order ('' for a text):
  ! the swept fields' and the figures' in the units of the base file's model (the gas containers'
  ! are nondimensional).
  subroutine column_units(file, self, failure)
    type(hdf5_file), intent(in) :: file
    type(case_index), intent(in) :: self
    type(failure_type), intent(out) :: failure
    character(len=24) :: units(2 + sum(self%study%sweeps%elements) + 2 + size(self%shown))
    type(run_configuration), target :: base
    type(failure_type) :: base_failure
    integer :: s, next

    call read_run_config(self%study%base, base, base_failure)
    units = ''
    units(1) = '1'                        ! case; file is a text
    next = 3
    do s = 1, size(self%study%sweeps)
      associate (sweep => self%study%sweeps(s))
        if (.not. sweep%textual) then
          if (.not. base_failure%failed()) then
            units(next:next + sweep%elements - 1) = field_units(item_name(sweep%field), base)
          else
            units(next:next + sweep%elements - 1) = field_units(item_name(sweep%field))
          end if
        end if
        next = next + sweep%elements
      end associate
    end do
    units(next + 2:) = self%units(self%shown)       ! after status and failure_kind
    call file%set_dataset_texts('cases', 'column_units', units, failure)
  end subroutine column_units

  ! Writes index.h5: built in memory, written as index.h5.tmp (synced) and renamed over index.h5.
  subroutine write_index(self, failure)
    type(case_index), intent(inout) :: self
    type(failure_type), intent(out) :: failure
    type(hdf5_file) :: file
    real(real64), allocatable :: numbers(:, :), parameters(:)
    character(len=status_length), allocatable :: texts(:, :)
    character(len=64), allocatable :: parameter_texts(:)
    character(len=:), allocatable :: reason
    type(failure_type) :: ignored
    integer :: c, n_numbers, n_texts

    n_numbers = self%columns%numeric_count()
    n_texts = self%columns%text_count()
    allocate (numbers(n_numbers, size(self%results)), texts(n_texts, size(self%results)))
    do c = 1, size(self%results)
      call case_parameters(self%study, c, parameters, parameter_texts)
      numbers(:, c) = [parameters, self%results(c)%metrics(self%shown)]
      texts(1, c) = ''
      if (.not. self%study%index_only) texts(1, c) = case_name(c)
      texts(2:n_texts - 2, c) = parameter_texts
      texts(n_texts - 1, c) = self%results(c)%status
      texts(n_texts, c) = self%results(c)%failure_kind
    end do
    call file%create_in_memory(failure)
    if (.not. failure%failed()) call self%columns%write(file%id, 'cases', numbers, texts, failure)
    if (.not. failure%failed()) call file%set_text('study', self%study%input_file, failure)
    if (.not. failure%failed()) call file%set_text('base', self%study%base, failure)
    if (.not. failure%failed()) call file%set_text('combine', self%study%combine, failure)
    ! What every case shares (all but the swept fields): the scene without opening a case file.
    if (.not. failure%failed()) call file%set_text('case_1_input', namelist_of_run(self%study%cases(1)%config), failure)
    if (.not. failure%failed()) call file%set_integer('index_only', merge(1, 0, self%study%index_only), failure)
    if (.not. failure%failed()) call file%set_integer('repeats', self%study%repeats, failure)
    if (.not. failure%failed()) call file%set_text('code_version', code_version, failure)
    if (.not. failure%failed()) call write_provenance(file, 'EME study '//self%study%input_file//': '// &
                                         integer_text(size(self%results))//' cases', petsc_options_in_force(), failure, &
                                         started=self%started)
    if (.not. failure%failed()) call load_attributes(file, self, failure)
    if (.not. failure%failed()) call column_units(file, self, failure)
    if (.not. failure%failed()) call write_registry(file, failure)
    if (.not. failure%failed()) call file%store(self%index_path, .true., failure)
    call file%close(ignored)
    if (failure%code == failure_io) then           ! the OS's words
      reason = failure%message
      call fail(failure, failure_io, 'cannot write '//self%index_path//' ('//self%study%input_file//'): '//reason, &
                self%index_path)
    else if (failure%failed()) then
      call fail(failure, failure_library, 'HDF5 failed to build '//self%index_path, self%index_path)
    end if
  end subroutine write_index

  ! The machine's load averages (1, 5 and 15 minutes) and cores online when this run of the study
  ! began, and when it ended (once it has), and its ranks: what its timings shared the machine with.
  subroutine load_attributes(file, self, failure)
    type(hdf5_file), intent(in) :: file
    type(case_index), intent(in) :: self
    type(failure_type), intent(out) :: failure

    call file%set_reals('load_average_start', self%load_start%averages, failure)
    if (.not. failure%failed()) call file%set_integer('cores_start', self%load_start%cores, failure)
    if (.not. failure%failed()) call file%set_integer('ranks', self%ranks, failure)
    if (.not. self%ended) return
    if (.not. failure%failed()) call file%set_reals('load_average_end', self%load_end%averages, failure)
    if (.not. failure%failed()) call file%set_integer('cores_end', self%load_end%cores, failure)
  end subroutine load_attributes

  ! The dataset /integrators: one row per registered integrator.
  subroutine write_registry(file, failure)
    type(hdf5_file), intent(in) :: file
    type(failure_type), intent(out) :: failure
    type(table_columns) :: columns
    type(integrator_entry), allocatable :: entries(:)
    character(len=status_length), allocatable :: texts(:, :)
    real(real64), allocatable :: numbers(:, :)
    integer :: i

    allocate (entries, source=registered_integrators())
    allocate (texts(4, size(entries)), numbers(4, size(entries)))

    call columns%add('name', len(entries(1)%name))
    call columns%add('label', len(entries(1)%label))
    call columns%add('family', len(entries(1)%family))
    call columns%add('description', len(entries(1)%description))
    call columns%add('takes_constraints', column_integer)
    call columns%add('uses_discrete_gradient', column_integer)
    call columns%add('adaptive', column_integer)
    call columns%add('error_control', column_integer)
    do i = 1, size(entries)
      texts(:, i) = [character(len=status_length) :: entries(i)%name, entries(i)%label, entries(i)%family, &
                     entries(i)%description]
      numbers(:, i) = merge(1.0_real64, 0.0_real64, [entries(i)%takes_constraints, entries(i)%uses_discrete_gradient, &
                                                     entries(i)%adaptive, entries(i)%error_control])
    end do
    call columns%write(file%id, 'integrators', numbers, texts, failure)
  end subroutine write_registry

  ! Results of an earlier run of the same study from its index.h5, if there is one, each given
  ! to this study's case with the same swept values (earlier(c): its row there). A damaged index
  ! (it does not open, or a checksum of its rows or texts fails) is set aside: the journal and
  ! case files rebuild it.
  ! Refused: a finished case that this study does not have (a changed value), or case 1 of the
  ! earlier run given other input than this study gives it (a changed base scene).
  subroutine read_previous_index(self, earlier, notes, failure)
    type(case_index), intent(inout) :: self
    integer, intent(inout) :: earlier(:)
    character(len=:), allocatable, intent(inout) :: notes
    type(failure_type), intent(out) :: failure
    type(failure_type) :: reading, ignored
    type(hdf5_file) :: old
    type(case_lookup) :: by_values
    real(real64), allocatable :: numbers(:, :), parameters(:)
    character(len=status_length), allocatable :: texts(:, :)
    character(len=64), allocatable :: parameter_texts(:)
    character(len=:), allocatable :: first_input
    integer :: c, r, rows, n_numbers, n_texts, n_parameters

    if (.not. file_exists(self%index_path)) return
    call old%open_existing(self%index_path, .false., reading)
    if (.not. reading%failed()) call old%check_texts(self%index_path, reading)
    rows = -1
    if (.not. reading%failed()) rows = table_rows(old%id, 'cases')
    if (.not. reading%failed() .and. rows >= 0) call old%get_text('case_1_input', first_input, reading)
    if (reading%failed() .or. rows < 0) then
      call old%close(ignored)
      call add_note(notes, self%index_path//' cannot be read; it is rebuilt from the journal and the case files')
      return
    end if
    n_numbers = self%columns%numeric_count()
    n_texts = self%columns%text_count()
    allocate (numbers(n_numbers, rows), texts(n_texts, rows))
    call self%columns%read(old%id, 'cases', numbers, texts, reading)
    call old%close(ignored)
    if (reading%failed()) then
      call add_note(notes, self%index_path//' cannot be read (damaged: a checksum fails); it is rebuilt from the '// &
                    'journal and the case files')
      return
    end if
    call values_lookup(self%study, by_values)
    call case_parameters(self%study, 1, parameters, parameter_texts)
    n_parameters = size(parameters)
    do r = 1, rows
      c = find_case(by_values, values_key(numbers(2:n_parameters, r), texts(2:n_texts - 2, r)))
      if (c == 0) then
        if (texts(n_texts - 1, r) /= 'complete') cycle       ! not finished: nothing is lost
        call fail(failure, failure_input, self%index_path//': case '//integer_text(r)//' ('// &
                  row_values(self, numbers(:, r), texts(:, r))//') is complete, but '//self%study%input_file// &
                  ' has no case with these values (a changed or removed value); use another output_dir, or remove '// &
                  'this one to start afresh', self%index_path)
        return
      end if
      if (r == 1) then
        if (namelist_of_run(self%study%cases(c)%config) /= first_input) then
          call fail(failure, failure_input, self%index_path//': its cases ran from another base scene than '// &
                    self%study%base//' now gives (case 1''s input differs); use another output_dir, or remove this '// &
                    'one to start afresh', self%index_path)
          return
        end if
      end if
      self%results(c)%status = texts(n_texts - 1, r)
      self%results(c)%failure_kind = texts(n_texts, r)(1:kind_length)
      ! A figure that is no column (the model has none) is NaN, as the case's run gives it.
      self%results(c)%metrics = ieee_value(1.0_real64, ieee_quiet_nan)
      self%results(c)%metrics(self%shown) = numbers(n_parameters + 1:, r)
      ! An index written before CPU times were recorded reads them as 0: not measured.
      where (.not. self%results(c)%metrics([m_cpu, m_solve_cpu]) > 0) &
        self%results(c)%metrics([m_cpu, m_solve_cpu]) = ieee_value(1.0_real64, ieee_quiet_nan)
      earlier(c) = r
    end do
    if (rows /= size(self%results) .or. any(earlier /= 0 .and. earlier /= [(c, c=1, size(earlier))])) &
      call add_note(notes, 'the sweeps changed since '//self%index_path//' was written: '// &
                    integer_text(count(earlier /= 0))//' of its '//integer_text(rows)//' cases are in this study, ' &
                    //'matched by their swept values')
  end subroutine read_previous_index

  ! Applies the journal's lines (each the latest result of its case) over what index.h5 gave,
  ! each to this study's case with the same overrides. A line that does not parse is skipped; a
  ! complete case that this study does not have is refused, as in read_previous_index.
  subroutine replay_journal(self, by_overrides, earlier, notes, failure)
    type(case_index), intent(inout) :: self
    type(case_lookup), intent(in) :: by_overrides
    integer, intent(inout) :: earlier(:)
    character(len=:), allocatable, intent(inout) :: notes
    type(failure_type), intent(out) :: failure
    type(journal_entry), allocatable :: entries(:)
    integer :: k, c, applied, skipped

    call read_journal(self%journal_path, entries, skipped, failure)
    if (failure%failed()) return
    applied = 0
    do k = 1, size(entries)
      c = find_case(by_overrides, entries(k)%overrides)
      if (c == 0) then
        if (entries(k)%result%status /= 'complete') cycle
        call fail(failure, failure_input, self%journal_path//': case '//integer_text(entries(k)%case_number)//' ('// &
                  entries(k)%overrides//') is complete, but '//self%study%input_file//' has no case with these '// &
                  'values (a changed or removed value); use another output_dir, or remove this one to start afresh', &
                  self%journal_path)
        return
      end if
      self%results(c) = entries(k)%result
      earlier(c) = entries(k)%case_number
      applied = applied + 1
    end do
    if (applied > 0) call add_note(notes, integer_text(applied)//' results taken from '//self%journal_path)
    if (skipped > 0) call add_note(notes, integer_text(skipped)//' damaged lines of '//self%journal_path//' skipped')
  end subroutine replay_journal

  ! An index row's swept values as 'field = value; ...', for messages.
  function row_values(self, numbers, texts) result(text)
    type(case_index), intent(in) :: self
    real(real64), intent(in) :: numbers(:)
    character(len=*), intent(in) :: texts(:)
    character(len=:), allocatable :: text
    character(len=32) :: number
    integer :: i, k, t

    text = ''
    k = 0
    t = 0
    do i = 1, size(self%columns%widths)
      if (self%columns%widths(i) <= 0) then
        k = k + 1
      else
        t = t + 1
      end if
      if (i <= 2) cycle                                   ! case, file
      if (trim(self%columns%names(i)) == 'status') exit
      if (len(text) > 0) text = text//'; '
      if (self%columns%widths(i) <= 0) then
        write (number, '(g0)') numbers(k)
        text = text//trim(self%columns%names(i))//' = '//trim(number)
      else
        text = text//trim(self%columns%names(i))//' = '''//trim(texts(t))//''''
      end if
    end do
  end function row_values

  subroutine add_note(notes, text)
    character(len=:), allocatable, intent(inout) :: notes
    character(len=*), intent(in) :: text

    if (len(notes) > 0) notes = notes//new_line('a')
    notes = notes//text
  end subroutine add_note

end module study_index
