!> The input of an ensemble study: a &study group naming a base scene (an eme_run namelist)
!> and one &sweep group per swept field, each with a list of numbers (`values`) or of texts
!> (`texts`). The sweeps combine as a Cartesian product (the first sweep varies slowest) or are
!> zipped. Every case is expanded, numbered and validated here, by reading the base scene with
!> the case's overrides exactly as eme_run would, so bad study input fails before any case runs.
module study_config
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_is_nan
  use namelist_text, only: namelist_item, read_source_text, group_names, group_items, lowercase, item_name
  use namelist_field, only: group_field, text_field, reals_field, texts_field, logical_field, integer_field, &
                            invalid_value_message
  use namelist_group, only: read_group, parse_subscript
  use run_config, only: run_configuration, read_run_config, same_variable, field_length
  use integrator_settings, only: step_count
  use number_text, only: integer_text
  use failures, only: failure_type, fail, failure_input
  implicit none (type, external)
  private
  public :: study_definition, study_case, read_study, study_fields, sweep_fields, max_sweep_values

  integer, parameter :: max_sweep_values = 256
  integer, parameter :: max_cases = 100000
  !> The most runs of one case (&study repeats): a timing median needs a few, not millions.
  integer, parameter :: max_repeats = 1000
  !> A study of this many cases or more keeps only its index unless &study index_only says otherwise.
  integer, parameter :: index_only_from = 1000

  !> One swept field and its values, one namelist value text per case ('0.15', '''eme''', or for
  !> an array or a section of `elements` reals, '1.0, 2.0'). The index has a column per element.
  type :: study_sweep
    character(len=:), allocatable :: field
    logical :: textual = .false.
    integer :: elements = 1              !! values per case
    integer :: first_element = 1         !! the subscript of the first (field(i:j): i)
    character(len=256), allocatable :: values(:)
  end type study_sweep

  !> One case: its overrides of the base scene, validated configuration and cost estimate.
  type :: study_case
    integer :: number = 0
    type(namelist_item), allocatable :: overrides(:)
    type(run_configuration) :: config
    real(real64) :: cost = 0.0_real64      !! planned steps, for largest-first order
  end type study_case

  !> The study: where its pieces are, its sweeps and the expanded cases.
  type :: study_definition
    character(len=:), allocatable :: input_file
    character(len=:), allocatable :: base
    character(len=:), allocatable :: output_dir
    character(len=:), allocatable :: combine
    logical :: index_only = .false.      !! keep the index row only, no case files
    integer :: repeats = 1               !! runs of each case; the index holds the median solve time
    type(study_sweep), allocatable :: sweeps(:)
    type(study_case), allocatable :: cases(:)
  end type study_definition

