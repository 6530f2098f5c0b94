!> eme_run FILE.nml [PETSc options]: one run of the thermoviscoelastic double pendulum.
!> Reads the namelist, integrates, writes the HDF5 file named in &output and prints a
!> one-line summary. Exit status: 0 complete, 2 bad input or usage (no output file is
!> written), 3 the run stopped early (the file is kept, marked incomplete), 1 I/O or PETSc error,
!> 128 + N after signal N (SIGTERM, SIGINT: the file is kept, marked incomplete).
!> eme_run --help (or -h), --integrators (the registry as a table) and --output-schema (the
!> HDF5 layout as a table) print and exit with status 0.
program eme_run
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit, real64
  use run_config, only: run_configuration, read_run_config
  use simulation, only: run_summary, run_simulation, run_exit_status => exit_status
  use run_options, only: progress_wanted
  use run_output, only: print_output_schema
  use command_help, only: print_run_help, print_integrators, has_argument
  implicit none

  type(run_configuration) :: config
  type(run_summary) :: summary
  character(len=4096) :: path
  character(len=:), allocatable :: message
  integer :: stat, exit_status
  PetscErrorCode :: ierr

  ! These need neither PETSc nor an input file.
  if (has_argument([character(len=6) :: '--help', '-h'])) then
    call print_run_help(output_unit)
    stop
  else if (has_argument(['--integrators'])) then
    call print_integrators(output_unit, tabular=.true.)
    stop
  else if (has_argument(['--output-schema'])) then
    call print_output_schema()
    stop
  end if
  PetscCallA(PetscInitialize(ierr))
  exit_status = 0
  if (command_argument_count() < 1) then
    write (error_unit, '(a)') 'usage: eme_run FILE.nml [PETSc options, e.g. -snes_monitor -snes_converged_reason]; '// &
      'eme_run --help tells more'
    exit_status = 2
  else
    call get_command_argument(1, path)
    call read_run_config(trim(path), config, stat, message)
    if (stat /= 0) then
      write (error_unit, '(a)') 'eme_run: '//message
      exit_status = 2
    else
      if (progress_wanted()) then
        call run_simulation(config, summary, stat, message, progress=print_progress)
      else
        call run_simulation(config, summary, stat, message)
      end if
      exit_status = run_exit_status(summary)
      if (stat /= 0) then
        write (error_unit, '(a)') 'eme_run: '//message
      else if (summary%status /= 'complete') then
        write (error_unit, '(a)') 'eme_run: '//config%output_file//': '//summary%status
        if (len(message) > 0) write (error_unit, '(a)') 'eme_run: '//message
      end if
      if (stat == 0) write (output_unit, '(a, ": ", a, ", ", i0, "/", i0, " steps, ", a, es9.2, a, es10.2, a, es10.2, a, &
        & es9.2, a, f6.2, a, f8.3, a)') config%output_file, summary%status, summary%steps_completed, &
        summary%steps_planned, 'energy balance <= ', summary%energy_drift, ', min dS = ', &
        summary%min_entropy_increment, ' J/K, max dV = ', summary%max_lyapunov_increment, ' J, |dJz| <= ', &
        summary%angular_momentum_drift, ', Newton/step ', &
        real(summary%newton_iterations, real64)/max(1, summary%steps_completed), ', ', summary%wall_seconds, ' s'
    end if
  end if
  PetscCallA(PetscFinalize(ierr))
  if (exit_status /= 0) stop exit_status, quiet=.true.

contains

  ! A progress line on stderr (simulation sends one at most every 2 s).
  subroutine print_progress(text)
    character(len=*), intent(in) :: text

    write (error_unit, '(a)') 'eme_run: '//text
    flush (error_unit)
  end subroutine print_progress

end program eme_run
