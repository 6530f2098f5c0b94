!> What the time loop needs from an integrator: advance the state by one output step. The
!> structure-preserving schemes (step_solver: one SNES solve per step) and the PETSc TS
!> baselines (ts_integrator) both provide it.
module time_stepper
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: stepper, step_report

  !> How a step went.
  type :: step_report
    logical :: accepted = .false.
    integer :: strategy = 0              !! what found the root (step_solver's strategy_*; 0 for TS)
    integer :: newton_iterations = 0     !! summed over every solve of the step
    integer :: solves = 0                !! SNES solves (continuation stages included), or TS steps taken
    integer :: rejected_roots = 0        !! roots rejected as unphysical, or TS steps rejected
    real(real64) :: scheme_temperature(2) = 0.0_real64  !! the temperatures the step's K0 used
    character(len=:), allocatable :: reason           !! why the step failed (if it did)
    character(len=:), allocatable :: last_rejection   !! why the last rejected root was rejected
  end type step_report

  !> An integrator of the run's unknowns x = (z, multipliers).
  type, abstract :: stepper
  contains
    procedure(advance_interface), deferred :: advance
  end type stepper

  abstract interface
    !> From x_old (at time t_old) to x_new at t_old + dt; `guess` is a predictor the integrator
    !> may use. ierr /= 0 only for a library error; a step that cannot be done is reported.
    subroutine advance_interface(self, x_old, t_old, dt, guess, x_new, report, ierr)
      import :: stepper, step_report, real64
      class(stepper), intent(inout) :: self
      real(real64), intent(in) :: x_old(:), t_old, dt, guess(:)
      real(real64), intent(out) :: x_new(:)
      type(step_report), intent(out) :: report
      integer, intent(out) :: ierr
    end subroutine advance_interface
  end interface

end module time_stepper
