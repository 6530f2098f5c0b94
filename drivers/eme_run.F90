!> eme_run [PETSc options] FILE.nml [PETSc options]: one run of the thermoviscoelastic double pendulum.
!> Reads the namelist, integrates, writes the HDF5 file named in &output and prints a
!> one-line summary. Exit status: 0 complete, 2 bad input or usage, or another run writing the
!> same output (no output file is written), 3 the run stopped early (the file is kept, marked incomplete), 1 I/O or PETSc error,
!> 128 + N after signal N (SIGTERM, SIGINT: the file is kept, marked incomplete).
!> eme_run --help (or -h), --version, --integrators (the registry as a table) and --output-schema
!> (the HDF5 layout as a table) print and exit with status 0; so does PETSc's -help, which also
!> lists the options the run's solver reads (set up from FILE.nml, not run). A model that can be
!> split over ranks (the spring chain) runs split under mpirun -n P, and on the sparse path
!> beyond the dense path's 1000 unknowns (src/run/distributed_simulation); for any other model
!> several ranks are refused (eme_ensemble runs studies on several).
program eme_run
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit, real64
  use, intrinsic :: ieee_arithmetic, only: ieee_is_nan
  use run_config, only: run_configuration, read_run_config
  use simulation, only: run_summary, run_simulation, run_exit_status => exit_status, set_up_only
  use distributed_simulation, only: run_distributed, split_run_wanted, set_up_distributed_only
  use run_options, only: progress_wanted, split_requested, dense_requested
  use run_schema, only: print_output_schema
  use command_help, only: print_run_help, print_integrators
  use command_line, only: command_arguments, parse_command_line, initialize_petsc, check_own_options, &
                          petsc_help_requested, unused_petsc_options, petsc_error_text, check_petsc_file_options, &
                          forget_petsc_file_options
  use output_path, only: check_outside_studies, run_own_files, protected_entries
  use library_versions, only: print_versions
  use filesystem, only: output_lock, lock_output, unlock_output, lock_held_elsewhere, lock_not_offered
  use failures, only: failure_type
  use number_text, only: integer_text, fixed_text, scientific_text
  implicit none

  type(run_configuration) :: config
  type(run_summary) :: summary
  type(command_arguments) :: arguments
  character(len=:), allocatable :: unused
  integer :: stat, exit_status, ranks, rank
  logical :: split      !! the run is split over the ranks (distributed_simulation)
  logical :: dense_refused   !! -eme_dense with -eme_split or on several ranks
  type(failure_type) :: failure, startup, config_failure
  character(len=:), allocatable :: own_files     !! the files of the run, which no PETSc option may write
  PetscErrorCode :: ierr

  call parse_command_line('eme_run', [character(len=16) :: '--help', '-h', '--version', '--integrators', &
                          '--output-schema'], arguments, failure)
  ! These need neither PETSc nor an input file.
  if (arguments%has_flag('--help') .or. arguments%has_flag('-h')) then
    call print_run_help(output_unit)
    stop
  else if (arguments%has_flag('--version')) then
    call print_versions(output_unit, 'eme_run')
    stop
  else if (arguments%has_flag('--integrators')) then
    call print_integrators(output_unit, tabular=.true.)
    stop
  else if (arguments%has_flag('--output-schema')) then
    call print_output_schema()
    stop
  end if
  ! The run's own files are known before PETSc starts, which opens the files of some options
  ! (-history, -info, -log_trace) as it starts: an option that would write one is refused first.
  own_files = protected_entries(arguments%given_files, 'an input file')
  if (.not. failure%failed()) then
    call read_run_config(arguments%input_file, config, config_failure)
    if (.not. config_failure%failed()) then
      own_files = run_own_files(config%output_file, arguments%input_file)
      call check_outside_studies(config%output_file, config%input_file, config_failure)
    end if
  end if
  call check_petsc_file_options(arguments, .false., own_files, '', .true., startup)
  if (startup%failed()) then
    write (error_unit, '(a)') 'eme_run: '//startup%text()
    stop 2, quiet=.true.
  end if
  call initialize_petsc(arguments, startup)
  if (startup%failed()) then
    ! A PETSc option that PETSc itself refuses at start (-options_file of a missing file, ...).
    write (error_unit, '(a)') 'eme_run: PETSc could not start with the options given: '//petsc_error_text()
    stop 2, quiet=.true.
  end if
  PetscCallMPIA(MPI_Comm_size(PETSC_COMM_WORLD, ranks, ierr))
  PetscCallMPIA(MPI_Comm_rank(PETSC_COMM_WORLD, rank, ierr))
  exit_status = 0
  split = .false.
  ! The path by the model, its size and the integrator, or -eme_split / -eme_dense (docs/performance.md, Two paths).
  if (.not. failure%failed() .and. .not. config_failure%failed()) split = split_run_wanted(config, ranks)
  ! (An input or command line that cannot be read is reported as such below, on rank 0.)
  dense_refused = dense_requested()
  if (dense_refused .and. ranks == 1) dense_refused = split_requested()
  if (dense_refused) then
    if (rank == 0) write (error_unit, '(a)') 'eme_run: -eme_dense asks for the dense path, which runs on one '// &
      'process without -eme_split; allowed: eme_run FILE.nml -eme_dense (one process, at most 1000 unknowns)'
    exit_status = 2
  else if (split_requested() .and. .not. split .and. .not. failure%failed() .and. .not. config_failure%failed()) then
    if (rank == 0) write (error_unit, '(a)') 'eme_run: '//arguments%input_file//': -eme_split: this model and '// &
      'integrator run on the dense path only; allowed: -eme_split with the spring chain and an integrator of its '// &
      'split path (eme, midpoint, the relaxed family, PETSc TS; docs/integrators.md, On the split path)'
    exit_status = 2
  else if (ranks > 1 .and. .not. split .and. .not. failure%failed() .and. .not. config_failure%failed()) then
    ! Every rank would write the same file: a study of several cases is eme_ensemble's.
    if (rank == 0) write (error_unit, '(a, i0, a)') 'eme_run: runs one case on one process, not on ', ranks, &
      ' ranks; for several cases on several ranks: mpirun -n N eme_ensemble STUDY.nml (docs/performance.md)'
    exit_status = 2
  else if (petsc_help_requested()) then
    ! PETSc's -help: the usage, then every option the run's solver reads as it is set up.
    call print_run_help(output_unit)
    if (.not. failure%failed()) then
      call read_run_config(arguments%input_file, config, failure)
      if (.not. failure%failed() .and. split) then
        call set_up_distributed_only(config, PETSC_COMM_WORLD, failure)
      else if (.not. failure%failed()) then
        call set_up_only(config, failure)
      end if
      if (failure%failed()) then
        if (rank == 0) write (error_unit, '(a)') 'eme_run: '//failure%text()
        exit_status = 2
      end if
    end if
  else if (failure%failed()) then
    if (rank == 0) write (error_unit, '(a)') 'eme_run: '//failure%text()
    exit_status = 2
  else
    call check_own_options(failure)
    if (.not. failure%failed()) call check_petsc_file_options(arguments, .true., own_files, '', .true., failure)
    if (failure%failed()) then
      if (rank == 0) write (error_unit, '(a)') 'eme_run: '//failure%text()
      exit_status = 2
    else
      failure = config_failure       ! (read before PETSc started)
      ! The solver set up once, unwritten: PETSc options it cannot take are bad input.
      if (split .and. .not. failure%failed()) then
        call set_up_distributed_only(config, PETSC_COMM_WORLD, failure)
      else if (.not. failure%failed()) then
        call set_up_only(config, failure)
      end if
      if (failure%failed()) then
        if (rank == 0) write (error_unit, '(a)') 'eme_run: '//failure%text()
        exit_status = 2
      else
        call run_case()
      end if
    end if
  end if
  ! A run refused before it ran writes nothing, PETSc's -log_view file included.
  if (exit_status == 2) call forget_petsc_file_options()
  call PetscFinalize(ierr)
  ! After a refusal its reason was said: PETSc's failure to write a refused -log_view file is not news.
  if (ierr /= 0 .and. exit_status == 0) then
    write (error_unit, '(a)') 'eme_run: PETSc failed at its finalization: '//petsc_error_text()
    exit_status = 1
  end if
  if (exit_status /= 0) stop exit_status, quiet=.true.

