!> The run file's steps that the dense run (src/run/simulation) and the split run
!> (src/run/distributed_simulation) take alike, each written once: whether a run continues the
!> one its file holds (and from which record), the output path's checks before a run that starts
!> writes, the file's opening, the output's lock while the run writes, and the name the finished file takes
!> (docs/faults.md, Continuing a run; docs/output.md).
module run_file_steps
  use, intrinsic :: iso_fortran_env, only: int64
  use run_config, only: run_configuration
  use run_output, only: run_file, extra_attribute
  use resume_records, only: resume_record
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry
  use stepper, only: step_diagnostic
  use solver_description, only: solver_report
  use run_continuation, only: find_resume_record
  use run_outcome, only: run_summary, failure_input, failure_io, failure_library
  use time_loop_steps, only: record_failure
  use number_text, only: integer_text
  use run_options, only: overwrite_requested, continue_requested, petsc_options_in_force
  use hdf5_files, only: check_run_file, file_template
  use output_path, only: check_output_path
  use filesystem, only: make_parent_directories, rename_file, file_exists, output_lock, recheck_lock
  use failures, only: failure_type
  implicit none (type, external)
  private
  public :: continuation_wanted, prepare_output, open_run_file, holds_complete_run, name_finished_file, guard_output_lock

contains

  !> Whether a run with a file (`keeping`) should continue the run its file holds: as the caller
  !> says (`resume_if_possible`: an ensemble's case, when it can) or as the command line asks
  !> (-eme_continue); a run without a file never does.
  logical function continuation_wanted(keeping, resume_if_possible) result(continuing)
    logical, intent(in) :: keeping
    logical, intent(in), optional :: resume_if_possible

    continuing = .false.
    if (.not. keeping) return
    if (present(resume_if_possible)) then
      continuing = resume_if_possible
    else
      continuing = continue_requested()
    end if
  end function continuation_wanted

  !> The output before a run that writes: the record it continues from, if it is to continue
  !> (`continuing` on entry; on return whether it does: find_continuation), else the output
  !> path's checks (check_output_before_run). `kind` is '' if the run may go on, else the failure
  !> kind, with `text` saying why.
  subroutine prepare_output(config, chooses_time, unknowns, lenient, continuing, resume, kind, text)
    type(run_configuration), intent(in) :: config
    logical, intent(in) :: chooses_time, lenient
    integer, intent(in) :: unknowns
    logical, intent(inout) :: continuing
    type(resume_record), intent(out) :: resume
    character(len=:), allocatable, intent(out) :: kind, text

    kind = ''
    text = ''
    if (continuing) call find_continuation(config, chooses_time, unknowns, lenient, resume, continuing, kind, text)
    if (len(kind) == 0 .and. .not. continuing) call check_output_before_run(config, kind, text)
  end subroutine prepare_output

  !> The record a continued run starts from (src/run/run_continuation), which must be of the run's
  !> path: `unknowns` numbers in its state (the dense path's state and multipliers), or none (0: a
  !> split run's record stands at its last snapshot). A record that cannot be used gives its
  !> failure kind and text, unless `lenient` (an ensemble's case): then the run starts from t = 0,
  !> as it would have (`continuing` .false.).
  subroutine find_continuation(config, chooses_time, unknowns, lenient, resume, continuing, kind, text)
    type(run_configuration), intent(in) :: config
    logical, intent(in) :: chooses_time, lenient
    integer, intent(in) :: unknowns
    type(resume_record), intent(out) :: resume
    logical, intent(out) :: continuing
    character(len=:), allocatable, intent(out) :: kind, text

    call find_resume_record(config, chooses_time, resume, kind, text)
    if (len(kind) == 0) then
      if (size(resume%x) /= unknowns) then
        kind = failure_input
        text = other_path_text(config, unknowns == 0)
      end if
    end if
    continuing = len(kind) == 0
    if (continuing .or. .not. lenient) return
    ! Nothing to continue from: the run starts from t = 0, as it would have.
    kind = ''
    text = ''
  end subroutine find_continuation

  ! Why a record of the other path's run cannot be continued on this one (`split`: the run is split).
  function other_path_text(config, split) result(text)
    type(run_configuration), intent(in) :: config
    logical, intent(in) :: split
    character(len=:), allocatable :: text

    if (split) then
      text = config%output_file//': its run was not split over ranks (its state is in /state) and continues '// &
             'on the dense path ('//config%input_file//', -eme_continue); allowed: eme_run -eme_dense on one '// &
             'process, as it ran (one process takes a chain of more than 64 unknowns with an implicit '// &
             'integrator to the split path)'
    else
      text = config%output_file//': its run was split over ranks (its state is in /snapshots) and cannot be '// &
             'continued on the dense path ('//config%input_file//', -eme_continue); allowed: mpirun -n P eme_run '// &
             'with P > 1 (any P), or eme_run -eme_split on one process, which continue it from its last snapshot'
    end if
  end function other_path_text

  !> The output path's checks before a run that starts writes (it does not continue one): not the
  !> input file, a directory, a stranger's file or a study's (src/io/output_path), its directory
  !> made, and no complete run in it unless it may be replaced (&output overwrite, -eme_overwrite).
  !> `kind` is '' if the run may write, else the failure kind, with `text` saying why.
  subroutine check_output_before_run(config, kind, text)
    type(run_configuration), intent(in) :: config
    character(len=:), allocatable, intent(out) :: kind, text
    type(failure_type) :: checking
    logical :: replace

    kind = ''
    text = ''
    replace = overwrite_requested()       ! asked first, so PETSc counts -eme_overwrite as used
    if (config%overwrite) replace = .true.
    call check_output_path(config%output_file, config%input_file, replace, checking)
    if (checking%failed()) then
      kind = failure_input
      text = checking%message
      return
    end if
    call make_parent_directories(config%output_file, checking)
    if (checking%failed()) then
      kind = failure_io
      text = 'cannot create the directory of the output file '''//config%output_file//''' ('//config%input_file// &
             ', &output: file): '//checking%message
      return
    end if
    if (replace) return
    if (.not. holds_complete_run(config%output_file)) return
    kind = failure_input
    text = config%output_file//' holds a complete run, which is kept; to replace it, set &output overwrite = .true. '// &
           'in '//config%input_file//', give -eme_overwrite, or choose another &output file'
  end subroutine check_output_before_run

  !> Whether `path` is a run file that reads back complete.
  logical function holds_complete_run(path)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: status
    integer :: steps
    type(failure_type) :: checking

    holds_complete_run = .false.
    if (.not. file_exists(path)) return
    call check_run_file(path, status, steps, checking)
    holds_complete_run = .not. checking%failed() .and. status == 'complete'
  end function holds_complete_run

  !> Opens the run's file `part` (run_output's create, from `template` unless the run is
  !> `continuing`; `state_rows` as there, with `extras` as root attributes and synced if `durable`),
  !> records the solver `solver`, and takes a continued run's file up from its record `resume`.
  !> A failure (HDF5's, or a file that cannot be continued) is recorded with the file's name.
  subroutine open_run_file(output, part, config, entry, model, constraints, diagnostics, solver, continuing, resume, &
                           summary, failure, extras, durable, template, state_rows)
    type(run_file), intent(inout) :: output
    character(len=*), intent(in) :: part
    type(run_configuration), intent(in), target :: config
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    type(step_diagnostic), intent(in) :: diagnostics(:)
    type(solver_report), intent(in) :: solver
    logical, intent(in) :: continuing
    type(resume_record), intent(in) :: resume
    type(run_summary), intent(inout) :: summary
    type(failure_type), intent(inout) :: failure
    type(extra_attribute), intent(in), optional :: extras(:)
    logical, intent(in), optional :: durable, state_rows
    type(file_template), intent(inout), target, optional :: template
    type(extra_attribute), allocatable :: added(:)
    type(failure_type) :: writing

    allocate (added(0))
    if (present(extras)) added = extras
    if (present(durable)) output%store%durable = durable
    if (continuing) then        ! the file exists: nothing of it comes from a template
      call output%create(part, config, entry, model, constraints, [diagnostics, model_diagnostics(model)], added, &
                         petsc_options_in_force(), writing, state_rows=state_rows)
    else
      call output%create(part, config, entry, model, constraints, [diagnostics, model_diagnostics(model)], added, &
                         petsc_options_in_force(), writing, template, state_rows)
    end if
    if (.not. writing%failed()) call output%record_solver(solver, writing)
    if (writing%failed()) then
      call record_failure(failure, summary, failure_library, 'HDF5 could not prepare the output file '''//part// &
                          ''' ('//config%input_file//')', config%input_file)
      return
    end if
    if (.not. continuing) return
    call output%continue_file(resume, config, writing)
    if (writing%failed()) call record_failure(failure, summary, failure_io, "cannot continue the output file '"// &
                                              part//"' ("//config%input_file//'): '//writing%message, config%input_file)
  end subroutine open_run_file

  ! The model's own figures of each step (generic_model's step_figure_list) as datasets of the
  ! rows, after the integrator's.
  function model_diagnostics(model) result(items)
    class(generic_model), intent(in) :: model
    type(step_diagnostic), allocatable :: items(:)
    integer :: k

    associate (figures => model%step_figure_list())
      allocate (items(size(figures)))
      do k = 1, size(figures)
        items(k) = step_diagnostic(trim(figures(k)%name), trim(figures(k)%units), figures(k)%description, &
                                   trim(figures(k)%combine))
      end do
    end associate
  end function model_diagnostics

  !> The finished file `part` takes the output's name (synced if `durable`), unless the run is
  !> incomplete (summary's status) and the name holds a complete run: that one is kept, and the
  !> summary's note says where this run's file is. A renaming that fails is the run's failure.
  subroutine name_finished_file(config, part, durable, summary, failure)
    type(run_configuration), intent(in) :: config
    character(len=*), intent(in) :: part
    logical, intent(in) :: durable
    type(run_summary), intent(inout) :: summary
    type(failure_type), intent(inout) :: failure
    type(failure_type) :: renaming

    if (summary%status /= 'complete') then
      if (holds_complete_run(config%output_file)) then
        if (.not. failure%failed()) summary%note = config%output_file//' keeps the earlier complete run; this '// &
                                                   'run''s file is '//part
        return
      end if
    end if
    call rename_file(part, config%output_file, renaming, sync=durable)
    if (.not. renaming%failed()) return
    failure = failure_type()      ! the file's name is what its user looks for first
    call record_failure(failure, summary, failure_io, 'cannot rename '''//part//''' to '''//config%output_file// &
                        ''' ('//config%input_file//'): '//renaming%message, config%input_file)
  end subroutine name_finished_file

  !> Whether the output's lock (eme_run's) is still this process's, checked before the run
  !> writes. One removed or replaced behind the run's back means that another writer can be in:
  !> `lost`, the run stops after `steps` steps (summary's status and a failure say why) and writes
  !> its file once more, marked incomplete, only if it took the lock again (`may_write`); else it
  !> writes nothing more and leaves the file as its last write made it.
  subroutine guard_output_lock(lock, config, part, steps, summary, failure, lost, may_write)
    type(output_lock), intent(inout) :: lock
    type(run_configuration), intent(in) :: config
    character(len=*), intent(in) :: part
    integer(int64), intent(in) :: steps
    type(run_summary), intent(inout) :: summary
    type(failure_type), intent(inout) :: failure
    logical, intent(out) :: lost, may_write
    character(len=:), allocatable :: holder, what, aftermath
    logical :: retaken

    call recheck_lock(lock, lost, retaken, what, holder)
    may_write = .not. lost .or. retaken
    if (.not. lost) return
    summary%status = 'incomplete: the lock '//lock%path//' was '//what//' while the run wrote'
    summary%failure_kind = failure_io
    if (retaken) then
      aftermath = ', so that a second writer could start: the run stops after '//integer_text(steps)// &
                  ' steps; it took the lock again, and '//part//' is marked incomplete'
    else
      aftermath = ', and '//holder//' holds it now: the run stops after '//integer_text(steps)// &
                  ' steps and writes nothing more ('//part//' is left as its last write made it)'
    end if
    call record_failure(failure, summary, failure_io, config%output_file//' ('//config%input_file//'): its lock '// &
                        lock%path//' was '//what//' while the run wrote'//aftermath, config%input_file)
  end subroutine guard_output_lock

end module run_file_steps
