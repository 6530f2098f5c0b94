!> The values of namelist items as Fortran reads list-directed input: reals (an exact count, or
!> up to a count), quoted texts, an integer, a logical, each checked to be one item where one is
!> expected, and array subscripts i or i:j within a range. A failure (failure_input) says the text
!> is not such a value (its message the reason where there is more to say, else empty); the group reader (namelist_group) names the
!> field and what it allows.
module namelist_values
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use number_text, only: integer_text
  use failures, only: failure_type, fail, failure_input
  implicit none (type, external)
  private
  public :: read_reals, read_texts, read_integer, read_logical, single_item, parse_subscript

contains

  ! Exactly size(values) values from the text (list-directed), or 1 to size(values) if
  ! open_length; fewer, more, an empty value between commas, NaN and Inf are errors (with the
  ! reason). The text is read twice, into arrays preset to 0 and to 1: an element that differs
  ! was left unassigned by the list.
  subroutine read_reals(text, values, failure, open_length)
    character(len=*), intent(in) :: text
    real(real64), intent(inout) :: values(:)
    type(failure_type), intent(out) :: failure
    logical, intent(in), optional :: open_length
    character(len=:), allocatable :: reason
    real(real64) :: zeros(size(values) + 1), ones(size(values) + 1)
    logical :: assigned(size(values) + 1), open
    integer :: given, stat
    character(len=len(text) + 2) :: ended

    reason = ''
    open = .false.
    if (present(open_length)) open = open_length
    zeros = 0.0_real64
    ones = 1.0_real64
    ended = text//' /'                             ! '/' ends list-directed input early
    read (ended, *, iostat=stat) zeros
    if (stat == 0) read (ended, *, iostat=stat) ones
    if (stat /= 0) then
      call fail(failure, failure_input, '')
      return
    end if
    if (.not. all(ieee_is_finite(zeros))) then
      call fail(failure, failure_input, 'NaN and Inf are not allowed')
      return
    end if
    assigned = abs(zeros - ones) < 0.5_real64
    given = count(assigned)
    if (given > 0 .and. .not. all(assigned(1:given))) then
      reason = 'a value is missing between commas'
    else if (given > size(values)) then
      reason = 'more than '//integer_text(size(values))//' values'
    else if (given == 0) then
      reason = 'no value'
    else if (given < size(values) .and. .not. open) then
      reason = integer_text(size(values))//' values needed, '//integer_text(given)//' given'
    else
      values(1:given) = zeros(1:given)
      return
    end if
    call fail(failure, failure_input, reason)
  end subroutine read_reals

  ! Up to size(values) quoted texts; one more is an error.
  subroutine read_texts(text, values, failure)
    character(len=*), intent(in) :: text
    character(len=64), intent(inout) :: values(:)
    type(failure_type), intent(out) :: failure
    character(len=64) :: probe(size(values) + 1)
    integer :: stat, probe_stat
    character(len=len(text) + 2) :: ended

    ended = text//' /'
    read (ended, *, iostat=stat) values
    if (stat == 0) read (text, *, iostat=probe_stat) probe
    if (stat /= 0 .or. probe_stat == 0) call fail(failure, failure_input, '')
  end subroutine read_texts

  ! One integer.
  subroutine read_integer(text, value, failure)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: value
    type(failure_type), intent(out) :: failure
    integer :: stat

    read (text, *, iostat=stat) value
    if (stat /= 0 .or. .not. single_item(text)) call fail(failure, failure_input, '')
  end subroutine read_integer

  ! One logical.
  subroutine read_logical(text, value, failure)
    character(len=*), intent(in) :: text
    logical, intent(inout) :: value
    type(failure_type), intent(out) :: failure
    integer :: stat

    read (text, *, iostat=stat) value
    if (stat /= 0 .or. .not. single_item(text)) call fail(failure, failure_input, '')
  end subroutine read_logical

  ! Whether the text holds one list item only (a second one makes the field's value wrong).
  logical function single_item(text)
    character(len=*), intent(in) :: text
    character(len=len(text)) :: items(2)
    integer :: stat

    read (text, *, iostat=stat) items
    single_item = stat /= 0
  end function single_item

  !> The subscript 'i)' or 'i:j)' (the text after '('), within first:last, which it narrows to
  !> i:j; a failure (failure_input) with the reason if it is not one or out of range.
  subroutine parse_subscript(text, first, last, failure)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: first, last
    type(failure_type), intent(out) :: failure
    integer :: colon, close_at, lower, upper, stat

    close_at = index(text, ')')
    if (close_at == 0) then
      call fail(failure, failure_input, 'subscript ('//trim(text)//' is not closed')
      return
    end if
    colon = index(text(1:close_at - 1), ':')
    if (colon == 0) then
      read (text(1:close_at - 1), *, iostat=stat) lower
      upper = lower
    else
      read (text(1:colon - 1), *, iostat=stat) lower
      if (stat == 0) read (text(colon + 1:close_at - 1), *, iostat=stat) upper
    end if
    if (stat /= 0) then
      call fail(failure, failure_input, 'subscript ('//text(1:close_at)//' is not i or i:j')
      return
    end if
    if (lower < first .or. upper > last .or. upper < lower) then
      call fail(failure, failure_input, 'subscript ('//text(1:close_at)//' is out of range')
      return
    end if
    first = lower
    last = upper
  end subroutine parse_subscript

end module namelist_values
