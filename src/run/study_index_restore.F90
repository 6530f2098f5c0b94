!> A study's index opened (src/run/study_index): the earlier runs' results restored from index.h5,
!> its journal and the case files, matched to this study's cases, their files renamed where a case's
!> number moved, and the notes that tell the user what was kept or refused.
!> (A .F90 file: docs/development.md, Modules that grow.)
submodule (study_index) study_index_restore
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use hdf5_files, only: hdf5_file
  use hdf5_table, only: table_rows
  use filesystem, only: make_directories, file_exists, rename_file
  use provenance, only: iso_time
  use effective_namelist, only: namelist_of_run
  use namelist_text, only: blanked
  use study_case_files, only: case_file, case_file_checks_out, read_case_file
  use study_journal, only: journal_entry, read_journal, start_journal
  use study_columns, only: m_steps, m_cpu, m_solve_cpu, choose_metrics, define_columns, case_parameters
  use study_case_matching, only: case_lookup, values_key, values_lookup, overrides_lookup, find_case
  use number_text, only: integer_text
  use failures, only: failure_input
  implicit none

contains

  module procedure open_index
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
  end procedure open_index

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

end submodule study_index_restore
