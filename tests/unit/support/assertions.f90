!> A minimal assertion library for the unit-test programs (pFUnit is not installable here).
!> Each check prints one line, "PASS <name>" or "FAIL <name>: got ..., expected ...";
!> tests/run_tests.py counts those lines. `finish` sets the exit status.
module assertions
  use, intrinsic :: iso_fortran_env, only: real64, output_unit
  implicit none (type, external)
  private
  public :: test_suite

  !> Counts of one test program's checks.
  type :: test_suite
    character(len=:), allocatable :: name
    integer :: passed = 0
    integer :: failed = 0
  contains
    procedure :: check_close
    procedure :: check_true
    procedure :: check_equal_int
    procedure :: finish
  end type test_suite

contains

  !> |got - expected| <= atol + rtol |expected|, elementwise; reports the worst entry.
  subroutine check_close(self, name, got, expected, rtol, atol)
    class(test_suite), intent(inout) :: self
    character(len=*), intent(in) :: name
    real(real64), intent(in) :: got(:), expected(:)
    real(real64), intent(in), optional :: rtol, atol
    real(real64) :: r, t, excess(size(got))
    integer :: worst
    character(len=200) :: detail

    r = 0.0_real64
    t = 0.0_real64
    if (present(rtol)) r = rtol
    if (present(atol)) t = atol
    if (size(got) /= size(expected)) then
      write (detail, '(a, i0, a, i0)') 'size ', size(got), ' /= expected size ', size(expected)
      call report(self, name, .false., trim(detail))
      return
    end if
    excess = abs(got - expected) - (t + r*abs(expected))
    worst = maxloc(excess, dim=1)
    if (.not. all(excess <= 0.0_real64)) then   ! also catches NaN
      write (detail, '(a, i0, a, es23.15, a, es23.15, a, es9.2, a, es9.2)') 'entry ', worst, ': got ', &
        got(worst), ', expected ', expected(worst), ', rtol ', r, ', atol ', t
      call report(self, name, .false., trim(detail))
    else
      call report(self, name, .true., '')
    end if
  end subroutine check_close

  !> Passes when `condition` holds; `detail` says what was measured.
  subroutine check_true(self, name, condition, detail)
    class(test_suite), intent(inout) :: self
    character(len=*), intent(in) :: name
    logical, intent(in) :: condition
    character(len=*), intent(in), optional :: detail

    if (present(detail)) then
      call report(self, name, condition, detail)
    else
      call report(self, name, condition, 'condition is false')
    end if
  end subroutine check_true

  !> got == expected for integers.
  subroutine check_equal_int(self, name, got, expected)
    class(test_suite), intent(inout) :: self
    character(len=*), intent(in) :: name
    integer, intent(in) :: got, expected
    character(len=80) :: detail

    write (detail, '(a, i0, a, i0)') 'got ', got, ', expected ', expected
    call report(self, name, got == expected, trim(detail))
  end subroutine check_equal_int

  !> Prints the summary and stops with status 1 if any check failed.
  subroutine finish(self)
    class(test_suite), intent(in) :: self

    write (output_unit, '(a, ": ", i0, " passed, ", i0, " failed")') self%name, self%passed, self%failed
    flush (output_unit)
    if (self%failed > 0) stop 1, quiet=.true.
  end subroutine finish

  subroutine report(self, name, ok, detail)
    class(test_suite), intent(inout) :: self
    character(len=*), intent(in) :: name, detail
    logical, intent(in) :: ok

    if (ok) then
      self%passed = self%passed + 1
      write (output_unit, '("PASS ", a, ": ", a)') self%name, name
    else
      self%failed = self%failed + 1
      write (output_unit, '("FAIL ", a, ": ", a, ": ", a)') self%name, name, detail
    end if
  end subroutine report

end module assertions
