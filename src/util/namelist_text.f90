!> Namelist files as text: the whole file without comments, its group names, and a group split
!> into `name = value` items, so that src/util/namelist_group reads each item on its own (a failing
!> item is known by name) and extra items (overrides) can follow the file's.
module namelist_text
  use, intrinsic :: iso_c_binding, only: c_char, c_int, c_long_long, c_null_char
  use number_text, only: integer_text
  use failures, only: failure_type, fail, failure_input, failure_io
  implicit none (type, external)
  private
  public :: namelist_item, read_source_text, group_names, group_items, item_name, lowercase, blanked
  public :: max_input_bytes, joined

  !> The largest input file read: namelists are small, and a wrong file is not read whole.
  integer, parameter :: max_input_bytes = 1048576
  character(len=*), parameter :: name_characters = 'abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_'
  character(len=*), parameter :: syntax = 'groups &name field = value, ... / and comments after !'

  !> One `name = value` item as written, and its origin (the file's name, or e.g. a study's sweep).
  type :: namelist_item
    character(len=:), allocatable :: item
    character(len=:), allocatable :: origin
  end type namelist_item

  interface
    ! src/util/input_file_check.c: 0 and the size of a readable regular file, else -1 and the reason.
    function c_check_input_file(path, size, reason, reason_size) result(status) bind(c, name='eme_check_input_file')
      import :: c_char, c_int, c_long_long
      character(kind=c_char), intent(in) :: path(*)
      integer(c_long_long), intent(out) :: size
      character(kind=c_char), intent(out) :: reason(*)
      integer(c_int), value :: reason_size
      integer(c_int) :: status
    end function c_check_input_file
  end interface

