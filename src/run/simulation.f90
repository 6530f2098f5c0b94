!> One dense run from a validated configuration to its HDF5 file, for eme_run and eme_ensemble:
!> its set-up and closing around the one time loop (src/run/time_loop), which steps the run's
!> dense path (src/run/dense_run_path). The model and its initial state come from the
!> configuration's scene, the integrator from the registry; the loop advances it one output step
!> at a time and records every point and step (src/run/run_output). The file is written as FILE.part and renamed to
!> FILE when the run has ended and the file has been read back; an existing complete FILE is
!> not replaced unless asked (&output overwrite, -eme_overwrite). A run ends early, cleanly, when
!> a step cannot be solved, when SIGTERM or SIGINT arrives, or when the output cannot be
!> written: the file then keeps every step written before, its `status` reads 'incomplete:
!> <reason>' and its `failure_kind` says why in a word. Every write stores the state after its last
!> row (run_output's resume record), so that -eme_continue goes on from there, appending to the
!> file (docs/faults.md, Continuing a run).
module simulation
  use, intrinsic :: iso_fortran_env, only: real64
  use integrator_settings, only: step_count
  use integrator_registry, only: integrator_entry, find_integrator, build_integrator, chooses_times
  use stepper, only: time_stepper
  use run_config, only: run_configuration
  use run_output, only: extra_attribute
  use resume_records, only: resume_record
  use run_file_steps, only: continuation_wanted, prepare_output, open_run_file, holds_complete_run, &
                            name_finished_file
  use time_loop_steps, only: run_observer, line_reporter, exit_status, failure_code_of, complete_if_finished
  use run_outcome, only: run_summary, open_summary, summarize_model, close_summary, failure_input, failure_io, &
                         failure_library
  use step_balances, only: applicable_balances
  use step_check, only: checked_balances
  use run_signals, only: install_interrupt_handlers
  use dense_run_path, only: dense_path
  use time_loop, only: run_time_loop
  use hdf5_files, only: file_template
  use command_line, only: petsc_error_text
  use filesystem, only: output_lock
  use dense_setup, only: dense_max_unknowns, set_up_only, check_dense_size, setup_failure_text
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: run_summary, extra_attribute, run_simulation, run_observer, line_reporter, exit_status, set_up_only
  public :: dense_max_unknowns, holds_complete_run, failure_code_of

contains

  !> Runs `config` and writes its HDF5 file (none if keep_file is .false.: an index-only study).
  !> A failure (its code from the failure kind, its origin the input file), with a message naming
  !> the file, the input file and the OS's reason, if the output could not be written, a library
  !> failed, or the output file holds a complete run that may not be replaced; a run that stops
  !> early is reported through summary%status (and summary%note). Either way
  !> summary%failure_kind says why in a word (src/run/run_outcome's failure_* words).
  !> With `reusable`, the caller's integrator is used when it is of the configured kind (an
  !> ensemble rank keeps its PETSc objects from case to case), replaced otherwise, and left for
  !> the next run; without, the run builds and frees its own. `progress` receives a line at most
  !> every 2 s; `extras` are root attributes added to the file. The finished file is synced to
  !> disk unless `durable` is .false. (an ensemble's case: its index is the record). The run
  !> continues the one its file holds if the command line asks (-eme_continue: else it fails with
  !> failure_input); with `resume_if_possible` instead, it does when it can (an interrupted case of
  !> a study) and starts from t = 0 otherwise. With `lock` (eme_run's lock of the output), the
  !> run checks before each write that the lock file is still the one it holds: one removed or
  !> replaced behind its back stops the run (failure_io), and the file is written once more,
  !> marked with the reason, only if the lock can be taken again (else another writer has it, and
  !> the file is left as the last write made it). The time loop's many exits set `failure` as they
  !> go; summary%note says what the driver adds to a run without one.
  subroutine run_simulation(config, summary, failure, observer, reusable, progress, keep_file, extras, durable, &
                            template, resume_if_possible, lock)
    type(run_configuration), intent(in), target :: config
    type(run_summary), intent(out), target :: summary
    type(failure_type), intent(out), target :: failure
    class(run_observer), intent(inout), target, optional :: observer
    class(time_stepper), allocatable, intent(inout), target, optional :: reusable
    procedure(line_reporter), optional :: progress
    logical, intent(in), optional :: keep_file
    type(extra_attribute), intent(in), optional :: extras(:)
    logical, intent(in), optional :: durable
    type(file_template), intent(inout), target, optional :: template
    logical, intent(in), optional :: resume_if_possible
    type(output_lock), intent(inout), target, optional :: lock
    class(time_stepper), allocatable, target :: own
    type(dense_path) :: run             !! the loop's state (src/run/dense_run_path)
    type(integrator_entry) :: entry
    type(resume_record) :: resume       !! the state a continued run starts from
    character(len=:), allocatable :: kind, text
    real(real64), allocatable :: z0(:)
    type(failure_type) :: step_failure, release_failure, io_failure
    logical :: found, continuing, completed
    integer :: n_unknowns

    run%config => config
    run%summary => summary
    run%failure => failure
    if (present(observer)) run%observer => observer
    if (present(progress)) run%progress => progress
    if (present(lock)) run%lock => lock
    call run%timer%begin()
    call open_summary(summary, step_count(config%integrator))
    run%dt = config%integrator%dt
    run%t_end = config%integrator%t_end
    run%time = 0.0_real64
    run%n = 0
    run%writing = .true.
    run%lock_lost = .false.
    if (present(keep_file)) run%writing = keep_file
    run%part = config%output_file//'.part'
    call install_interrupt_handlers(io_failure)     ! (a run without them still runs)
    call find_integrator(config%integrator%scheme, entry, found)
    call config%scene%build(config%integrator%thermo_variable, run%model, z0, run%constraints, step_failure)
    if (.not. step_failure%failed()) call check_dense_size(size(z0), step_failure)
    if (step_failure%failed()) then
      call run%fail(failure_input, config%input_file//': '//step_failure%message)
      return
    end if
    run%chooses_time = chooses_times(entry, config%integrator%tolerance_given)
    continuing = continuation_wanted(run%writing, resume_if_possible)
    if (run%writing) then
      call prepare_output(config, run%chooses_time, run%model%state_size + size(run%constraints), &
                          present(resume_if_possible), continuing, resume, kind, text)
      if (len(kind) > 0) call run%fail(kind, text)
    end if
    if (failure%failed()) return
    run%n_state = run%model%state_size
    ! The unknowns: the state and the multipliers of the active constraints (initial guess 0).
    n_unknowns = run%n_state + size(run%constraints)
    allocate (run%x(n_unknowns), run%x_previous(n_unknowns), run%x_new(n_unknowns))
    allocate (run%residuals(size(run%constraints)))
    call summarize_model(summary, run%model)
    ! The conserved components at t = 0 (a continued run's too: its input builds the same z0).
    run%conserved_0 = run%model%conserved_momenta(z0)
    run%x = 0.0_real64
    run%x(1:run%n_state) = z0
    run%boundary_heat = 0.0_real64
    run%checked = checked_balances(entry, run%model, run%constraints)
    run%has_balance = applicable_balances(run%model)

    if (present(reusable)) then
      if (allocated(reusable)) then
        if (reusable%scheme /= entry%name) then
          call reusable%release(release_failure)
          deallocate (reusable)
        end if
      end if
      if (.not. allocated(reusable)) call build_integrator(entry, reusable)
      run%integrator => reusable
    else
      call build_integrator(entry, own)
      run%integrator => own
    end if
    ! The integrator starts first: the datasets of its own figures can depend on its settings.
    call run%integrator%start(config%integrator, run%model, run%constraints, z0, step_failure)
    run%integrator_figures = size(run%integrator%diagnostics())
    run%model_figures = size(run%model%step_figure_list())
    if (step_failure%failed()) then
      ! The drivers set the solver up once before (set_up_only), so this is rare: nothing is written.
      call run%fail(failure_input, config%input_file//': '//setup_failure_text())
      if (.not. present(reusable)) call run%integrator%release(release_failure)
      return
    end if
    if (run%writing) call open_run_file(run%output, run%part, config, entry, run%model, run%constraints, &
                                        run%integrator%diagnostics(), run%integrator%describe_solver(), continuing, &
                                        resume, summary, failure, extras, durable, template)
    if (failure%failed()) then
      if (.not. present(reusable)) call run%integrator%release(release_failure)
      return
    end if
    if (continuing) then
      call restore(resume)
      call run%integrator%restore_state(resume%integrator_state, run%x, run%x_previous, step_failure)
      if (step_failure%failed()) then
        call run%fail(failure_input, run%part//": its integrator state does not fit &integrator scheme = '"// &
                      trim(entry%name)//"' ("//config%input_file//', -eme_continue); allowed: a file of the same input')
        if (.not. present(reusable)) call run%integrator%release(release_failure)
        return
      end if
    else
      call run%observe(z0)
      run%energy_0 = run%seen%energy
      call run%record_point(0.0_real64, z0, .true.)
      run%outputs_passed = 0
      run%x_previous = run%x
      call run%output%note_resume_state(run%n, run%time, run%outputs_passed, run%energy_0, run%first_conserved_0(), &
                                        run%boundary_heat, summary, run%x, run%x_previous, run%integrator)
    end if
    summary%steps_chosen = run%chooses_time
    call run_time_loop(run)
    call close_summary(summary, run%model, run%has_balance)
    call run%set_times(.true.)
    call complete_if_finished(summary, run%finished, run%n, completed)
    if (completed) summary%warnings = run%integrator%accuracy_warnings()
    if (.not. present(reusable)) then
      call run%integrator%release(release_failure)
      if (release_failure%failed()) call run%fail(failure_library, 'PETSc failed to free the solver: '// &
                                                  petsc_error_text())
    end if
    call close_output()
    call run%set_times(.false.)

  contains

    ! The loop's state as `record` stored it (the point after its step was recorded).
    subroutine restore(record)
      type(resume_record), intent(in) :: record

      run%n = record%step
      run%time = record%time
      run%outputs_passed = record%outputs_passed
      run%energy_0 = record%energy_0
      run%boundary_heat = record%boundary_heat
      run%x = record%x
      run%x_previous = record%x_previous
      call record%restore_summary(summary)
      call run%observe(run%x(1:run%n_state))
      summary%min_temperature = record%summary%min_temperature
    end subroutine restore

    ! Writes the file's last rows and final attributes, reads it back, and gives it its final
    ! name; an incomplete run does not take the name of a complete one.
    subroutine close_output()
      type(failure_type) :: finishing

      if (.not. run%writing) return
      call run%guard_lock()
      if (.not. run%writing) return
      call run%set_times(.false.)
      call run%output%finish(summary, finishing)
      if (finishing%failed()) then
        summary%status = 'incomplete: cannot write the output file: '//finishing%message
        failure = failure_type()
        call run%fail(failure_io, 'cannot write the output file '''//run%part//''' ('//config%input_file//'): ' &
                      //finishing%message//run%output%kept_words(run%part))
        return
      end if
      call name_finished_file(config, run%part, run%output%store%durable, summary, failure)
    end subroutine close_output

  end subroutine run_simulation

end module simulation
