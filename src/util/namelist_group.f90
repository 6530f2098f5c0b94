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
  use namelist_field, only: group_field, field_real, field_integer, field_logical, celsius_below, invalid_value_message, &
                            field_value_text, field_names, within_bounds, field_index, names_text
  implicit none (type, external)
  private
  public :: read_group, value_origin, parse_subscript, celsius_suspects, given_origin

  ! What apply_item found wrong with an item.
  integer, parameter :: value_problem = 1, subscript_problem = 2

contains

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
