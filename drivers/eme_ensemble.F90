!> mpirun -n P eme_ensemble [PETSc options] STUDY.nml [PETSc options]: runs the cases of a parameter study on
!> P ranks (docs/studies.md). Exit status: 0 every case was attempted (failed cases
!> are results, recorded in the index with their reason), 2 bad study input, or another study
!> running in the same output_dir (nothing is written), 1 the index or a case's output could not be written, 128 + N after signal N (the
!> study stopped cleanly; running it again goes on).
program eme_ensemble
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use study_config, only: study_definition, read_study
  use ensemble, only: run_study, study_outcome, world_rank
  use command_help, only: print_study_help, print_integrators
  use command_line, only: command_arguments, parse_command_line, initialize_petsc, check_own_options, &
                          petsc_help_requested, unused_petsc_options, petsc_error_text, check_petsc_file_options, &
                          launcher_rank, forget_petsc_file_options
  use output_path, only: protected_entry, protected_entries
  use simulation, only: set_up_only
  use distributed_simulation, only: split_run_wanted, set_up_distributed_only
  use library_versions, only: print_versions
  use failures, only: failure_type, failure_input, fail
  use run_options, only: split_requested, dense_requested
  use number_text, only: integer_text
  implicit none

  type(study_definition), target :: study
  type(study_outcome) :: outcome
  type(command_arguments) :: arguments
  character(len=:), allocatable :: message, unused
  integer :: stat, rank, exit_status
  type(failure_type) :: failure, startup, study_failure
  character(len=:), allocatable :: own_files, own_folders   !! the study's, which no PETSc option may write
  logical :: help, both_paths
  PetscErrorCode :: ierr

  call parse_command_line('eme_ensemble', [character(len=16) :: '--help', '-h', '--version', '--integrators'], &
                          arguments, failure)
  if (arguments%has_flag('--help') .or. arguments%has_flag('-h')) then
    call print_study_help(output_unit)
    stop
  else if (arguments%has_flag('--version')) then
    call print_versions(output_unit, 'eme_ensemble')
    stop
  else if (arguments%has_flag('--integrators')) then
    call print_integrators(output_unit, tabular=.true.)
    stop
  end if
  ! The study's files are known before PETSc starts, which opens the files of some options
  ! (-history, -info, -log_trace) as it starts: an option that would write one is refused first.
  ! Every rank reads and validates the study: the expansion is cheap and deterministic.
  own_files = protected_entries(arguments%given_files, 'an input file')
  own_folders = ''
  if (.not. failure%failed()) then
    call read_study(arguments%input_file, study, study_failure)
    if (.not. study_failure%failed()) then
      own_files = own_files//protected_entry(study%base, 'the study''s base input file')
      own_folders = protected_entry(study%output_dir, 'in the study''s output folder (output_dir of '// &
                                    study%input_file//')')
    end if
  end if
  call check_petsc_file_options(arguments, .false., own_files, own_folders, .false., startup)
  if (startup%failed()) then
    if (launcher_rank() == 0) write (error_unit, '(a)') 'eme_ensemble: '//startup%text()
    stop 2, quiet=.true.
  end if
  call initialize_petsc(arguments, startup)
  if (startup%failed()) then
    write (error_unit, '(a)') 'eme_ensemble: PETSc could not start with the options given: '//petsc_error_text()
    stop 2, quiet=.true.
  end if
  rank = world_rank()
  exit_status = 0
  help = petsc_help_requested()
  if (help) then
    if (rank == 0) call print_study_help(output_unit)
  else if (failure%failed()) then
    if (rank == 0) write (error_unit, '(a)') 'eme_ensemble: '//failure%text()
    exit_status = 2
  else
    call check_own_options(failure)
    both_paths = dense_requested()
    if (both_paths) both_paths = split_requested()
    if (.not. failure%failed() .and. both_paths) &
      call fail(failure, failure_input, '-eme_split and -eme_dense ask for both paths; allowed: one of them, '// &
                'or neither (each case takes the path eme_run would take)')
    if (.not. failure%failed()) &
      call check_petsc_file_options(arguments, .true., own_files, own_folders, .false., failure)
    if (failure%failed()) then
      if (rank == 0) write (error_unit, '(a)') 'eme_ensemble: '//failure%text()
      exit_status = 2
    end if
  end if
  if (exit_status == 0 .and. .not. help) then
    failure = study_failure            ! (read before PETSc started)
    stat = failure%code
    if (failure%failed()) message = failure%text()
    if (stat == 0) call check_solver_options()
    if (stat /= 0) then
      if (rank == 0) write (error_unit, '(a)') 'eme_ensemble: '//message
      exit_status = 2
    else
      call run_study(study, outcome, failure, print_line)
      stat = failure%code
      if (failure%failed()) then
        if (rank == 0) write (error_unit, '(a)') 'eme_ensemble: '//failure%text()
        ! 2 (bad input): another study holds output_dir, or it holds finished cases this study lacks
        exit_status = merge(2, 1, failure%code == failure_input)
      else if (outcome%io_failure) then
        if (rank == 0) write (error_unit, '(a)') 'eme_ensemble: stopped: '//outcome%io_message
        exit_status = 1
      else if (outcome%signal /= 0) then
        exit_status = 128 + outcome%signal
      end if
      if (stat == 0 .and. rank == 0) then
        write (output_unit, '(a, i0, a, i0, a, i0, a, i0, a, f10.3, a)') 'eme_ensemble: ', outcome%cases, ' cases: ', &
          outcome%complete, ' complete (', outcome%skipped, ' from an earlier run), ', outcome%failed, &
          ' failed; wall time', outcome%wall_seconds, ' s; index '//study%output_dir//'/index.h5'
      end if
      unused = unused_petsc_options()
      if (len(unused) > 0) write (error_unit, '(a)') 'eme_ensemble: warning: PETSc options that nothing used: '//unused
    end if
  end if
  ! A study refused before it ran writes nothing, PETSc's -log_view file included.
  if (exit_status == 2) call forget_petsc_file_options()
  call PetscFinalize(ierr)
  ! After a refusal its reason was said: PETSc's failure to write a refused -log_view file is not news.
  if (ierr /= 0 .and. exit_status == 0) then
    if (rank == 0) write (error_unit, '(a)') 'eme_ensemble: PETSc failed at its finalization: '//petsc_error_text()
    exit_status = 1
  end if
  if (exit_status /= 0) stop exit_status, quiet=.true.

contains

  ! Every integrator of the study set up once, unwritten, before any case runs: PETSc options
  ! that one of them cannot take are bad input for the whole study (exit 2, no case run). A case
  ! that eme_run would split is set up on the split path, on this rank alone, as it will run.
  subroutine check_solver_options()
    character(len=32), allocatable :: checked(:)      ! path, scheme and thermodynamic variable of each set-up
    character(len=32) :: key
    integer :: c
    logical :: split

    allocate (checked(0))
    do c = 1, size(study%cases)
      split = split_run_wanted(study%cases(c)%config, 1)
      associate (choice => study%cases(c)%config%integrator)
        write (key, '(a, 1x, a, 1x, i0)') trim(merge('split', 'dense', split)), trim(choice%scheme), &
          choice%thermo_variable
      end associate
      if (any(checked == key)) cycle
      checked = [checked, key]
      if (split) then
        call set_up_distributed_only(study%cases(c)%config, PETSC_COMM_SELF, failure)
      else
        call set_up_only(study%cases(c)%config, failure)
      end if
      if (failure%failed()) then
        stat = 1
        ! The message names the base file once (the path's refusals start with it) and the case.
        message = failure%message
        if (index(message, study%cases(c)%config%input_file) /= 1) &
          message = study%cases(c)%config%input_file//': '//message
        message = message//' (case '//integer_text(c)//' of the study)'
        return
      end if
    end do
  end subroutine check_solver_options

  ! The study's start, progress and warning lines, as they come.
  subroutine print_line(text)
    character(len=*), intent(in) :: text

    write (output_unit, '(a)') text
    flush (output_unit)
  end subroutine print_line

end program eme_ensemble
