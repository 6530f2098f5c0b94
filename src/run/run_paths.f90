!> What the one time loop (src/run/time_loop) asks of a run's path: the dense path's state in one
!> process (src/run/dense_run_path) or the split path's, a model's system spread over the ranks of
!> a communicator (src/run/split_run_path). The loop's own variables (the step count, the time, the
!> summary it fills, the failure it records) are the path's components; the deferred bindings are
!> what differs between the paths, each one named step of the loop (docs/architecture.md, The
!> time loop).
module run_paths
  use, intrinsic :: iso_fortran_env, only: real64, int64
  use run_config, only: run_configuration
  use run_outcome, only: run_summary
  use run_clock, only: run_timer
  use time_loop_steps, only: run_observer, line_reporter, record_failure
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: run_path, step_taken

  real(real64), parameter :: progress_interval = 2.0_real64   !! seconds between progress lines

  !> What one step's solve came to, as the loop judges it alike on both paths.
  type :: step_taken
    logical :: library_failed = .false.          !! the library failed (not the method)
    character(len=:), allocatable :: library_text   !! the library's words for it
    logical :: chose_time = .false.               !! the integrator chose the step's end
    real(real64) :: reached = 0.0_real64          !! the time it reached (if it chose it)
    logical :: accepted = .false.                 !! the step has a root
    character(len=:), allocatable :: reason       !! why not, if it has none
  end type step_taken

  !> A run's path through the time loop. The set-up (src/run/simulation, distributed_simulation)
  !> points `config`, `summary` and `failure` at its own and, where wanted, `observer` (called
  !> after every accepted step) and `progress` (receives a progress line at most every 2 s).
  type, abstract :: run_path
    type(run_configuration), pointer :: config => null()
    type(run_summary), pointer :: summary => null()
    type(failure_type), pointer :: failure => null()
    class(run_observer), pointer :: observer => null()
    procedure(line_reporter), pointer, nopass :: progress => null()
    type(run_timer) :: timer
    integer(int64) :: n = 0                !! steps taken (accepted)
    real(real64) :: time = 0.0_real64      !! the time the last accepted step reached
    real(real64) :: dt = 0.0_real64        !! &integrator dt
    real(real64) :: t_end = 0.0_real64     !! &integrator t_end
    logical :: finished = .false.          !! the last step was the run's last
  contains
    procedure(stop_rule), deferred :: agree_to_stop
    procedure(stepping), deferred :: take_step
    procedure(judging), deferred :: step_stands
    procedure(acting), deferred :: accept_step
    procedure(acting), deferred :: record_row
    procedure(judging), deferred :: output_held
    procedure :: fail
    procedure :: report_progress
  end type run_path

  abstract interface
    !> Whether the run stops before its next step (every rank of a split run alike), with the
    !> summary's status and failure kind saying why.
    logical function stop_rule(self) result(stop)
      import :: run_path
      class(run_path), intent(inout) :: self
    end function stop_rule

    !> Takes step self%n (counted already) from the state of the last: what its solve came to.
    subroutine stepping(self, taken)
      import :: run_path, step_taken
      class(run_path), intent(inout) :: self
      type(step_taken), intent(out) :: taken
    end subroutine stepping

    !> A judgement of the step or its output: .false. ends the run (the summary or failure says why).
    logical function judging(self) result(goes_on)
      import :: run_path
      class(run_path), intent(inout) :: self
    end function judging

    !> One step of the loop that cannot end the run.
    subroutine acting(self)
      import :: run_path
      class(run_path), intent(inout) :: self
    end subroutine acting
  end interface

contains

  !> Records a failure that is not the method's (the first one wins) with its message, the input
  !> file as its origin.
  subroutine fail(self, kind, text)
    class(run_path), intent(inout) :: self
    character(len=*), intent(in) :: kind, text

    call record_failure(self%failure, self%summary, kind, text, self%config%input_file)
  end subroutine fail

  !> After an accepted step: the observer's turn, then a progress line when one is due.
  subroutine report_progress(self)
    class(run_path), intent(inout) :: self
    character(len=:), allocatable :: line

    if (associated(self%observer)) call self%observer%after_step()
    if (.not. associated(self%progress)) return
    line = self%timer%progress_line(progress_interval, self%time, self%t_end, self%n)
    if (len(line) > 0) call self%progress(line)
  end subroutine report_progress

end module run_paths
