!> The time loop, one for both paths (src/run/run_paths): the dense run (src/run/simulation) and
!> the run split over MPI ranks (src/run/distributed_simulation) set up their path, hand it to
!> run_time_loop, and close the run when it returns (docs/architecture.md, The time loop).
module time_loop
  use run_paths, only: run_path, step_taken
  use run_outcome, only: failure_library
  use time_loop_steps, only: land_step, fail_step, note_petsc_error
  implicit none (type, external)
  private
  public :: run_time_loop

contains

  !> Steps `path` until its last step (path%finished) or until a step ends the run: the stop rules
  !> agreed at the top of every step, the step, a library's failure or a step without a root, a
  !> step that breaks a balance, output that cannot be written. Integrators on the output grid
  !> take steps_planned steps to n dt (at least one: the input refuses dt > t_end); those that
  !> choose their times go on until they reach t_end (the last step lands on it), or until the step
  !> budget (&integrator max_steps) is spent.
  subroutine run_time_loop(path)
    class(run_path), intent(inout) :: path
    type(step_taken) :: taken

    call path%timer%begin_loop()
    path%finished = .false.
    do while (.not. path%finished)
      if (path%agree_to_stop()) exit
      path%n = path%n + 1
      call path%take_step(taken)
      if (taken%library_failed) then
        call path%fail(failure_library, 'PETSc failed during the solve: '//taken%library_text)
        call note_petsc_error(path%summary, path%n)
        exit
      end if
      call land_step(taken%chose_time, taken%reached, path%n, path%dt, path%t_end, path%summary%steps_planned, &
                     path%time, path%finished)
      if (.not. taken%accepted) then
        call fail_step(path%summary, path%n, path%time, taken%reason)
        exit
      end if
      if (.not. path%step_stands()) exit
      call path%accept_step()
      call path%record_row()
      if (.not. path%output_held()) exit
      call path%report_progress()
    end do
  end subroutine run_time_loop

end module time_loop