contains

  !> The file's text with comments removed and lines joined by blanks. The file must be a
  !> readable regular file of at most max_input_bytes (a FIFO or a device is refused, not waited
  !> on) holding namelist groups '&name items /' and nothing else. A file without any group comes
  !> back with no group: the caller, who knows the allowed groups, refuses it.
  subroutine read_source_text(path, text, failure)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: text
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: raw, code
    character(len=4096) :: io_message
    character(kind=c_char, len=512) :: reason
    character :: quote
    integer(c_long_long) :: size
    integer :: unit, ios, line_number, start, finish, length, stat
    logical :: group_seen

    text = ''
    reason = ''
    stat = int(c_check_input_file(path//c_null_char, size, reason, len(reason, kind=c_int)))
    if (stat /= 0) then
      call fail(failure, failure_io, path//': cannot read the input file: '//c_text(reason), path)
      return
    end if
    if (size > max_input_bytes) then
      call fail(failure, failure_input, path//': cannot read the input file: it has more than '// &
                integer_text(max_input_bytes)//' bytes; allowed: a namelist file of at most '// &
                integer_text(max_input_bytes)//' bytes', path)
      return
    end if
    ! The whole file at once (its size is known), then line by line.
    allocate (character(len=int(size)) :: raw)
    io_message = ''
    open (newunit=unit, file=path, access='stream', form='unformatted', status='old', action='read', iostat=stat, &
          iomsg=io_message)
    if (stat == 0 .and. size > 0) read (unit, iostat=stat, iomsg=io_message) raw
    if (stat == 0) close (unit, iostat=stat, iomsg=io_message)
    if (stat /= 0) then
      close (unit, iostat=ios)
      call fail(failure, failure_io, path//': cannot read the input file: '//trim(io_message), path)
      return
    end if
    ! A text file holds no control bytes but tabs and line ends: a NUL or other control byte is a
    ! binary file or a damaged one, never silently read as a blank.
    stat = control_byte_at(raw)
    if (stat /= 0) then
      call fail(failure, failure_input, path//': line '// &
                integer_text(count([(raw(start:start) == achar(10), start = 1, stat - 1)]) + 1)//': byte '// &
                integer_text(stat)//' is the control character '//integer_text(iachar(raw(stat:stat)))// &
                '; allowed: a text file (printable characters, tabs and line ends)', path)
      return
    end if
    text = repeat(' ', len(raw) + 1)      ! each line adds a blank, each newline goes
    length = 0
    line_number = 0
    group_seen = .false.
    start = 1
    do while (start <= len(raw))
      finish = index(raw(start:), achar(10)) + start - 2
      if (finish < start - 1) finish = len(raw)
      line_number = line_number + 1
      code = trim(without_comment(blanked(raw(start:finish))))
      text(length + 1:length + 1 + len(code)) = ' '//code
      length = length + 1 + len(code)
      ! An open quote is a group's error; text before any group is refused as such below.
      group_seen = group_seen .or. index(code, '&') > 0
      quote = ' '
      if (group_seen) quote = open_quote(code)
      if (quote /= ' ') then
        call fail(failure, failure_input, path//': line '//integer_text(line_number)//': '// &
                  last_group(text(1:length))//'a text opened by '//quote//' is not closed on its line; allowed: '// &
                  syntax, path)
        return
      end if
      start = finish + 2
    end do
    text = text(1:length)
    call check_groups(text, path, failure)
  end subroutine read_source_text

  ! The position of the first control byte other than tab, line feed, form feed and carriage
  ! return (0 if none).
  pure integer function control_byte_at(raw)
    character(len=*), intent(in) :: raw
    integer :: i, code

    control_byte_at = 0
    do i = 1, len(raw)
      code = iachar(raw(i:i))
      if (code >= 32 .or. code == 9 .or. code == 10 .or. code == 12 .or. code == 13) cycle
      control_byte_at = i
      return
    end do
  end function control_byte_at

  !> A line with its control characters (tab, newline, carriage return) as blanks.
  pure function blanked(line) result(clean)
    character(len=*), intent(in) :: line
    character(len=len(line)) :: clean
    integer :: i

    clean = line
    do i = 1, len(line)
      if (iachar(line(i:i)) < 32) clean(i:i) = ' '
    end do
  end function blanked

  ! The quote character of a text left open at the end of `code` (' ' if none).
  pure function open_quote(code) result(quote)
    character(len=*), intent(in) :: code
    character :: quote
    integer :: i

    quote = ' '
    do i = 1, len(code)
      if (quote /= ' ') then
        if (code(i:i) == quote) quote = ' '
      else if (code(i:i) == '''' .or. code(i:i) == '"') then
        quote = code(i:i)
      end if
    end do
  end function open_quote

  ! '&name: ' for the last group opened in the text (outside quotes), '' if none.
  function last_group(text) result(prefix)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: prefix
    character(len=32), allocatable :: names(:)

    call group_names(text, names)
    prefix = ''
    if (size(names) > 0) prefix = '&'//trim(names(size(names)))//': '
  end function last_group

  ! Checks that the text is a sequence of groups '&name items /' and nothing else: no text
  ! outside a group (a group whose '&' was forgotten), every group closed by '/' outside quotes
  ! before the next '&', and no '/' inside a value or right after '=' (an unquoted path, file =
  ! results/x.h5 or file = /tmp/x.h5, would close the group there).
  subroutine check_groups(text, path, failure)
    character(len=*), intent(in) :: text, path
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: name
    character :: quote
    integer :: i, j, name_end, closed, last

    i = 1
    do
      do while (i <= len(text))
        if (text(i:i) /= ' ') exit
        i = i + 1
      end do
      if (i > len(text)) exit
      if (text(i:i) /= '&') then
        call fail(failure, failure_input, path//': text outside any namelist group: '''//excerpt(text(i:))// &
                  ''' (was a group''s ''&'' forgotten?); allowed: '//syntax, path)
        return
      end if
      name_end = i + verify(text(i + 1:)//' ', name_characters) - 1
      name = lowercase(text(i + 1:name_end))
      if (len(name) == 0) then
        call fail(failure, failure_input, path//': ''&'' without a group name at '''//excerpt(text(i:))// &
                  '''; allowed: '//syntax, path)
        return
      end if
      closed = 0
      quote = ' '
      do j = name_end + 1, len(text)
        if (quote /= ' ') then
          if (text(j:j) == quote) quote = ' '
        else if (text(j:j) == '''' .or. text(j:j) == '"') then
          quote = text(j:j)
        else if (text(j:j) == '&') then
          call fail(failure, failure_input, path//': &'//name//' is not closed by ''/'' before '''// &
                    excerpt(text(j:))//'''; allowed: '//syntax, path)
          return
        else if (text(j:j) == '/') then
          closed = j
          exit
        end if
      end do
      if (quote /= ' ') then
        call fail(failure, failure_input, path//': &'//name//': a text opened by '//quote// &
                  ' is not closed; allowed: '//syntax, path)
        return
      else if (closed == 0) then
        call fail(failure, failure_input, path//': &'//name//' is not closed by ''/''; allowed: '//syntax, path)
        return
      end if
      if (index(' &', text(closed + 1:min(closed + 1, len(text)))) == 0) then
        call refuse_unquoted_path(text(name_end + 1:closed - 1), text(closed:))
        return
      end if
      last = name_end + len_trim(text(name_end + 1:closed - 1))
      if (text(last:last) == '=') then
        call fail(failure, failure_input, path//': &'//name//': field '''// &
                  item_name(last_name(text(name_end + 1:last)))//''' has no value '// &
                  'before the ''/'' that closes the group; texts need quotes, as in file = ''results/x.h5''', path)
        return
      end if
      i = closed + 1
    end do

  contains

    ! The '/' closing the group is followed by more of a word: the last item's value is an
    ! unquoted path whose first '/' ended the group ('results/x.h5' or '/tmp/x.h5').
    subroutine refuse_unquoted_path(body, rest)
      character(len=*), intent(in) :: body, rest
      character(len=:), allocatable :: field, value
      integer :: equals, k

      equals = 0
      do k = 1, len(body)
        if (body(k:k) == '=' .and. .not. quoted_at(body, k)) equals = k
      end do
      value = trim(adjustl(body(equals + 1:)))//rest(1:scan(rest//' ', ' ,') - 1)
      if (equals == 0) then
        call fail(failure, failure_input, path//': &'//name//': '''//excerpt(value)//''' is not a field = value ' &
                  //'item; allowed: '//syntax, path)
        return
      end if
      field = item_name(last_name(body(1:equals)))
      call fail(failure, failure_input, path//': &'//name//': field '''//field//''' has the unquoted value '// &
                value//', whose ''/'' closes the group; texts need quotes: '//field//' = '''//value//'''', path)
    end subroutine refuse_unquoted_path
  end subroutine check_groups

  ! 'name =' at the end of a group body.
  pure function last_name(body) result(item)
    character(len=*), intent(in) :: body
    character(len=:), allocatable :: item
    integer :: start

    start = len_trim(body(1:len(body) - 1))
    start = scan(body(1:start), ' ,', back=.true.)
    item = body(start + 1:)
  end function last_name

  ! The start of a text, for messages: at most 40 characters, the unprintable ones as '?'.
  pure function excerpt(text) result(short)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: short
    integer :: i

    short = trim(text(1:min(len(text), 40)))
    do i = 1, len(short)
      if (iachar(short(i:i)) < 32 .or. iachar(short(i:i)) > 126) short(i:i) = '?'
    end do
    if (len_trim(text) > 40) short = short//'...'
  end function excerpt

  ! The text of a C string buffer, up to its NUL.
  pure function c_text(buffer) result(text)
    character(len=*), intent(in) :: buffer
    character(len=:), allocatable :: text
    integer :: nul

    nul = index(buffer, c_null_char)
    if (nul == 0) nul = len_trim(buffer) + 1
    text = buffer(1:nul - 1)
  end function c_text

  !> Lower-case names of every group '&name' in the text, in order (outside quotes).
  subroutine group_names(text, names)
    character(len=*), intent(in) :: text
    character(len=32), allocatable, intent(out) :: names(:)
    integer :: i, last

    allocate (names(0))
    do i = 1, len(text)
      if (text(i:i) /= '&' .or. quoted_at(text, i)) cycle
      last = i + verify(text(i + 1:)//' ', name_characters) - 1
      names = [names, lowercase(text(i + 1:last))]
    end do
  end subroutine group_names

  !> The items of the `occurrence`-th group &group in the text (first by default), followed by
  !> the `extra` items whose names are among `names`. `origin` names where the file's came from.
  subroutine group_items(text, group, names, origin, items, extra, occurrence)
    character(len=*), intent(in) :: text, group, origin
    character(len=*), intent(in) :: names(:)
    type(namelist_item), allocatable, intent(out) :: items(:)
    type(namelist_item), intent(in), optional :: extra(:)
    integer, intent(in), optional :: occurrence
    character(len=:), allocatable :: body
    integer :: start, finish, next, i

    allocate (items(0))
    call group_body(text, group, body, occurrence)
    start = 1
    do while (start <= len(body))
      call next_item(body, start, finish, next)
      if (finish < start) exit
      call append(items, body(start:finish), origin)
      start = next
    end do
    if (.not. present(extra)) return
    do i = 1, size(extra)
      if (any(names == item_name(extra(i)%item))) call append(items, extra(i)%item, extra(i)%origin)
    end do
  end subroutine group_items

  ! items := [items, the item] (explicit, as gfortran 12 mishandles array constructors of
  ! types with allocatable character components).
  subroutine append(items, item, origin)
    type(namelist_item), allocatable, intent(inout) :: items(:)
    character(len=*), intent(in) :: item, origin
    type(namelist_item), allocatable :: longer(:)
    integer :: i

    allocate (longer(size(items) + 1))
    do i = 1, size(items)
      call move_alloc(items(i)%item, longer(i)%item)
      call move_alloc(items(i)%origin, longer(i)%origin)
    end do
    longer(size(longer))%item = item
    longer(size(longer))%origin = origin
    call move_alloc(longer, items)
  end subroutine append

  !> The field name of an item 'name[(...)] = value', in lower case.
  pure function item_name(item) result(name)
    character(len=*), intent(in) :: item
    character(len=:), allocatable :: name
    integer :: stop_at

    stop_at = scan(item, '=(')
    if (stop_at == 0) stop_at = len(item) + 1
    name = trim(lowercase(adjustl(item(1:stop_at - 1))))
  end function item_name

  !> The names, trimmed, with `separator` between them ('a, b, c' for ', ').
  pure function joined(names, separator) result(text)
    character(len=*), intent(in) :: names(:), separator
    character(len=:), allocatable :: text
    integer :: i

    text = ''
    if (size(names) > 0) text = trim(names(1))
    do i = 2, size(names)
      text = text//separator//trim(names(i))
    end do
  end function joined

  !> ASCII lower case.
  pure function lowercase(text) result(lower)
    character(len=*), intent(in) :: text
    character(len=len(text)) :: lower
    integer :: i, code

    lower = text
    do i = 1, len(text)
      code = iachar(text(i:i))
      if (code >= iachar('A') .and. code <= iachar('Z')) lower(i:i) = achar(code + 32)
    end do
  end function lowercase

  ! ------------------------------------------------------------------ scanning

  ! The text between the occurrence-th '&group' and its closing '/' (outside quotes); '' if absent.
  subroutine group_body(text, group, body, occurrence)
    character(len=*), intent(in) :: text, group
    character(len=:), allocatable, intent(out) :: body
    integer, intent(in), optional :: occurrence
    integer :: i, start, wanted, found

    body = ''
    wanted = 1
    if (present(occurrence)) wanted = occurrence
    found = 0
    start = 0
    do i = 1, len(text) - len(group)
      if (text(i:i) /= '&' .or. quoted_at(text, i)) cycle
      if (lowercase(text(i + 1:i + len(group))) /= group) cycle
      if (i + len(group) < len(text)) then
        if (verify(text(i + len(group) + 1:i + len(group) + 1), ' /') /= 0) cycle
      end if
      found = found + 1
      if (found == wanted) then
        start = i + len(group) + 1
        exit
      end if
    end do
    if (start == 0) return
    do i = start, len(text)
      if (text(i:i) == '/' .and. .not. quoted_at(text, i)) then
        body = text(start:i - 1)
        return
      end if
    end do
    body = text(start:)
  end subroutine group_body

  ! The next item 'name[(...)] = values' of a group body starting at `start`: it ends where the
  ! next 'name =' begins (outside quotes). Returns finish < start when no item is left.
  subroutine next_item(body, start, finish, next)
    character(len=*), intent(in) :: body
    integer, intent(inout) :: start
    integer, intent(out) :: finish, next
    integer :: i, equals

    do while (start <= len(body))
      if (index(' ,', body(start:start)) == 0) exit
      start = start + 1
    end do
    finish = start - 1
    next = len(body) + 1
    if (start > len(body)) return
    equals = index(body(start:), '=')
    if (equals == 0) then
      finish = len_trim(body)
      return
    end if
    equals = start + equals - 1
    do i = equals + 1, len(body)
      if (body(i:i) /= '=' .or. quoted_at(body, i)) cycle
      ! back up over the name (and any subscript) in front of this '='
      next = i - 1
      do while (next > equals .and. body(next:next) == ' ')
        next = next - 1
      end do
      if (body(next:next) == ')') next = index(body(1:next), '(', back=.true.) - 1
      do while (next > equals .and. index(' ,', body(next:next)) == 0)
        next = next - 1
      end do
      finish = next
      next = next + 1
      return
    end do
    finish = len_trim(body)
  end subroutine next_item

  ! Whether position i of the text lies inside a quoted string.
  pure logical function quoted_at(text, i)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    integer :: j
    character :: quote

    quoted_at = .false.
    quote = ' '
    do j = 1, i - 1
      if (quoted_at) then
        if (text(j:j) == quote) quoted_at = .false.
      else if (text(j:j) == '''' .or. text(j:j) == '"') then
        quoted_at = .true.
        quote = text(j:j)
      end if
    end do
  end function quoted_at

  ! A line without its '!' comment (a '!' inside quotes is kept).
  pure function without_comment(line) result(code)
    character(len=*), intent(in) :: line
    character(len=len(line)) :: code
    integer :: i

    code = line
    do i = 1, len_trim(line)
      if (line(i:i) == '!' .and. .not. quoted_at(line, i)) then
        code(i:) = ''
        return
      end if
    end do
  end function without_comment

end module namelist_text
