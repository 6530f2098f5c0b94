!> The fields of a namelist group's table (src/util/namelist_group reads a group into them): each
!> field's name, what it allows (for messages and --help), its units, the variable it is read
!> into, and its rules (bounds, choices, a temperature level in kelvin); the texts that quote a
!> field's value and its rules (messages, --help).
module namelist_field
  use, intrinsic :: iso_fortran_env, only: real64
  use number_text, only: integer_text, reals_text
  implicit none (type, external)
  private
  public :: group_field, real_field, reals_field, integer_field, logical_field, text_field, texts_field
  public :: field_real, field_integer, field_logical, field_text, celsius_below
  public :: absolute_temperature, invalid_value_message, field_value_text, describe_group, field_names, choices_text
  public :: within_bounds, first_outside, field_index, names_text

  !> A field's kind: the type of the variable it is read into.
  integer, parameter :: field_real = 1, field_integer = 2, field_logical = 3, field_text = 4

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

  subroutine set_bounds(field, minimum, exclusive)
    type(group_field), intent(inout) :: field
    real(real64), intent(in), optional :: minimum
    logical, intent(in), optional :: exclusive

    if (present(minimum)) field%minimum = minimum
    if (present(exclusive)) field%exclusive = exclusive
  end subroutine set_bounds

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

end module namelist_field
