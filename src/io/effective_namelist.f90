!> The input a run used, as namelist text: every group and field of eme_run's input (the
!> model's groups, &integrator, &output) with the values after defaults and overrides (a study
!> case's sweep values). Reals are written with the fewest digits that read back to the same
!> number, so that running the text again gives the same run. A field that is another's old
!> name (ts_tolerance) is left out, and so is `tolerance` where the input did not set it and the
!> integrator does not always read it (set, it switches step control on).
module effective_namelist
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use run_config, only: run_configuration, integrator_fields, output_fields
  use namelist_field, only: group_field, field_real, field_integer, field_logical
  use number_text, only: integer_text
  use integrator_registry, only: integrator_entry, find_integrator
  implicit none (type, external)
  private
  public :: namelist_of_run, exact_real_text

  !> A real's text, as exact_real_text last gave it.
  type :: real_text
    integer(int64) :: bits = 0
    character(len=:), allocatable :: text
  end type real_text

  ! exact_real_text's latest answers: a study's cases share most of their values, and finding the
  ! fewest digits takes a formatted write and read per digit (a tenth of a case file's cost).
  integer, parameter :: remembered_count = 128
  type(real_text), save :: remembered(remembered_count)
  integer, save :: next_remembered = 1

contains

  !> The namelist text of `config`: one group per block, one field per line.
  function namelist_of_run(config) result(text)
    type(run_configuration), intent(in), target :: config
    character(len=:), allocatable :: text
    character(len=16), allocatable :: groups(:)
    type(integrator_entry) :: entry
    type(group_field), allocatable :: fields(:)
    logical :: found
    integer :: g

    text = ''
    call config%scene%group_names(groups)
    do g = 1, size(groups)
      text = text//group_text(trim(groups(g)), config%scene%fields(trim(groups(g))))
    end do
    fields = integrator_fields(config)
    call find_integrator(config%integrator%scheme, entry, found)
    if (.not. (config%integrator%tolerance_given .or. entry%adaptive)) &
      fields = pack(fields, fields%name /= 'tolerance' .and. fields%name /= 'ts_tolerance')
    text = text//group_text('integrator', fields)//group_text('output', output_fields(config))
  end function namelist_of_run

  ! '&group' and a line per field, closed by '/'.
  function group_text(group, fields) result(text)
    character(len=*), intent(in) :: group
    type(group_field), intent(in) :: fields(:)
    character(len=:), allocatable :: text
    integer :: k

    text = '&'//group//new_line('a')
    do k = 1, size(fields)
      if (is_alias(fields, k)) cycle
      text = text//'  '//trim(fields(k)%name)//' = '//value_text(fields(k))//new_line('a')
    end do
    text = text//'/'//new_line('a')
  end function group_text

  ! Whether field k sets the same variable as an earlier field of the group (an old name).
  logical function is_alias(fields, k)
    type(group_field), intent(in) :: fields(:)
    integer, intent(in) :: k
    integer :: j

    is_alias = .false.
    do j = 1, k - 1
      if (associated(fields(k)%real_value)) then
        if (associated(fields(k)%real_value, fields(j)%real_value)) is_alias = .true.
      end if
    end do
  end function is_alias

  ! A field's value as namelist input: exact reals, quoted texts (quotes doubled).
  function value_text(field) result(text)
    type(group_field), intent(in) :: field
    character(len=:), allocatable :: text

    select case (field%kind)
    case (field_real)
      if (associated(field%real_value)) then
        text = exact_real_text(field%real_value)
      else
        text = real_list_text(field%real_values)
      end if
    case (field_integer)
      text = integer_text(field%integer_value)
    case (field_logical)
      text = trim(merge('.true. ', '.false.', field%logical_value))
    case default
      text = ''''//doubled_quotes(trim(field%text_value))//''''
    end select
  end function value_text

  !> values as a namelist list, a run of equal values as `r*value` (the namelist's repeat count):
  !> a chain of 10^5 springs at one temperature is `theta = 100000*280.0`. Built in one pass
  !> (joining piece by piece took time like the square of the count: 6.3 s of a 60,000-spring run).
  function real_list_text(values) result(text)
    real(real64), intent(in) :: values(:)
    character(len=:), allocatable :: text
    type(real_text), allocatable :: runs(:)
    integer :: first, last, count, length, at, k

    allocate (runs(size(values)))
    count = 0
    first = 1
    do while (first <= size(values))
      last = first
      do while (last < size(values))
        if (transfer(values(last + 1), 0_int64) /= transfer(values(first), 0_int64)) exit
        last = last + 1
      end do
      count = count + 1
      runs(count)%text = exact_real_text(values(first))
      if (last > first) runs(count)%text = integer_text(last - first + 1)//'*'//runs(count)%text
      first = last + 1
    end do
    length = 2*(count - 1)
    do k = 1, count
      length = length + len(runs(k)%text)
    end do
    allocate (character(len=length) :: text)
    at = 0
    do k = 1, count
      if (k > 1) then
        text(at + 1:at + 2) = ', '
        at = at + 2
      end if
      text(at + 1:at + len(runs(k)%text)) = runs(k)%text
      at = at + len(runs(k)%text)
    end do
  end function real_list_text

  !> x with the fewest significant digits that read back to x: fixed notation for exponents
  !> -3 to 6 (0.15, 280.0), else mantissa and exponent (1.0e-8).
  function exact_real_text(x) result(text)
    real(real64), intent(in) :: x
    character(len=:), allocatable :: text
    integer(int64) :: bits
    integer :: k

    bits = transfer(x, bits)
    do k = 1, remembered_count
      if (.not. allocated(remembered(k)%text)) exit
      if (remembered(k)%bits == bits) then
        text = remembered(k)%text
        return
      end if
    end do
    text = fewest_digits(x)
    remembered(next_remembered)%bits = bits
    remembered(next_remembered)%text = text
    next_remembered = modulo(next_remembered, remembered_count) + 1
  end function exact_real_text

  ! exact_real_text, found digit by digit.
  function fewest_digits(x) result(text)
    real(real64), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=48) :: buffer
    integer :: decimals, exponent, at, low, high

    if (.not. abs(x) > 0.0_real64) then
      text = '0.0'
      return
    end if
    ! The fewest decimals of d.ddd E e (decimals + 1 significant digits) that read back to x: one
    ! (most inputs' values) or by bisection up to 16, which always reads back (more decimals read
    ! back whenever fewer do), 5 tries where counting up took up to 16 (a chain's 10^5 positions).
    low = 1
    high = 16
    if (.not. reads_back(x, low)) then
      low = 2
      do while (low < high)
        decimals = (low + high)/2
        if (reads_back(x, decimals)) then
          high = decimals
        else
          low = decimals + 1
        end if
      end do
    end if
    decimals = low
    write (buffer, '(es40.'//integer_text(decimals)//'e3)') x
    at = index(buffer, 'E')
    read (buffer(at + 1:), *) exponent
    if (exponent >= -3 .and. exponent <= 6) then
      ! The same significant digits in fixed notation: decimals - exponent after the point.
      write (buffer, '(f48.'//integer_text(max(1, decimals - exponent))//')') x
      text = trim(adjustl(buffer))
      ! Zeros the mantissa did not need (0.10 from 1.0e-1), keeping a digit after the point.
      do while (text(len(text):) == '0' .and. text(len(text) - 1:len(text) - 1) /= '.')
        text = text(1:len(text) - 1)
      end do
    else
      text = trim(adjustl(buffer(1:at - 1)))//'e'//integer_text(exponent)
    end if
  end function fewest_digits

  ! Whether x written with `decimals` decimals in scientific notation reads back to x.
  logical function reads_back(x, decimals)
    real(real64), intent(in) :: x
    integer, intent(in) :: decimals
    character(len=48) :: buffer
    real(real64) :: back

    write (buffer, '(es40.'//integer_text(decimals)//'e3)') x
    read (buffer, *) back
    reads_back = .not. abs(back - x) > 0.0_real64
  end function reads_back

  pure function doubled_quotes(text) result(quoted)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: quoted
    integer :: i

    quoted = ''
    do i = 1, len(text)
      quoted = quoted//text(i:i)
      if (text(i:i) == '''') quoted = quoted//''''
    end do
  end function doubled_quotes

end module effective_namelist
