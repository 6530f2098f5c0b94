!> A study's workers (src/run/ensemble): each rank asks rank 0 for its next case while it runs one,
!> and runs a case as eme_run would, on one process (rank 0's cases too, between serving requests).
!> (A .F90 file: docs/development.md, Modules that grow.)
submodule (ensemble) ensemble_workers
  use mpi_f08, only: MPI_COMM_SELF, MPI_Send, MPI_Recv, MPI_Irecv, MPI_Wait, MPI_Request, &
                     MPI_DOUBLE_PRECISION, MPI_CHARACTER, MPI_STATUS_IGNORE
  use study_index, only: status_length, kind_length
  use study_case_files, only: case_file, case_overrides
  use run_config, only: run_configuration
  use run_outcome, only: failure_interrupted
  use run_signals, only: interrupting_signal
  use simulation, only: run_summary, run_simulation, extra_attribute
  use distributed_simulation, only: run_distributed, split_run_wanted
  use statistics, only: median
  implicit none

contains

  module procedure work
    type(case_result) :: result
    class(time_stepper), allocatable :: integrator
    type(file_template), target :: template     !! the root attributes of the rank's case files
    type(MPI_Request) :: asked
    real(real64) :: message(message_length)
    character(len=status_length + kind_length) :: texts
    integer :: current(1), next(1)
    type(failure_type) :: release_failure

    message = 0.0_real64
    texts = ''
    call request(message, texts)
    call MPI_Recv(current, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
    if (current(1) /= 0) then
      call request(message, texts)
      call MPI_Irecv(next, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, asked)
    end if
    do while (current(1) /= 0)
      call run_case(study, current(1), rank, result, integrator, template)
      call MPI_Wait(asked, MPI_STATUS_IGNORE)
      message(1:metric_count + 1) = [real(current(1), real64), result%metrics]
      texts = result%status//result%failure_kind
      if (next(1) == 0) exit
      if (interrupting_signal() /= 0) exit      ! the case held next stays pending
      call request(message, texts)
      current = next
      call MPI_Irecv(next, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, asked)
    end do
    ! The last result (if any), and leave.
    message(message_length) = leaving
    call request(message, texts)
    call MPI_Recv(next, 1, MPI_INTEGER, 0, tag_assign, MPI_COMM_WORLD, MPI_STATUS_IGNORE)
    if (allocated(integrator)) call integrator%release(release_failure)
  end procedure work

  module procedure run_case
    type(run_configuration) :: config
    type(run_summary) :: summary
    type(extra_attribute) :: extras(4)
    type(failure_type) :: failure
    real(real64), allocatable :: solve_seconds(:), solve_cpu_seconds(:)      ! on the heap: their size is the input's
    integer :: r
    logical :: split

    config = study%cases(c)%config
    config%output_file = case_file(study, c)
    config%overwrite = .true.          ! the index, not the file, says whether a case is done
    extras(1)%name = 'study'
    extras(1)%text = study%input_file
    extras(2)%name = 'study_case'
    extras(2)%number = c
    extras(3)%name = 'study_overrides'
    extras(3)%text = case_overrides(study, c)
    extras(4)%name = 'study_rank'
    extras(4)%number = rank
    ! With &study repeats = R the case runs R times, only the last keeping its file; the index
    ! gets the median of the time loops' durations (wall and CPU, each its own median), so timings
    ! on a shared machine do not zig-zag.
    allocate (solve_seconds(study%repeats), solve_cpu_seconds(study%repeats))
    ! The path eme_run would take for the case on one process, -eme_split and -eme_dense included
    ! (docs/performance.md, Two paths).
    split = split_run_wanted(config, 1)
    do r = 1, study%repeats
      ! An interrupted case (its file incomplete, with the same input) continues from its file
      ! (the split path from the file's last snapshot).
      if (split) then
        call run_distributed(config, MPI_COMM_SELF%MPI_VAL, summary, failure, observer=observer, &
                             keep_file=.not. study%index_only .and. r == study%repeats, extras=extras, &
                             durable=.false., resume_if_possible=study%repeats == 1)
      else
        call run_simulation(config, summary, failure, observer, integrator, &
                            keep_file=.not. study%index_only .and. r == study%repeats, extras=extras, durable=.false., &
                            template=template, resume_if_possible=study%repeats == 1)
      end if
      solve_seconds(r) = summary%solve_seconds
      solve_cpu_seconds(r) = summary%solve_cpu_seconds
      if (failure%failed() .or. summary%status /= 'complete') exit
    end do
    if (r > study%repeats) then
      summary%solve_seconds = median(solve_seconds)
      summary%solve_cpu_seconds = median(solve_cpu_seconds)
    end if
    if (summary%failure_kind == failure_interrupted) then
      result%status = summary%status
    else if (failure%failed()) then
      result%status = 'failed: '//failure%message
    else if (summary%status == 'complete') then
      result%status = 'complete'
    else
      result%status = 'failed: '//summary%status
    end if
    result%failure_kind = summary%failure_kind
    result%metrics = [real(summary%steps_completed, real64), real(summary%steps_planned, real64), &
                      real(summary%newton_iterations, real64), summary%wall_seconds, summary%solve_seconds, &
                      summary%cpu_seconds, summary%solve_cpu_seconds, summary%energy_drift, &
                      summary%min_entropy_increment, summary%max_lyapunov_increment, &
                      summary%angular_momentum_drift, summary%min_temperature, &
                      real(summary%halved_steps, real64), real(summary%rejected_steps, real64), &
                      merge(1.0_real64, 0.0_real64, len(summary%warnings) > 0), real(rank, real64), 0.0_real64]
  end procedure run_case

  ! A request to rank 0: the last result (case 0: none) and whether the worker is leaving.
  subroutine request(message, texts)
    real(real64), intent(in) :: message(:)
    character(len=*), intent(in) :: texts

    call MPI_Send(message, size(message), MPI_DOUBLE_PRECISION, 0, tag_request, MPI_COMM_WORLD)
    call MPI_Send(texts, len(texts), MPI_CHARACTER, 0, tag_status, MPI_COMM_WORLD)
  end subroutine request

end submodule ensemble_workers