contains

  !> Reads `path`, expands and validates every case; stat /= 0 with a message on bad input.
  subroutine read_study(path, study, failure)
    character(len=*), intent(in) :: path
    type(study_definition), intent(out) :: study
    type(failure_type), intent(out) :: failure
    character(len=:), allocatable :: text
    character(len=32), allocatable :: groups(:)
    integer :: i

    study%input_file = path
    call read_source_text(path, text, failure)
    if (failure%failed()) return
    call group_names(text, groups)
    if (size(groups) == 0) then
      call fail(failure, failure_input, path//': no namelist group found (an empty file, only comments, or not a '// &
                'namelist); allowed groups: &study, &sweep, each written &name field = value, ... /')
      return
    end if
    do i = 1, size(groups)
      if (groups(i) /= 'study' .and. groups(i) /= 'sweep') then
        call fail(failure, failure_input, path//': unknown namelist group &'//trim(groups(i))// &
                  '; allowed groups: &study, &sweep')
        return
      end if
    end do
    if (count(groups == 'study') > 1) then
      call fail(failure, failure_input, path//': &study appears '//integer_text(count(groups == 'study'))// &
                ' times; allowed: one &study group and one &sweep group per swept field')
      return
    end if
    call read_study_group(text, study, failure)
    if (failure%failed()) return
    allocate (study%sweeps(0))
    do i = 1, count(groups == 'sweep')
      call read_sweep_group(text, i, study, failure)
      if (failure%failed()) return
    end do
    call check_collisions(study, failure)
    if (failure%failed()) return
    call expand_cases(study, failure)
    if (failure%failed()) return
    if (size(study%cases) >= index_only_from) then
      if (.not. index_only_given(text, path)) study%index_only = .true.
    end if
  end subroutine read_study

  ! `path` as seen from the folder of `file`: itself if absolute or empty, else the folder's path
  ! and it (a file in the current folder: `path` itself).
  ! The path as a user reads it: no './' segments, no repeated or trailing '/' ('..' is kept: it
  ! need not cancel the folder before it when that is a symbolic link).
  pure function tidy_path(path) result(tidy)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: tidy
    integer :: at

    tidy = path
    do
      at = index(tidy, '//')
      if (at == 0) exit
      tidy = tidy(1:at)//tidy(at + 2:)
    end do
    do
      at = index(tidy, '/./')
      if (at == 0) exit
      tidy = tidy(1:at)//tidy(at + 3:)
    end do
    do while (len(tidy) > 2)
      if (tidy(1:2) /= './') exit
      tidy = tidy(3:)
    end do
    if (len(tidy) > 1) then
      if (tidy(len(tidy):) == '/') tidy = tidy(1:len(tidy) - 1)
    end if
  end function tidy_path

  pure function beside(file, path) result(resolved)
    character(len=*), intent(in) :: file, path
    character(len=:), allocatable :: resolved
    integer :: slash

    resolved = path
    if (len(path) == 0) return
    if (path(1:1) == '/') return
    slash = index(file, '/', back=.true.)
    if (slash > 0) resolved = file(1:slash)//path
  end function beside

  ! Whether &study sets index_only.
  logical function index_only_given(text, path)
    character(len=*), intent(in) :: text, path
    type(namelist_item), allocatable :: items(:)
    integer :: k

    call group_items(text, 'study', [character(len=1) ::], path, items)
    index_only_given = .false.
    do k = 1, size(items)
      if (item_name(items(k)%item) == 'index_only') index_only_given = .true.
    end do
  end function index_only_given

  subroutine read_study_group(text, definition, failure)
    character(len=*), intent(in) :: text
    type(study_definition), intent(inout) :: definition
    type(failure_type), intent(out) :: failure
    character(len=4096), target :: base, output_dir
    character(len=16), target :: combine
    logical, target :: index_only
    integer, target :: repeats
    type(group_field) :: fields(5)
    integer :: slash, dot

    base = ''
    slash = index(definition%input_file, '/', back=.true.)
    dot = index(definition%input_file, '.', back=.true.)
    if (dot <= slash) dot = len(definition%input_file) + 1
    output_dir = 'results/'//definition%input_file(slash + 1:dot - 1)
    combine = 'product'
    index_only = .false.
    repeats = 1
    fields = study_fields(base, output_dir, combine, index_only, repeats)
    call read_group(text, 'study', fields, definition%input_file, failure)
    if (failure%failed()) return
    definition%index_only = index_only
    definition%repeats = repeats
    ! One rule for paths (docs/input.md): a path that names another input file (base) is relative
    ! to the file that names it; an output path (output_dir, and its default) is relative to the
    ! current folder, the run directory, as eme_run's &output file is.
    definition%base = tidy_path(beside(definition%input_file, trim(base)))
    definition%output_dir = tidy_path(trim(output_dir))
    definition%combine = trim(lowercase(combine))
    if (len(definition%base) == 0) then
      call fail(failure, failure_input, definition%input_file//': &study: base is missing; allowed: '//trim(fields(1)%allowed))
    else if (definition%combine /= 'product' .and. definition%combine /= 'zip') then
      call fail(failure, failure_input, invalid_value_message(definition%input_file, 'study', fields(3)))
    else if (len(definition%output_dir) == 0) then
      call fail(failure, failure_input, invalid_value_message(definition%input_file, 'study', fields(2)))
    end if
  end subroutine read_study_group

  subroutine read_sweep_group(text, occurrence, definition, failure)
    character(len=*), intent(in) :: text
    integer, intent(in) :: occurrence
    type(study_definition), intent(inout) :: definition
    type(failure_type), intent(out) :: failure
    character(len=64), target :: field
    real(real64), target :: values(max_sweep_values)
    character(len=64), target :: texts(max_sweep_values)
    type(group_field) :: fields(3)
    type(study_sweep) :: new_sweep
    integer :: i, n

    field = ''
    values = ieee_value(1.0_real64, ieee_quiet_nan)
    texts = ''
    fields = sweep_fields(field, values, texts)
    call read_group(text, 'sweep', fields, definition%input_file, failure, occurrence=occurrence)
    if (failure%failed()) return
    new_sweep%field = trim(lowercase(adjustl(field)))
    if (len(new_sweep%field) == 0) then
      call fail(failure, failure_input, definition%input_file//': &sweep number '//integer_text(occurrence) &
          //': field is missing; allowed: ' &
                //trim(fields(1)%allowed))
      return
    end if
    n = count(.not. ieee_is_nan(values))
    new_sweep%textual = n == 0
    if (new_sweep%textual) n = count(len_trim(texts) > 0)
    if (n == 0 .or. (new_sweep%textual .and. any(len_trim(texts(n + 1:)) > 0)) .or. &
        (.not. new_sweep%textual .and. (any(len_trim(texts) > 0) .or. any(ieee_is_nan(values(1:n)))))) then
      call fail(failure, failure_input, definition%input_file//': &sweep '''//new_sweep%field &
          //''': give either values (numbers) or texts, '// &
                'one list without gaps')
      return
    end if
    if (.not. new_sweep%textual) then
      call sweep_elements(new_sweep, failure)
      if (failure%failed()) then
        failure%message = definition%input_file//': &sweep '''//new_sweep%field//''': '//failure%message
        return
      end if
      if (mod(n, new_sweep%elements) /= 0) then
        call fail(failure, failure_input, definition%input_file//': &sweep '''//new_sweep%field//''': '//integer_text(n) &
            //' values for '// &
                  integer_text(new_sweep%elements)//' elements; allowed: a multiple of '// &
                  integer_text(new_sweep%elements)//', the elements of each case one case after another')
        return
      end if
    end if
    allocate (new_sweep%values(n/new_sweep%elements))
    new_sweep%values = ''
    do i = 1, n
      if (new_sweep%textual .and. is_logical_literal(texts(i))) then
        ! Logical fields (fix_length, fix_temperature) take .true. and .false. unquoted.
        new_sweep%values(i) = trim(adjustl(texts(i)))
      else if (new_sweep%textual) then
        new_sweep%values(i) = ''''//trim(texts(i))//''''
      else
        associate (value => new_sweep%values((i - 1)/new_sweep%elements + 1))
          if (len_trim(value) > 0) value = trim(value)//', '
          value = trim(value)//number_value(values(i))
        end associate
      end if
    end do
    call append_sweep(definition%sweeps, new_sweep)
  end subroutine read_sweep_group

  ! How many values a numeric sweep gives each case: a section field(i:j) j - i + 1, a whole array
  ! its size, anything else 1 (the case's validation refuses what does not fit the field).
  subroutine sweep_elements(sweep, failure)
    type(study_sweep), intent(inout) :: sweep
    type(failure_type), intent(out) :: failure
    integer :: first, last, open_at

    open_at = index(sweep%field, '(')
    if (open_at == 0) then
      sweep%elements = max(1, field_length(sweep%field))
      return
    end if
    first = 1
    last = huge(1)
    call parse_subscript(sweep%field(open_at + 1:), first, last, failure)
    if (failure%failed()) return
    sweep%first_element = first
    sweep%elements = last - first + 1
  end subroutine sweep_elements

  ! A swept number as namelist text: whole numbers as integers, so that integer fields
  ! (newton_max_iterations) take them too.
  function number_value(x) result(text)
    real(real64), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=32) :: buffer

    if (abs(x) < 1.0e15_real64 .and. abs(x - anint(x)) <= 0.0_real64) then
      write (buffer, '(i0)') nint(x, int64)
    else
      write (buffer, '(g0)') x
    end if
    text = trim(buffer)
  end function number_value

  !> The fields of &study, bound to the variables that receive them.
  function study_fields(base, output_dir, combine, index_only, repeats) result(fields)
    character(len=*), intent(in), target :: base, output_dir, combine
    logical, intent(in), target :: index_only
    integer, intent(in), target :: repeats
    type(group_field) :: fields(5)

    fields = [ &
      text_field('base', base, 'the path of an eme_run namelist (the base scene), relative to the study file''s '// &
                 'folder (an input names its inputs relative to itself)', ''), &
      text_field('output_dir', output_dir, 'a directory for the case files and index.h5, relative to the current '// &
                 'folder, as every output path (default results/<study name>)', ''), &
      text_field('combine', combine, "'product' or 'zip' (product: the first sweep varies slowest)", ''), &
      logical_field('index_only', index_only, '.true.: only the index row per case, no case files; .false.: a '// &
                    'case file per case too (default: .false. below '//integer_text(index_only_from)//' cases, '// &
                    '.true. from there)'), &
      integer_field('repeats', repeats, 'an integer from 1 to '//integer_text(max_repeats)//': runs of each case, '// &
                    'timed; the index holds the median solve time (default 1)', minimum=1, maximum=max_repeats)]
  end function study_fields

  !> The fields of &sweep, bound to the variables that receive them.
  function sweep_fields(field, values, texts) result(fields)
    character(len=*), intent(in), target :: field
    real(real64), intent(in), target :: values(:)
    character(len=64), intent(in), target :: texts(:)
    type(group_field) :: fields(3)

    fields = [ &
      text_field('field', field, 'the name of an eme_run namelist field, e.g. ''dt'', ''theta(2)'', an array '// &
                 '''mass'' or a section ''p2(1:2)''', ''), &
      reals_field('values', values, 'up to 256 real numbers; for an array or section of k elements, k per case '// &
                  'one case after another', '', open_length=.true.), &
      texts_field('texts', texts, 'up to 256 quoted texts, e.g. ''eme'', ''midpoint''')]
  end function sweep_fields

  ! Cases that would collide: two sweeps that set the same variable (or overlapping elements of
  ! it: 'theta' and 'theta(2)'; a field and its old name), and a sweep of the output file, which
  ! the study names for each case.
  subroutine check_collisions(study, failure)
    type(study_definition), intent(in) :: study
    type(failure_type), intent(out) :: failure
    integer :: s, t, first(2), last(2)

    do s = 1, size(study%sweeps)
      if (item_name(study%sweeps(s)%field) == 'file') then
        call fail(failure, failure_input, study%input_file//': &sweep ''file'': the study writes each case to '// &
                  'output_dir/case_NNNNN.h5; allowed: any eme_run field but &output file', 'file')
        return
      end if
      do t = 1, s - 1
        if (.not. same_variable(item_name(study%sweeps(s)%field), item_name(study%sweeps(t)%field))) cycle
        call element_range(study%sweeps(t)%field, first(1), last(1))
        call element_range(study%sweeps(s)%field, first(2), last(2))
        if (max(first(1), first(2)) > min(last(1), last(2))) cycle
        call fail(failure, failure_input, study%input_file//': &sweep '''//study%sweeps(t)%field//''' and &sweep '''// &
                  study%sweeps(s)%field//''' set the same value, and the later would overwrite the earlier in every '// &
                  'case; allowed: each field (or array element) in one sweep', study%sweeps(s)%field)
        return
      end do
    end do
  end subroutine check_collisions

  ! The elements first:last that a sweep field 'name', 'name(i)' or 'name(i:j)' sets (all of
  ! them, 1:huge, without a subscript or with one that is not i or i:j, which the case's own
  ! validation refuses).
  subroutine element_range(field, first, last)
    character(len=*), intent(in) :: field
    integer, intent(out) :: first, last
    type(failure_type) :: failure
    integer :: open_at

    first = 1
    last = huge(1)
    open_at = index(field, '(')
    if (open_at == 0) return
    call parse_subscript(field(open_at + 1:), first, last, failure)
    if (.not. failure%failed()) return
    first = 1
    last = huge(1)
  end subroutine element_range

  ! The cases: a Cartesian product (first sweep slowest) or the zip of the sweeps. Each is read
  ! and validated as eme_run would read the base scene with the case's overrides.
  subroutine expand_cases(study, failure)
    type(study_definition), intent(inout) :: study
    type(failure_type), intent(out) :: failure
    integer :: n_sweeps, n_cases, c, s, remainder, pick(max(1, size(study%sweeps)))

    n_sweeps = size(study%sweeps)
    if (n_sweeps == 0) then
      n_cases = 1
    else if (study%combine == 'zip') then
      n_cases = size(study%sweeps(1)%values)
      do s = 2, n_sweeps
        if (size(study%sweeps(s)%values) /= n_cases) then
          call fail(failure, failure_input, study%input_file//': &study: combine = ''zip'' needs sweeps of equal length; '''// &
                    study%sweeps(s)%field//''' differs from '''//study%sweeps(1)%field//'''')
          return
        end if
      end do
    else
      n_cases = 1
      do s = 1, n_sweeps
        if (n_cases > max_cases/size(study%sweeps(s)%values)) then
          call fail(failure, failure_input, study%input_file//': the product of the sweeps has more than 100000 cases')
          return
        end if
        n_cases = n_cases*size(study%sweeps(s)%values)
      end do
    end if
    allocate (study%cases(n_cases))
    do c = 1, n_cases
      ! Which value of each sweep this case takes.
      remainder = c - 1
      do s = n_sweeps, 1, -1
        if (study%combine == 'zip') then
          pick(s) = c
        else
          pick(s) = mod(remainder, size(study%sweeps(s)%values)) + 1
          remainder = remainder/size(study%sweeps(s)%values)
        end if
      end do
      associate (this => study%cases(c))
        this%number = c
        allocate (this%overrides(n_sweeps))
        do s = 1, n_sweeps
          this%overrides(s) = namelist_item(study%sweeps(s)%field//' = '//trim(study%sweeps(s)%values(pick(s))), &
                                            study%input_file//': &sweep '''//study%sweeps(s)%field//'''')
        end do
        call read_run_config(study%base, this%config, failure, this%overrides)
        if (failure%failed()) then
          failure%message = failure%message//' (case '//integer_text(c)//' of the study)'
          return
        end if
        this%cost = real(step_count(this%config%integrator), real64)
      end associate
    end do
  end subroutine expand_cases

  ! sweeps := [sweeps, new_sweep], explicitly (see namelist_text's append).
  subroutine append_sweep(sweeps, new_sweep)
    type(study_sweep), allocatable, intent(inout) :: sweeps(:)
    type(study_sweep), intent(in) :: new_sweep
    type(study_sweep), allocatable :: longer(:)
    integer :: i

    allocate (longer(size(sweeps) + 1))
    do i = 1, size(sweeps)
      call move_alloc(sweeps(i)%field, longer(i)%field)
      call move_alloc(sweeps(i)%values, longer(i)%values)
      longer(i)%textual = sweeps(i)%textual
      longer(i)%elements = sweeps(i)%elements
      longer(i)%first_element = sweeps(i)%first_element
    end do
    longer(size(longer)) = new_sweep
    call move_alloc(longer, sweeps)
  end subroutine append_sweep

  ! Whether a sweep text is a Fortran logical constant.
  pure logical function is_logical_literal(text)
    character(len=*), intent(in) :: text

    is_logical_literal = any(lowercase(trim(adjustl(text))) == [character(len=7) :: '.true.', '.false.'])
  end function is_logical_literal

end module study_config
