!> Finding an earlier run's case among a study's cases (src/run/study_index, on a restart): by
!> its swept values (an index.h5 row) or its overrides (a journal line, a case file), never by its
!> number, which moves when sweeps grow. Keys are ordered once and searched by bisection.
module study_case_matching
  use, intrinsic :: iso_fortran_env, only: real64
  use study_config, only: study_definition
  use study_case_files, only: case_overrides
  use study_columns, only: case_parameters
  use namelist_text, only: blanked
  implicit none (type, external)
  private
  public :: case_lookup, values_key, values_lookup, overrides_lookup, find_case

  !> Case numbers ordered by a text key (a case's swept values or its overrides), to find a case
  !> of this study from an earlier run's record, whose numbers move when sweeps grow.
  type :: case_lookup
    character(len=:), allocatable :: keys(:)
    integer, allocatable :: order(:)          !! keys(order(i)) ascend
  end type case_lookup

contains

  !> The key of a case's swept values: its numbers exactly, then its texts.
  pure function values_key(numbers, texts) result(key)
    real(real64), intent(in) :: numbers(:)
    character(len=*), intent(in) :: texts(:)
    character(len=:), allocatable :: key
    character(len=32) :: number
    integer :: i

    key = ''
    do i = 1, size(numbers)
      write (number, '(es25.17e3)') numbers(i)
      key = key//trim(adjustl(number))//achar(9)
    end do
    do i = 1, size(texts)
      key = key//trim(texts(i))//achar(9)
    end do
  end function values_key

  !> This study's cases by their swept values (values_key).
  subroutine values_lookup(study, lookup)
    type(study_definition), intent(in) :: study
    type(case_lookup), intent(out) :: lookup
    real(real64), allocatable :: parameters(:)
    character(len=64), allocatable :: parameter_texts(:)
    integer :: c, longest

    longest = 0
    do c = 1, size(study%cases)
      call case_parameters(study, c, parameters, parameter_texts)
      longest = max(longest, len(values_key(parameters(2:), parameter_texts)))
    end do
    allocate (character(len=longest) :: lookup%keys(size(study%cases)))
    do c = 1, size(study%cases)
      call case_parameters(study, c, parameters, parameter_texts)
      lookup%keys(c) = values_key(parameters(2:), parameter_texts)
    end do
    call order_keys(lookup)
  end subroutine values_lookup

  !> This study's cases by their overrides (as the journal and case files hold them, blanked).
  subroutine overrides_lookup(study, lookup)
    type(study_definition), intent(in) :: study
    type(case_lookup), intent(out) :: lookup
    integer :: c, longest

    longest = 0
    do c = 1, size(study%cases)
      longest = max(longest, len(case_overrides(study, c)))
    end do
    allocate (character(len=longest) :: lookup%keys(size(study%cases)))
    do c = 1, size(study%cases)
      lookup%keys(c) = blanked(case_overrides(study, c))
    end do
    call order_keys(lookup)
  end subroutine overrides_lookup

  ! Orders the lookup's keys (a merge sort of their numbers, bottom up).
  subroutine order_keys(lookup)
    type(case_lookup), intent(inout) :: lookup
    integer, allocatable :: merged(:)
    integer :: width, first, middle, last, i, j, k, n

    n = size(lookup%keys)
    lookup%order = [(i, i=1, n)]
    allocate (merged(n))
    width = 1
    do while (width < n)
      do first = 1, n, 2*width
        middle = min(first + width - 1, n)
        last = min(first + 2*width - 1, n)
        i = first
        j = middle + 1
        do k = first, last
          if (j > last) then
            merged(k) = lookup%order(i)
            i = i + 1
          else if (i > middle) then
            merged(k) = lookup%order(j)
            j = j + 1
          else if (llt(lookup%keys(lookup%order(j)), lookup%keys(lookup%order(i)))) then
            merged(k) = lookup%order(j)
            j = j + 1
          else
            merged(k) = lookup%order(i)
            i = i + 1
          end if
        end do
      end do
      lookup%order = merged
      width = 2*width
    end do
  end subroutine order_keys

  !> The case whose key is `key` (binary search), or 0.
  integer function find_case(lookup, key)
    type(case_lookup), intent(in) :: lookup
    character(len=*), intent(in) :: key
    integer :: low, high, middle

    find_case = 0
    if (len_trim(key) > len(lookup%keys)) return
    low = 1
    high = size(lookup%order)
    do while (low <= high)
      middle = (low + high)/2
      if (lookup%keys(lookup%order(middle)) == key) then
        find_case = lookup%order(middle)
        return
      else if (llt(lookup%keys(lookup%order(middle)), key)) then
        low = middle + 1
      else
        high = middle - 1
      end if
    end do
  end function find_case

end module study_case_matching
