!> SIGTERM and SIGINT as requests to stop (src/run/signal_flags.c): once handlers are installed,
!> the signal is recorded and the time loop and the ensemble's scheduler stop between two steps,
!> leaving their files marked 'incomplete: interrupted by SIGTERM' (or SIGINT); the drivers then
!> exit with 128 + the signal number, as a shell reports a process killed by it.
module run_signals
  use, intrinsic :: iso_c_binding, only: c_int
  use failures, only: failure_type, fail_on_code
  implicit none (type, external)
  private
  public :: install_interrupt_handlers, interrupting_signal, signal_name

  interface
    function c_install_interrupt_handlers() result(status) bind(c, name='eme_install_interrupt_handlers')
      import :: c_int
      integer(c_int) :: status
    end function c_install_interrupt_handlers
    function c_interrupting_signal() result(number) bind(c, name='eme_interrupting_signal')
      import :: c_int
      integer(c_int) :: number
    end function c_interrupting_signal
    function c_signal_number(which) result(number) bind(c, name='eme_signal_number')
      import :: c_int
      integer(c_int), value :: which
      integer(c_int) :: number
    end function c_signal_number
  end interface

contains

  !> Catches SIGTERM and SIGINT from now on (call after PetscInitialize, which may install
  !> handlers of its own); a failure (failure_library, the C shim's code) if the OS refused.
  subroutine install_interrupt_handlers(failure)
    type(failure_type), intent(out) :: failure

    call fail_on_code(failure, int(c_install_interrupt_handlers()), 'install_interrupt_handlers', &
                      'the OS refused a handler for SIGTERM or SIGINT')
  end subroutine install_interrupt_handlers

  !> The signal number of the first SIGTERM or SIGINT caught, or 0.
  integer function interrupting_signal()
    interrupting_signal = int(c_interrupting_signal())
  end function interrupting_signal

  !> 'SIGTERM' or 'SIGINT' for their numbers, else 'signal N'.
  function signal_name(number) result(name)
    integer, intent(in) :: number
    character(len=:), allocatable :: name
    character(len=12) :: digits

    if (number == int(c_signal_number(0))) then
      name = 'SIGTERM'
    else if (number == int(c_signal_number(1))) then
      name = 'SIGINT'
    else
      write (digits, '(i0)') number
      name = 'signal '//trim(digits)
    end if
  end function signal_name

end module run_signals
