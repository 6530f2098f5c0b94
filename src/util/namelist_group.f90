!> One reader for every namelist group: a group is a table of fields, each bound to the variable
!> that receives it, with what it allows. `read_group` applies the group's items from the file
!> and then any overrides (e.g. a study's sweep values), one item at a time, so that a failing
!> item is known by name, and checks each field against its table entry. Errors come back as a
!> message naming the file (or override), the group, the field and what is allowed. The same
!> tables give --help its lists and the output its attributes.
!>
!> Values are read as Fortran reads list-directed input (repeat counts such as 2*0.5 included);
!> an array takes exactly its number of values, or one value per subscript (theta(2) = 350,
!> p2(1:2) = 2*0.5); texts need quotes; logical values are .true. or .false. (or T, F).
module namelist_group
  use, intrinsic :: iso_fortran_env, only: real64
  use namelist_text, only: namelist_item, group_items, item_name
  use namelist_values, only: read_reals, read_texts, read_integer, read_logical, single_item, parse_subscript
  use number_text, only: integer_text, reals_text
  use failures, only: failure_type, fail, failure_input
  implicit none (type, external)
  private
  public :: group_field, real_field, reals_field, integer_field, logical_field, text_field, texts_field
  public :: read_group, field_names, invalid_value_message, choices_text, field_value_text, value_origin
  public :: describe_group, parse_subscript, absolute_temperature, celsius_suspects, given_origin
  public :: field_real, field_integer, field_logical, field_text, first_outside

  integer, parameter :: field_real = 1, field_integer = 2, field_logical = 3, field_text = 4
  ! What apply_item found wrong with an item.
  integer, parameter :: value_problem = 1, subscript_problem = 2

  !> A field of a group: its name, what it allows (for messages and --help), its units, and the
  !> variable it is read into. Bounds and choices are checked after the group is read.
  type :: group_field
    character(len=24) :: name = ''
    character(len=:), allocatable :: allowed      !! what it allows, for messages and --help
    character(len=16) :: units = ''
    integer :: kind = field_real
    real(real64), pointer :: real_value => null()
    real(real64), pointer :: real_values(:) => null()
    integer, pointer :: integer_value => null()
    logical, pointer :: logical_value => null()
    character(len=:), pointer :: text_value => null()
    character(len=64), pointer :: text_values(:) => null()
    logical :: open_length = .false.              !! an array that takes up to its size of values
    real(real64) :: minimum = -huge(1.0_real64)   !! every value >= minimum (> if exclusive)
    logical :: exclusive = .false.
    real(real64) :: maximum = huge(1.0_real64)    !! every value <= maximum
    logical :: nonzero = .false.                  !! an array that must not be all zero
    logical :: check_equal = .false.              !! a real that must equal `required` (relative 1e-12)
    real(real64) :: required = 0.0_real64
    character(len=:), allocatable :: choices      !! the allowed texts, separated by blanks ('' = any)
    !> A temperature level in kelvin (not a difference): a value below celsius_below K is
    !> more likely degrees Celsius, and the drivers warn.
    logical :: absolute_temperature = .false.
  end type group_field

  real(real64), parameter :: celsius_below = 150.0_real64

contains

  ! ------------------------------------------------------------------ building tables

  !> A real scalar field.
  function real_field(name, variable, allowed, units, minimum, exclusive, maximum) result(field)
    character(len=*), intent(in) :: name, allowed, units
    real(real64), intent(in), target :: variable
    real(real64), intent(in), optional :: minimum, maximum
    logical, intent(in), optional :: exclusive
    type(group_field) :: field

    field = group_field(name=name, allowed=allowed, units=units, kind=field_real)
    field%real_value => variable
    call set_bounds(field, minimum, exclusive)
    if (present(maximum)) field%maximum = maximum
  end function real_field

  !> A real array field; nonzero: not all values may be zero; open_length: it takes up to its
  !> size of values, leaving the rest as they were.
  function reals_field(name, variable, allowed, units, minimum, exclusive, nonzero, open_length) result(field)
    character(len=*), intent(in) :: name, allowed, units
    real(real64), intent(in), target :: variable(:)
    real(real64), intent(in), optional :: minimum
    logical, intent(in), optional :: exclusive, nonzero, open_length
    type(group_field) :: field

    field = group_field(name=name, allowed=allowed, units=units, kind=field_real)
    field%real_values => variable
    call set_bounds(field, minimum, exclusive)
    if (present(nonzero)) field%nonzero = nonzero
    if (present(open_length)) field%open_length = open_length
  end function reals_field

  !> An integer field.
  function integer_field(name, variable, allowed, minimum, maximum) result(field)
    character(len=*), intent(in) :: name, allowed
    integer, intent(in), target :: variable
    integer, intent(in), optional :: minimum, maximum
    type(group_field) :: field

    field = group_field(name=name, allowed=allowed, units='1', kind=field_integer)
    field%integer_value => variable
    if (present(minimum)) field%minimum = real(minimum, real64)
    if (present(maximum)) field%maximum = real(maximum, real64)
  end function integer_field

  !> A logical field.
  function logical_field(name, variable, allowed) result(field)
    character(len=*), intent(in) :: name, allowed
    logical, intent(in), target :: variable
    type(group_field) :: field

    field = group_field(name=name, allowed=allowed, units='', kind=field_logical)
    field%logical_value => variable
  end function logical_field

  !> A text field; choices (blank-separated) are its allowed values, '' for any text.
  function text_field(name, variable, allowed, choices) result(field)
    character(len=*), intent(in) :: name, allowed, choices
    character(len=*), intent(in), target :: variable
    type(group_field) :: field

    field = group_field(name=name, allowed=allowed, units='', kind=field_text)
    field%text_value => variable
    if (len_trim(choices) > 0) field%choices = trim(choices)
  end function text_field

  !> A list of up to size(variable) quoted texts (the rest is left as it was).
  function texts_field(name, variable, allowed) result(field)
    character(len=*), intent(in) :: name, allowed
    character(len=64), intent(in), target :: variable(:)
    type(group_field) :: field

    field = group_field(name=name, allowed=allowed, units='', kind=field_text)
    field%text_values => variable
    field%open_length = .true.
  end function texts_field

  !> The field, marked as a temperature level in kelvin (group_field's absolute_temperature).
  function absolute_temperature(field) result(marked)
    type(group_field), intent(in) :: field
    type(group_field) :: marked

    marked = field
    marked%absolute_temperature = .true.
  end function absolute_temperature

  !> The fields of &group that the input set (file or overrides) and that are temperature levels
  !> below celsius_below K, each as 'origin: &group: name = value K'.
  subroutine celsius_suspects(text, group, fields, origin, suspects, extra)
    character(len=*), intent(in) :: text, group, origin
    type(group_field), intent(in) :: fields(:)
    character(len=400), allocatable, intent(out) :: suspects(:)
    type(namelist_item), intent(in), optional :: extra(:)
    type(namelist_item), allocatable :: items(:)
    integer :: k, i

    allocate (suspects(0))
    call group_items(text, group, field_names(fields), origin, items, extra)
    do k = 1, size(fields)
      if (.not. fields(k)%absolute_temperature) cycle
      if (associated(fields(k)%real_value)) then
        if (fields(k)%real_value >= celsius_below) cycle
      else if (associated(fields(k)%real_values)) then
        if (all(fields(k)%real_values >= celsius_below)) cycle
      else
        cycle
      end if
      do i = size(items), 1, -1
        if (item_name(items(i)%item) /= trim(fields(k)%name)) cycle
        suspects = [character(len=400) :: suspects, items(i)%origin//': &'//group//': '//trim(fields(k)%name)//' = '// &
                    field_value_text(fields(k))//' K looks like degrees Celsius (below '// &
                    reals_text([celsius_below])//' K); temperatures are absolute, in kelvin']
        exit
      end do
    end do
  end subroutine celsius_suspects

  subroutine set_bounds(field, minimum, exclusive)
    type(group_field), intent(inout) :: field
    real(real64), intent(in), optional :: minimum
    logical, intent(in), optional :: exclusive

    if (present(minimum)) field%minimum = minimum
    if (present(exclusive)) field%exclusive = exclusive
  end subroutine set_bounds

  ! ------------------------------------------------------------------ reading

  !> Reads group &group of `text` (and the `extra` items that name its fields) into the fields'
  !> variables and checks them; on the first problem a failure (failure_input) whose message
  !> names the file, group and field and whose origin is the field's name. `origin` is the
  !> file's name, for messages.
  subroutine read_group(text, group, fields, origin, failure, extra, occurrence)
    character(len=*), intent(in) :: text, group, origin
    type(group_field), intent(in) :: fields(:)
    type(failure_type), intent(out) :: failure
    type(namelist_item), intent(in), optional :: extra(:)
    integer, intent(in), optional :: occurrence
    type(namelist_item), allocatable :: items(:)
    character(len=:), allocatable :: reason
    integer :: i, k, problem

    call group_items(text, group, field_names(fields), origin, items, extra, occurrence)
    call check_single_setting(group, fields, items, failure)
    if (failure%failed()) return
    do i = 1, size(items)
      k = field_index(fields, item_name(items(i)%item))
      if (k == 0) then
        call fail(failure, failure_input, items(i)%origin//': &'//group//': unknown field '''// &
                  item_name(items(i)%item)//'''; allowed: '//names_text(fields), item_name(items(i)%item))
        return
      end if
      call apply_item(fields(k), items(i)%item, problem, reason)
      if (problem == subscript_problem) then
        call fail(failure, failure_input, items(i)%origin//': &'//group//': '// &
                  trim(adjustl(items(i)%item(1:index(items(i)%item, '=') - 1)))//': '//reason, trim(fields(k)%name))
        return
      else if (problem /= 0) then
        if (len(reason) > 0) reason = ' ('//reason//')'
        call fail(failure, failure_input, items(i)%origin//': &'//group//': field '''//trim(fields(k)%name)// &
                  ''' cannot take the value '//quoted_value(items(i)%item)//reason//'; allowed: '// &
                  trim(fields(k)%allowed), trim(fields(k)%name))
        return
      end if
    end do
    do k = 1, size(fields)
      if (within_bounds(fields(k))) cycle
      call fail(failure, failure_input, invalid_value_message(origin_of(items, fields(k)%name, origin), group, &
                fields(k)), trim(fields(k)%name))
      return
    end do
  end subroutine read_group

  !> Where &group of `text` (or an `extra` item) sets the field `name` ('' if nowhere): for a
  !> setting that a scene refuses after the group was read.
  function given_origin(text, group, fields, origin, name, extra) result(where)
    character(len=*), intent(in) :: text, group, origin, name
    type(group_field), intent(in) :: fields(:)
    type(namelist_item), intent(in), optional :: extra(:)
    character(len=:), allocatable :: where
    type(namelist_item), allocatable :: items(:)
    integer :: i

    where = ''
    call group_items(text, group, field_names(fields), origin, items, extra)
    do i = 1, size(items)
      if (item_name(items(i)%item) /= name) cycle
      where = items(i)%origin
      return
    end do
  end function given_origin

  !> "origin: &group: field = value is not allowed; allowed: ...", for a field whose value (as it
  !> stands now) breaks a rule of the group.
  function invalid_value_message(origin, group, field) result(message)
    character(len=*), intent(in) :: origin, group
    type(group_field), intent(in) :: field
    character(len=:), allocatable :: message

    integer :: first

    first = 0
    if (field%kind == field_real .and. associated(field%real_values)) then
      if (given_count(field%real_values) > 1) first = first_outside(field, field%real_values)
    end if
    if (first > 0) then
      ! The first value outside its bounds, by its namelist subscript: of 10^5 values one is wrong.
      message = origin//': &'//group//': '//trim(field%name)//'('//integer_text(first)//') = '// &
                reals_text(field%real_values(first:first))//' (value '//integer_text(first)//' of '// &
                integer_text(given_count(field%real_values))//') is not allowed; allowed: '//trim(field%allowed)
    else
      message = origin//': &'//group//': '//trim(field%name)//' = '//field_value_text(field)//' is not allowed; '// &
                'allowed: '//trim(field%allowed)
    end if
  end function invalid_value_message

  ! How many of a reading array's values were given: those before its unset tail (huge()), at
  ! least one.
  pure integer function given_count(values)
    real(real64), intent(in) :: values(:)

    given_count = size(values)
    do while (given_count > 1)
      if (values(given_count) < huge(1.0_real64)) exit
      given_count = given_count - 1
    end do
  end function given_count

  !> The field's value as a user would write it (texts quoted).
  function field_value_text(field) result(text)
    type(group_field), intent(in) :: field
    character(len=:), allocatable :: text

    select case (field%kind)
    case (field_real)
      if (associated(field%real_value)) then
        text = reals_text([field%real_value])
      else
        text = listed_reals(field%real_values)
      end if
    case (field_integer)
      text = integer_text(field%integer_value)
    case (field_logical)
      text = merge('.true. ', '.false.', field%logical_value)
      text = trim(text)
    case default
      if (associated(field%text_value)) then
        text = ''''//trim(field%text_value)//''''
      else
        text = ''''//trim(field%text_values(1))//''', ...'
      end if
    end select
  end function field_value_text

  ! Values of a list as a message quotes them: those given (a reading array's unset tail, huge(),
  ! left out), at most 8 of them and their number beyond that (a chain's 1e5 values).
  function listed_reals(values) result(text)
    real(real64), intent(in) :: values(:)
    character(len=:), allocatable :: text
    integer, parameter :: most = 8
    integer :: given

    given = given_count(values)
    if (given <= most) then
      text = reals_text(values(1:given))
    else
      text = reals_text(values(1:most))//', ... ('//integer_text(given)//' values)'
    end if
  end function listed_reals

  !> The group as --help shows it: '&group', then each field with its default (the value it holds
  !> now; none for a real at huge(), a default that follows from other fields, which its text
  !> gives) and what it allows.
  subroutine describe_group(unit, group, fields)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: group
    type(group_field), intent(in) :: fields(:)
    integer :: k

    write (unit, '(2x, a)') '&'//group
    do k = 1, size(fields)
      write (unit, '(4x, a, t28, a)') trim(fields(k)%name), trim(fields(k)%allowed)
      if (fields(k)%open_length .or. field_value_text(fields(k)) == "''") cycle
      if (fields(k)%kind == field_real .and. associated(fields(k)%real_value)) then
        if (fields(k)%real_value >= huge(1.0_real64)) cycle
      end if
      write (unit, '(t28, a)') 'default: '//field_value_text(fields(k))
    end do
  end subroutine describe_group

  !> The names of a table's fields.
  function field_names(fields) result(names)
    type(group_field), intent(in) :: fields(:)
    character(len=24) :: names(size(fields))

    names = fields%name
  end function field_names

  !> "'a', 'b' or 'c'" from the blank-separated choices "a b c".
  pure function choices_text(choices) result(text)
    character(len=*), intent(in) :: choices
    character(len=:), allocatable :: text
    character(len=:), allocatable :: rest, word
    integer :: count, blank

    text = ''
    rest = trim(adjustl(choices))
    count = 0
    do while (len(rest) > 0)
      blank = index(rest, ' ')
      if (blank == 0) blank = len(rest) + 1
      word = ''''//rest(1:blank - 1)//''''
      rest = trim(adjustl(rest(blank:)))
      count = count + 1
      if (count == 1) then
        text = word
      else if (len(rest) == 0) then
        text = text//' or '//word
      else
        text = text//', '//word
      end if
    end do
  end function choices_text

  ! ------------------------------------------------------------------ helpers

  ! The first pair of items from one origin that set the same variable or element: a field twice
  ! (dt = 0.1, dt = 0.2), an element twice (x(1) = 1, x(1) = 2), an element of an array given
  ! whole and by subscript (theta = 300, 300, theta(2) = 310) or by overlapping ranges (an array
  ! given whole sets every element, also one that takes up to its size of values), or two names
  ! of one field (a field and its old name). Overrides (a study's sweep) come from another origin
  ! and replace the file's value. An item of an unknown field or with a bad subscript is left to
  ! read_group, which says what is wrong with it.
  subroutine check_single_setting(group, fields, items, failure)
    character(len=*), intent(in) :: group
    type(group_field), intent(in) :: fields(:)
    type(namelist_item), intent(in) :: items(:)
    type(failure_type), intent(out) :: failure
    integer :: first(size(items)), last(size(items)), field(size(items))
    character(len=:), allocatable :: element
    integer :: i, j

    do i = 1, size(items)
      call element_range(fields, items(i)%item, field(i), first(i), last(i))
    end do
    do i = 1, size(items)
      if (field(i) == 0) cycle
      do j = i + 1, size(items)
        if (field(j) == 0 .or. items(i)%origin /= items(j)%origin) cycle
        if (field(i) == field(j)) then
          if (max(first(i), first(j)) > min(last(i), last(j))) cycle
          element = setting_key(items(i)%item)
          if (element /= setting_key(items(j)%item)) element = item_name(items(i)%item)//'('// &
                                                               integer_text(max(first(i), first(j)))//')'
          call fail(failure, failure_input, items(i)%origin//': &'//group//': '//element//' is given twice ('// &
                    as_written(items(i)%item)//' and '//as_written(items(j)%item)//'); allowed: each field and '// &
                    'each element once in its group', trim(fields(field(i))%name))
          return
        end if
        if (.not. same_target(fields, item_name(items(i)%item), item_name(items(j)%item))) cycle
        call fail(failure, failure_input, items(i)%origin//': &'//group//': '//item_name(items(i)%item)//' and '// &
                  item_name(items(j)%item)//' set the same field; allowed: one of them', item_name(items(i)%item))
        return
      end do
    end do
  end subroutine check_single_setting

  ! The field an item sets (its index in the table) and the elements first:last it sets (1:1 for
  ! a scalar, every element for an array given whole); field 0 for an unknown field, a subscript
  ! on a scalar, or a subscript that is not one or out of range.
  subroutine element_range(fields, item, field, first, last)
    type(group_field), intent(in) :: fields(:)
    character(len=*), intent(in) :: item
    integer, intent(out) :: field, first, last
    type(failure_type) :: failure
    integer :: equals, open_at

    field = field_index(fields, item_name(item))
    first = 1
    last = 1
    equals = index(item, '=')
    if (field == 0 .or. equals == 0) then
      field = 0
      return
    end if
    if (associated(fields(field)%real_values)) last = size(fields(field)%real_values)
    if (associated(fields(field)%text_values)) last = size(fields(field)%text_values)
    open_at = index(item(1:equals), '(')
    if (open_at == 0) return
    if (.not. associated(fields(field)%real_values)) then
      field = 0
      return
    end if
    call parse_subscript(item(open_at + 1:equals - 1), first, last, failure)
    if (failure%failed()) field = 0
  end subroutine element_range

  ! An item as the file writes it, without the comma that separates it from the next.
  pure function as_written(item) result(text)
    character(len=*), intent(in) :: item
    character(len=:), allocatable :: text

    text = trim(adjustl(item))
    if (len(text) > 0) then
      if (text(len(text):) == ',') text = trim(text(1:len(text) - 1))
    end if
  end function as_written

  ! 'name(subscript)' of an item, lower case and without blanks.
  pure function setting_key(item) result(key)
    character(len=*), intent(in) :: item
    character(len=:), allocatable :: key
    integer :: i, equals

    equals = index(item, '=')
    if (equals == 0) equals = len(item) + 1
    key = ''
    do i = 1, equals - 1
      if (item(i:i) == ' ') cycle
      if (item(i:i) >= 'A' .and. item(i:i) <= 'Z') then
        key = key//achar(iachar(item(i:i)) + 32)
      else
        key = key//item(i:i)
      end if
    end do
  end function setting_key

  ! Whether two different field names of the table are bound to the same variable.
  logical function same_target(fields, name_a, name_b)
    type(group_field), intent(in) :: fields(:)
    character(len=*), intent(in) :: name_a, name_b
    integer :: a, b

    same_target = .false.
    if (name_a == name_b) return
    a = field_index(fields, name_a)
    b = field_index(fields, name_b)
    if (a == 0 .or. b == 0) return
    same_target = associated(fields(a)%real_value, fields(b)%real_value) .or. &
                  associated(fields(a)%real_values, fields(b)%real_values) .or. &
                  associated(fields(a)%integer_value, fields(b)%integer_value) .or. &
                  associated(fields(a)%logical_value, fields(b)%logical_value) .or. &
                  associated(fields(a)%text_value, fields(b)%text_value)
  end function same_target


  ! 'name = 'a', 'b'' for an unquoted value 'a, b': how the item is written with its texts quoted.
  pure function quoted_example(name, value) result(example)
    character(len=*), intent(in) :: name, value
    character(len=:), allocatable :: example
    integer :: start, comma

    example = name//' = '
    start = 1
    do
      comma = index(value(start:), ',')
      if (comma == 0) exit
      example = example//''''//trim(adjustl(value(start:start + comma - 2)))//''', '
      start = start + comma
    end do
    example = example//''''//trim(adjustl(value(start:)))//''''
  end function quoted_example

  ! Applies 'name[(i[:j])] = value' to the field. `problem`: 0, value_problem (the value does not
  ! fit the field) or subscript_problem, which read_group words differently; `reason` says why,
  ! when more than the allowed text helps.
  subroutine apply_item(field, item, problem, reason)
    type(group_field), intent(in) :: field
    character(len=*), intent(in) :: item
    integer, intent(out) :: problem
    character(len=:), allocatable, intent(out) :: reason
    character(len=:), allocatable :: value, text_buffer
    integer :: first, last, equals, open_at, stat
    type(failure_type) :: failure
    real(real64) :: one(1)

    reason = ''
    equals = index(item, '=')
    value = trim(adjustl(item(equals + 1:)))
    if (len(value) > 0) then
      if (value(len(value):len(value)) == ',') value = value(1:len(value) - 1)
    end if
    open_at = index(item(1:equals), '(')
    first = 1
    last = 1
    if (associated(field%real_values)) last = size(field%real_values)
    if (open_at > 0) then
      problem = subscript_problem
      if (.not. associated(field%real_values)) then
        reason = 'field '''//trim(field%name)//''' takes no subscript'
        return
      end if
      call parse_subscript(item(open_at + 1:equals - 1), first, last, failure)
      if (failure%failed()) then
        reason = failure%message//'; '''//trim(field%name)//''' has elements 1 to '// &
                 integer_text(size(field%real_values))
        return
      end if
    end if
    problem = value_problem
    if (len_trim(value) == 0) then
      reason = 'no value'
      return
    end if
    if (associated(field%real_values)) then
      call read_reals(value, field%real_values(first:last), failure, field%open_length)
      call take_outcome()
      return
    end if
    if (associated(field%text_values)) then
      if (index('''"', value(1:1)) == 0) then
        reason = 'texts need quotes: '//quoted_example(trim(field%name), value)
        return
      end if
      call read_texts(value, field%text_values, failure)
      call take_outcome()
      return
    end if
    stat = 0
    select case (field%kind)
    case (field_real)
      one = field%real_value
      call read_reals(value, one, failure)
      if (.not. failure%failed()) field%real_value = one(1)
      call take_outcome()
      return
    case (field_integer)
      call read_integer(value, field%integer_value, failure)
      call take_outcome()
      return
    case (field_logical)
      call read_logical(value, field%logical_value, failure)
      call take_outcome()
      return
    case default
      if (index('''"', value(1:1)) == 0) then
        reason = 'texts need quotes: '//quoted_example(trim(field%name), value)
        return
      end if
      allocate (character(len=len(value)) :: text_buffer)
      read (value, *, iostat=stat) text_buffer
      if (stat == 0 .and. .not. single_item(value)) stat = value_problem
      if (stat == 0 .and. len_trim(text_buffer) > len(field%text_value)) then
        stat = value_problem
        reason = 'longer than '//integer_text(len(field%text_value))//' characters'
      end if
      if (stat == 0) field%text_value = trim(text_buffer)
    end select
    problem = 0
    if (stat /= 0) problem = value_problem

  contains

    ! The value reader's outcome as the problem and its reason.
    subroutine take_outcome()
      problem = 0
      if (.not. failure%failed()) return
      problem = value_problem
      reason = failure%message
    end subroutine take_outcome
  end subroutine apply_item

  ! Whether the field's value keeps its bounds, non-zero rule and choices.
  logical function within_bounds(field)
    type(group_field), intent(in) :: field
    real(real64), allocatable :: values(:)

    within_bounds = .true.
    select case (field%kind)
    case (field_real)
      if (associated(field%real_value)) then
        values = [field%real_value]
      else
        values = field%real_values
      end if
      within_bounds = first_outside(field, values) == 0
      if (field%nonzero) within_bounds = within_bounds .and. norm2(values) > 0.0_real64
    case (field_integer)
      within_bounds = real(field%integer_value, real64) >= field%minimum .and. &
                      real(field%integer_value, real64) <= field%maximum
    case (field_text)
      if (allocated(field%choices)) within_bounds = is_choice(trim(field%text_value), field%choices)
    end select
  end function within_bounds

  ! The first of `values` outside the real field's bounds, each taken alone (its minimum, exclusive
  ! or not, its maximum and its required value), or 0. A loop: a chain's reading arrays hold up to
  ! 3 x 10^5 values, whose mask would be a temporary on the stack.
  pure integer function first_outside(field, values)
    type(group_field), intent(in) :: field
    real(real64), intent(in) :: values(:)
    logical :: inside
    integer :: i

    do i = 1, size(values)
      inside = .true.
      if (field%exclusive) then
        inside = values(i) > field%minimum
      else if (field%minimum > -huge(1.0_real64)) then
        inside = values(i) >= field%minimum
      end if
      if (field%maximum < huge(1.0_real64)) inside = inside .and. values(i) <= field%maximum
      if (field%check_equal) inside = inside .and. abs(values(i) - field%required) <= 1.0e-12_real64*abs(field%required)
      if (.not. inside) then
        first_outside = i
        return
      end if
    end do
    first_outside = 0
  end function first_outside

  ! Whether `word` is one of the blank-separated `choices`.
  pure logical function is_choice(word, choices)
    character(len=*), intent(in) :: word, choices

    is_choice = len(word) > 0 .and. index(' '//choices//' ', ' '//word//' ') > 0
  end function is_choice

  integer function field_index(fields, name)
    type(group_field), intent(in) :: fields(:)
    character(len=*), intent(in) :: name
    integer :: k

    field_index = 0
    do k = 1, size(fields)
      if (fields(k)%name == name) field_index = k
    end do
  end function field_index

  ! 'a, b, c' from the fields' names.
  function names_text(fields) result(list)
    type(group_field), intent(in) :: fields(:)
    character(len=:), allocatable :: list
    integer :: k

    list = trim(fields(1)%name)
    do k = 2, size(fields)
      list = list//', '//trim(fields(k)%name)
    end do
  end function names_text

  ! The value of an item as written, quoted if it is not already.
  function quoted_value(item) result(value)
    character(len=*), intent(in) :: item
    character(len=:), allocatable :: value

    value = trim(adjustl(item(index(item, '=') + 1:)))
    if (len(value) == 0) value = ' '
    if (verify(value(1:1), '''"') /= 0) value = ''''//value//''''
  end function quoted_value

  !> Where the last value of field `name` of group &group came from: the origin of an `extra`
  !> item that sets it, or `origin` (the input file).
  function value_origin(text, group, name, origin, extra) result(where)
    character(len=*), intent(in) :: text, group, name, origin
    type(namelist_item), intent(in), optional :: extra(:)
    character(len=:), allocatable :: where
    type(namelist_item), allocatable :: items(:)

    call group_items(text, group, [character(len=24) :: name], origin, items, extra)
    where = origin_of(items, name, origin)
  end function value_origin

  ! Where the last value of `name` came from: an override's origin, or the input file.
  function origin_of(items, name, input_file) result(origin)
    type(namelist_item), intent(in) :: items(:)
    character(len=*), intent(in) :: name, input_file
    character(len=:), allocatable :: origin
    integer :: i

    origin = input_file
    do i = 1, size(items)
      if (item_name(items(i)%item) == trim(name)) origin = items(i)%origin
    end do
  end function origin_of

end module namelist_group
