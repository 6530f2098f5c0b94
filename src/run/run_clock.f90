!> A run's clocks (src/run/simulation, src/run/distributed_simulation): wall time by the
!> monotonic clock and the process's CPU time, from the run's start and from its time loop's, and
!> the pacing of progress lines. The CPU clock is Fortran's cpu_time, portable and, in gfortran,
!> getrusage: user and system time of all the process's threads to the microsecond, enough for
!> cases of 0.1 ms and more. It is read inside the wall clock's readings, so that a CPU span lies
!> within its wall span. A processor without a CPU clock (cpu_time negative) gives NaN.
module run_clock
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use run_outcome, only: run_summary
  use number_text, only: integer_text, fixed_text
  implicit none (type, external)
  private
  public :: run_timer

  !> The readings at the run's and the loop's start, and at the last progress line.
  type :: run_timer
    integer(int64) :: start = 0, loop = 0, progress = 0, rate = 1
    real(real64) :: cpu_start = 0.0_real64, cpu_loop = 0.0_real64
  contains
    procedure :: begin
    procedure :: begin_loop
    procedure :: note_times
    procedure :: loop_seconds
    procedure :: progress_due
    procedure :: progress_line
  end type run_timer

contains

  !> The run starts (and, until begin_loop, its loop with it).
  subroutine begin(self)
    class(run_timer), intent(out) :: self

    call system_clock(self%start, self%rate)
    call cpu_time(self%cpu_start)
    self%loop = self%start
    self%progress = self%start
    self%cpu_loop = self%cpu_start
  end subroutine begin

  !> The time loop starts.
  subroutine begin_loop(self)
    class(run_timer), intent(inout) :: self

    call system_clock(self%loop)
    call cpu_time(self%cpu_loop)
  end subroutine begin_loop

  !> The progress line of a run at simulated `time` of `t_end` after `steps` steps: simulated time,
  !> steps, rate and the wall time left; '' unless `interval` seconds passed since the last one.
  function progress_line(self, interval, time, t_end, steps) result(line)
    class(run_timer), intent(inout) :: self
    real(real64), intent(in) :: interval, time, t_end
    integer(int64), intent(in) :: steps
    character(len=:), allocatable :: line
    real(real64) :: elapsed, left

    line = ''
    if (.not. self%progress_due(interval)) return
    elapsed = self%loop_seconds()
    left = elapsed*max(0.0_real64, t_end - time)/max(time, tiny(time))
    line = 't = '//fixed_text(time, 3)//' of '//fixed_text(t_end, 3)//' s, '//integer_text(steps)//' steps, '// &
           integer_text(nint(steps/max(elapsed, tiny(elapsed))))//' steps/s, about '//fixed_text(left, 1)//' s left'
  end function progress_line

  !> The whole run's seconds so far into `summary` (wall and CPU), and the time loop's while it
  !> runs (`in_loop`).
  subroutine note_times(self, summary, in_loop)
    class(run_timer), intent(in) :: self
    type(run_summary), intent(inout) :: summary
    logical, intent(in) :: in_loop
    real(real64) :: cpu_now
    integer(int64) :: now

    call cpu_time(cpu_now)
    call system_clock(now)
    if (in_loop) summary%solve_seconds = real(now - self%loop, real64)/real(self%rate, real64)
    summary%wall_seconds = real(now - self%start, real64)/real(self%rate, real64)
    if (self%cpu_start < 0) then
      summary%cpu_seconds = ieee_value(1.0_real64, ieee_quiet_nan)
      summary%solve_cpu_seconds = summary%cpu_seconds
      return
    end if
    if (in_loop) summary%solve_cpu_seconds = cpu_now - self%cpu_loop
    summary%cpu_seconds = cpu_now - self%cpu_start
  end subroutine note_times

  !> Wall seconds since the time loop started.
  real(real64) function loop_seconds(self)
    class(run_timer), intent(in) :: self
    integer(int64) :: now

    call system_clock(now)
    loop_seconds = real(now - self%loop, real64)/real(self%rate, real64)
  end function loop_seconds

  !> Whether `interval` seconds passed since the last progress line (which this one then is).
  logical function progress_due(self, interval)
    class(run_timer), intent(inout) :: self
    real(real64), intent(in) :: interval
    integer(int64) :: now

    call system_clock(now)
    progress_due = real(now - self%progress, real64) >= interval*real(self%rate, real64)
    if (progress_due) self%progress = now
  end function progress_due

end module run_clock
