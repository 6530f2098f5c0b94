!> The journal of a study's results, output_dir/index.journal: one line per case result,
!> appended whole as the case ends, so that a result counts as recorded before index.h5 is
!> rewritten (src/run/study_index). A line holds the case number, its failure_kind, its metrics,
!> status and overrides, separated by tabs; a line cut short by a kill has no newline and is
!> skipped when the journal is read back; a first line '#' names the study.
module study_journal
  use, intrinsic :: iso_fortran_env, only: real64
  use filesystem, only: remove_file, file_exists, append_text
  use namelist_text, only: blanked
  use number_text, only: integer_text
  use failures, only: failure_type, fail, failure_io
  implicit none (type, external)
  private
  public :: case_result, journal_entry, status_length, kind_length, metric_count
  public :: journal_line, read_journal, start_journal

  integer, parameter :: status_length = 256
  integer, parameter :: kind_length = 16
  integer, parameter :: metric_count = 17
  character(len=1), parameter :: tab = achar(9)

  !> What happened to one case (an index row without its parameters).
  type :: case_result
    character(len=status_length) :: status = 'pending'
    character(len=kind_length) :: failure_kind = 'none'
    real(real64) :: metrics(metric_count) = 0.0_real64
  end type case_result

  !> A line of the journal read back: its case, result and overrides (as written, blanked).
  type :: journal_entry
    integer :: case_number = 0
    type(case_result) :: result
    character(len=:), allocatable :: overrides
  end type journal_entry

contains

  !> Case c's line: case, failure_kind, the metrics, status and overrides, separated by tabs.
  function journal_line(c, result, overrides) result(line)
    integer, intent(in) :: c
    type(case_result), intent(in) :: result
    character(len=*), intent(in) :: overrides
    character(len=:), allocatable :: line
    character(len=32) :: number
    integer :: m

    line = integer_text(c)//tab//trim(result%failure_kind)
    do m = 1, metric_count
      write (number, '(es25.17e3)') result%metrics(m)
      line = line//tab//trim(adjustl(number))
    end do
    line = line//tab//blanked(trim(result%status))//tab//blanked(overrides)//new_line('a')
  end function journal_line

  !> The journal's lines at `path` (none if there is no journal), in order; `skipped` counts the
  !> lines that do not parse (a torn last line). A failure (failure_io) if it cannot be read.
  subroutine read_journal(path, entries, skipped, failure)
    character(len=*), intent(in) :: path
    type(journal_entry), allocatable, intent(out) :: entries(:)
    integer, intent(out) :: skipped
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: text, line
    integer :: unit, size_bytes, start, finish, count, ios
    character(len=256) :: io_message
    logical :: parsed

    skipped = 0
    allocate (entries(0))
    if (.not. file_exists(path)) return
    inquire (file=path, size=size_bytes)
    allocate (character(len=max(0, size_bytes)) :: text)
    open (newunit=unit, file=path, access='stream', form='unformatted', status='old', action='read', &
          iostat=ios, iomsg=io_message)
    if (ios == 0) read (unit, iostat=ios, iomsg=io_message) text
    if (ios == 0) close (unit)
    if (ios /= 0) then
      call fail(failure, failure_io, 'cannot read '//path//': '//trim(io_message), path)
      return
    end if
    deallocate (entries)
    allocate (entries(count_lines(text)))
    count = 0
    start = 1
    do while (start <= len(text))
      finish = index(text(start:), new_line('a'))
      if (finish == 0) then       ! no newline: a line cut short by a kill
        skipped = skipped + 1
        exit
      end if
      line = text(start:start + finish - 2)
      start = start + finish
      if (line(1:min(1, len(line))) == '#') cycle
      call parse_line(line, entries(count + 1), parsed)
      if (.not. parsed) then
        skipped = skipped + 1
        cycle
      end if
      count = count + 1
    end do
    entries = entries(1:count)
  end subroutine read_journal

  !> A fresh journal at `path` whose first line names the study: `header`.
  subroutine start_journal(path, header, failure)
    character(len=*), intent(in) :: path, header
    type(failure_type), intent(out) :: failure

    call remove_file(path, failure)
    if (.not. failure%failed()) call append_text(path, '# '//header//new_line('a'), .false., failure)
  end subroutine start_journal

  ! case, failure_kind, metrics, status, overrides; `parsed` unless the line is cut short or a
  ! number does not read.
  subroutine parse_line(line, entry, parsed)
    character(len=*), intent(in) :: line
    type(journal_entry), intent(out) :: entry
    logical, intent(out) :: parsed
    integer :: field, start, finish, m, stat

    parsed = .false.
    stat = 1
    start = 1
    do field = 1, metric_count + 3
      finish = index(line(start:), tab)
      if (finish == 0) return
      finish = start + finish - 2
      select case (field)
      case (1)
        read (line(start:finish), *, iostat=stat) entry%case_number
      case (2)
        entry%result%failure_kind = line(start:finish)
      case (3:metric_count + 2)
        m = field - 2
        read (line(start:finish), *, iostat=stat) entry%result%metrics(m)
      case default
        entry%result%status = line(start:finish)
      end select
      if (stat /= 0) return
      start = finish + 2
    end do
    entry%overrides = trim(line(start:))
    parsed = .true.
  end subroutine parse_line

  pure integer function count_lines(text)
    character(len=*), intent(in) :: text
    integer :: i

    count_lines = 0
    do i = 1, len(text)
      if (text(i:i) == new_line('a')) count_lines = count_lines + 1
    end do
  end function count_lines

end module study_journal