contains

  ! The run of `config`, its summary line and warnings; sets exit_status.
  subroutine run_case()
    type(output_lock) :: lock
    character(len=:), allocatable :: momentum_part, thermal_part, steps_done
    integer :: k
    logical :: progress

    ! One writer per output (rank 0 writes it): a second run of the same file is refused before it
    ! writes anything.
    if (rank == 0) call take_lock(lock)
    if (split) then
      PetscCallMPIA(MPI_Bcast(exit_status, 1, MPI_INTEGER, 0, PETSC_COMM_WORLD, ierr))
    end if
    if (exit_status /= 0) return
    if (allocated(config%warnings) .and. rank == 0) then
      do k = 1, size(config%warnings)
        write (error_unit, '(a)') 'eme_run: warning: '//trim(config%warnings(k))
      end do
    end if
    if (.not. split .and. config%snapshot_every > 0) write (error_unit, '(a)') 'eme_run: warning: '// &
      config%input_file//': &output: snapshot_every is read by the split path only (a chain under mpirun, '// &
      'an implicit integrator beyond 64 unknowns, any beyond 1000, or -eme_split); this run takes the dense '// &
      'path, whose rows hold the whole '// &
      'state (/state) at every written point'
    progress = progress_wanted()
    if (split .and. progress) then
      call run_distributed(config, PETSC_COMM_WORLD, summary, failure, progress=print_progress, lock=lock)
    else if (split) then
      call run_distributed(config, PETSC_COMM_WORLD, summary, failure, lock=lock)
    else if (progress) then
      call run_simulation(config, summary, failure, progress=print_progress, lock=lock)
    else
      call run_simulation(config, summary, failure, lock=lock)
    end if
    if (rank == 0) call unlock_output(lock)
    exit_status = run_exit_status(summary)
    unused = unused_petsc_options()      ! (collective: every rank asks)
    if (rank /= 0) return
    stat = failure%code
    if (failure%failed()) then
      write (error_unit, '(a)') 'eme_run: '//failure%text()
    else if (summary%status /= 'complete') then
      write (error_unit, '(a)') 'eme_run: '//config%output_file//': '//summary%status
      if (len(summary%note) > 0) write (error_unit, '(a)') 'eme_run: '//summary%note
    end if
    ! The steps done, out of the plan where there is one: an integrator that chooses its steps
    ! has none (t_end/dt is a fixed step's count, not its own).
    steps_done = integer_text(summary%steps_completed)
    if (.not. summary%steps_chosen) steps_done = steps_done//'/'//integer_text(summary%steps_planned)
    ! Figures of no step would be NaN: a run that completed none says so instead. Every figure
    ! keeps its column when it fits and is written whole when it does not (number_text).
    if (stat == 0 .and. summary%steps_completed == 0) then
      write (output_unit, '(a)') config%output_file//': '//summary%status//', '//steps_done// &
        ' steps: no step completed, '//fixed_text(summary%wall_seconds, 3, width=8)//' s'
    else if (stat == 0) then
      ! The momentum drift only for a model with a conserved momentum (NaN otherwise): the largest
      ! over its components, each named (|dJz|; |dJx|, |dJy|, |dJz| without gravity).
      momentum_part = ''
      if (.not. ieee_is_nan(summary%angular_momentum_drift)) momentum_part = ', '// &
        drift_names(summary%conserved_momentum)//' <= '//scientific_text(summary%angular_momentum_drift, 2, width=9)
      ! dS and dV only for a model with an entropy (NaN for a mechanical one: V = E).
      thermal_part = ''
      if (.not. ieee_is_nan(summary%min_entropy_increment)) thermal_part = ', min dS = '// &
        scientific_text(summary%min_entropy_increment, 2, width=10)//' '//trim(summary%entropy_units)//', max dV = '// &
        scientific_text(summary%max_lyapunov_increment, 2, width=10)//' '//trim(summary%energy_units)
      write (output_unit, '(a)') config%output_file//': '//summary%status//', '//steps_done//' steps, energy balance <= '// &
        scientific_text(summary%energy_drift, 2, width=9)//thermal_part//momentum_part//', Newton/step '// &
        fixed_text(real(summary%newton_iterations, real64)/real(summary%steps_completed, real64), 2, width=6)//', '// &
        fixed_text(summary%wall_seconds, 3, width=8)//' s'
    end if
    if (stat == 0 .and. summary%rejected_steps > 0) write (output_unit, '(a, i0, a, i0, a)') '  step-size control: ', &
      summary%steps_completed, ' steps accepted, ', summary%rejected_steps, ' rejected'
    ! A complete run whose accuracy is in doubt (the file's attribute `warnings`; docs/integrators.md).
    if (stat == 0 .and. allocated(summary%warnings)) then
      if (len(summary%warnings) > 0) write (error_unit, '(a)') 'eme_run: warning: '//config%output_file//': '// &
        summary%warnings
    end if
    if (len(unused) > 0) write (error_unit, '(a)') 'eme_run: warning: PETSc options that nothing used: '//unused
  end subroutine run_case

  ! The output's lock for this process; exit_status 2 (held by another run) or 1 (no lock file).
  subroutine take_lock(lock)
    type(output_lock), intent(inout) :: lock
    character(len=:), allocatable :: holder
    integer :: found

    call lock_output(lock, config%output_file//'.lock', found, holder, failure)
    if (failure%failed()) then
      write (error_unit, '(a)') 'eme_run: cannot create the lock file '''//config%output_file//'.lock'' ('// &
        config%input_file//', &output: file): '//failure%message
      exit_status = 1
    else if (found == lock_held_elsewhere) then
      if (len(holder) == 0) holder = 'another process'
      write (error_unit, '(a)') 'eme_run: '//config%output_file//' (&output file in '//config%input_file// &
        ') is being written by '//holder//', which holds '//config%output_file//'.lock; this run is refused '// &
        'and writes nothing'
      exit_status = 2
    else if (found == lock_not_offered) then
      write (error_unit, '(a)') 'eme_run: warning: the file system of '//config%output_file//' offers no lock; '// &
        'a second run writing it at the same time would not be refused'
    end if
  end subroutine take_lock

  ! '|dJz|' for the names 'J_z'; '|dJx|, |dJy|, |dJz|' for 'J_x J_y J_z' (underscores dropped).
  pure function drift_names(names) result(text)
    character(len=*), intent(in) :: names
    character(len=:), allocatable :: text
    integer :: i, start
    logical :: word_ends

    text = ''
    start = 1
    do i = 1, len_trim(names) + 1
      word_ends = i > len_trim(names)
      if (.not. word_ends) word_ends = names(i:i) == ' '
      if (.not. word_ends) cycle
      if (i > start) then
        if (len(text) > 0) text = text//', '
        text = text//'|d'//without_underscores(names(start:i - 1))//'|'
      end if
      start = i + 1
    end do
  end function drift_names

  ! `name` without its underscores (J_z: Jz).
  pure function without_underscores(name) result(plain)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: plain
    integer :: i

    plain = ''
    do i = 1, len(name)
      if (name(i:i) /= '_') plain = plain//name(i:i)
    end do
  end function without_underscores

  ! A progress line on stderr (simulation sends one at most every 2 s).
  subroutine print_progress(text)
    character(len=*), intent(in) :: text

    write (error_unit, '(a)') 'eme_run: '//text
    flush (error_unit)
  end subroutine print_progress

end program eme_run
