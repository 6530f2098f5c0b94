!> Named unit tests, as fortran-lang/test-drive registers them: a test program lists its tests
!> by name, and its command line picks which to run, so that one test can run alone and
!> tests/run_tests.py can run each in a process of its own (a crash then hides nothing else).
!>   test_x            every test, in order
!>   test_x --list     the names, one per line
!>   test_x NAME ...   the named tests only (exit status 2 for a name that is not registered)
module unit_testing
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  use assertions, only: test_suite
  implicit none (type, external)
  private
  public :: unit_test, test_body, run_unit_tests

  abstract interface
    !> One test: its checks report through the suite.
    subroutine test_body(suite)
      import :: test_suite
      type(test_suite), intent(inout) :: suite
    end subroutine test_body
  end interface

  !> A test's name and its body.
  type :: unit_test
    character(len=64) :: name = ''
    procedure(test_body), pointer, nopass :: body => null()
  end type unit_test

contains

  !> Runs the tests the command line asks for (see the module comment), then reports the
  !> counts; the exit status is 1 if a check failed.
  subroutine run_unit_tests(program_name, tests)
    character(len=*), intent(in) :: program_name
    type(unit_test), intent(in) :: tests(:)
    type(test_suite) :: suite
    character(len=256) :: argument
    integer :: i, k
    logical :: found

    suite%name = program_name
    if (command_argument_count() == 0) then
      do k = 1, size(tests)
        call tests(k)%body(suite)
      end do
    else
      call get_command_argument(1, argument)
      if (argument == '--list') then
        do k = 1, size(tests)
          write (output_unit, '(a)') trim(tests(k)%name)
        end do
        return
      end if
      do i = 1, command_argument_count()
        call get_command_argument(i, argument)
        found = .false.
        do k = 1, size(tests)
          if (tests(k)%name /= argument) cycle
          found = .true.
          call tests(k)%body(suite)
        end do
        if (.not. found) then
          write (error_unit, '(a)') program_name//': no test named '''//trim(argument)//'''; --list names them'
          stop 2, quiet=.true.
        end if
      end do
    end if
    call suite%finish()
  end subroutine run_unit_tests

end module unit_testing
