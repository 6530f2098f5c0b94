!> The part of pFUnit's `funit` API the project's tests use, for machines without pFUnit
!> (tests/README.md, Unit tests): assertTrue, assertFalse and assertEqual (integers; reals with an
!> absolute tolerance, scalars and arrays) with pFUnit's arguments (message, tolerance, location),
!> anyExceptions, SourceLocation, the base types of parameterized tests (AbstractTestParameter
!> with its toString, ParameterizedTestCase), and what tests/unit/fallback/pf_lite.py's drivers
!> need to run a test and report it. A failed assertion prints pFUnit's kind of report (the test, the location,
!> the message, expected and actual) and marks the running test failed.
module funit
  use, intrinsic :: iso_fortran_env, only: real64, output_unit
  implicit none
  private
  public :: assertTrue, assertFalse, assertEqual, anyExceptions, SourceLocation
  public :: AbstractTestParameter, ParameterizedTestCase
  public :: fallback_start_test, fallback_test_failed

  !> Where an assertion stands in its .pf file.
  type :: SourceLocation
    character(len=256) :: file_name = '<unknown file>'
    integer :: line_number = 0
  end type SourceLocation

  !> A parameter of a parameterized test; toString names it in the test's name.
  type, abstract :: AbstractTestParameter
  contains
    procedure(parameter_text), deferred :: toString
  end type AbstractTestParameter

  !> The test object a parameterized test receives as `this`.
  type :: ParameterizedTestCase
  end type ParameterizedTestCase

  abstract interface
    function parameter_text(this) result(text)
      import :: AbstractTestParameter
      class(AbstractTestParameter), intent(in) :: this
      character(:), allocatable :: text
    end function parameter_text
  end interface

  interface assertEqual
    module procedure equal_integers, equal_integer_arrays, equal_reals, equal_real_arrays, equal_real_matrices
  end interface assertEqual

  character(len=:), allocatable, save :: current_test
  logical, save :: failed = .false.

contains

  !> A new test named `name` begins: no assertion has failed yet.
  subroutine fallback_start_test(name)
    character(len=*), intent(in) :: name

    current_test = name
    failed = .false.
  end subroutine fallback_start_test

  !> Whether an assertion of the running test failed.
  logical function fallback_test_failed()
    fallback_test_failed = failed
  end function fallback_test_failed

  !> Whether an assertion failed (pFUnit's name: the generated code returns from the test then).
  logical function anyExceptions()
    anyExceptions = failed
  end function anyExceptions

  subroutine assertTrue(condition, message, location)
    logical, intent(in) :: condition
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location

    if (.not. condition) call fail('', message, location)
  end subroutine assertTrue

  subroutine assertFalse(condition, message, location)
    logical, intent(in) :: condition
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location

    if (condition) call fail('', message, location)
  end subroutine assertFalse

  subroutine equal_integers(expected, found, message, location)
    integer, intent(in) :: expected, found
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location
    character(len=120) :: detail

    if (expected == found) return
    write (detail, '(a, i0, a, i0)') 'AssertEqual failure: expected <', expected, '>, actual <', found
    call fail(trim(detail)//'>', message, location)
  end subroutine equal_integers

  !> expected(i) == found(i) for every i (compared as reals: exact for the integers of a test).
  subroutine equal_integer_arrays(expected, found, message, location)
    integer, intent(in) :: expected(:), found(:)
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location

    call equal_real_arrays(real(expected, real64), real(found, real64), message=message, location=location)
  end subroutine equal_integer_arrays

  subroutine equal_reals(expected, found, tolerance, message, location)
    real(real64), intent(in) :: expected, found
    real(real64), intent(in), optional :: tolerance
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location

    call equal_real_arrays([expected], [found], tolerance, message, location)
  end subroutine equal_reals

  !> |expected(i) - found(i)| <= tolerance (0 by default) for every i, as pFUnit compares arrays.
  subroutine equal_real_arrays(expected, found, tolerance, message, location)
    real(real64), intent(in) :: expected(:), found(:)
    real(real64), intent(in), optional :: tolerance
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location
    real(real64) :: allowed, difference(size(expected))
    character(len=240) :: detail
    integer :: i

    allowed = 0.0_real64
    if (present(tolerance)) allowed = tolerance
    if (size(expected) /= size(found)) then
      write (detail, '(a, i0, a, i0)') 'ArrayAssertEqual failure: expected size ', size(expected), ', actual size ', &
        size(found)
      call fail(trim(detail), message, location)
      return
    end if
    difference = abs(expected - found)
    do i = 1, size(expected)
      if (difference(i) <= allowed) cycle      ! a NaN difference fails
      write (detail, '(a, es24.16, a, es24.16, a, es11.4, a, es11.4, a, i0, a)') 'ArrayAssertEqual failure: expected <', &
        expected(i), '>, actual <', found(i), '>, difference <', difference(i), '> (greater than tolerance of ', &
        allowed, ') at index [', i, ']'
      call fail(trim(detail), message, location)
      return
    end do
  end subroutine equal_real_arrays

  !> Matrices compared entry by entry, as pFUnit compares them (column-major index in the message).
  subroutine equal_real_matrices(expected, found, tolerance, message, location)
    real(real64), intent(in) :: expected(:, :), found(:, :)
    real(real64), intent(in), optional :: tolerance
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location

    if (any(shape(expected) /= shape(found))) then
      call fail('ArrayAssertEqual failure: the shapes differ', message, location)
      return
    end if
    call equal_real_arrays(reshape(expected, [size(expected)]), reshape(found, [size(found)]), tolerance, message, &
                           location)
  end subroutine equal_real_matrices

  ! Reports a failure of the running test, as pFUnit prints it.
  subroutine fail(detail, message, location)
    character(len=*), intent(in) :: detail
    character(len=*), intent(in), optional :: message
    type(SourceLocation), intent(in), optional :: location
    character(len=32) :: line

    failed = .true.
    write (output_unit, '(a)') 'Failure in: '//current_test
    if (present(location)) then
      write (line, '(i0)') location%line_number
      write (output_unit, '(a)') '  Location: ['//trim(location%file_name)//':'//trim(line)//']'
    else
      write (output_unit, '(a)') '  Location: [<unknown location>]'
    end if
    if (present(message)) write (output_unit, '(a)') '  '//message
    if (len(detail) > 0) write (output_unit, '(a)') '  '//detail
    flush (output_unit)
  end subroutine fail

end module funit
