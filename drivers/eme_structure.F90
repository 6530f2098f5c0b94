!> eme_structure FILE.nml OUT.h5: the GENERIC structure of FILE.nml's scene at its initial state:
!> the matrices L and K of eq. (8) with grad E and grad S, for each thermodynamic variable, into
!> OUT.h5 (src/run/structure_file). postprocess/plot_structure.py draws them (the paper's Fig. 2).
!> Exit status: 0 written, 2 bad input or usage (nothing written), 1 HDF5 failed. --help, -h, -help
!> and --version print and exit with status 0.
program eme_structure
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use run_config, only: run_configuration, read_run_config
  use structure_file, only: write_structure_file
  use library_versions, only: print_versions
  use command_line, only: has_argument
  use failures, only: failure_type
  implicit none

  type(run_configuration) :: config
  character(len=4096) :: input, output
  integer :: exit_status
  type(failure_type) :: failure
  PetscErrorCode :: ierr

  ! --help, -h, PETSc's -help and --version answer at once, wherever they stand.
  if (has_argument([character(len=6) :: '--help', '-h', '-help'])) then
    call print_usage(output_unit)
    stop
  else if (has_argument(['--version'])) then
    call print_versions(output_unit, 'eme_structure')
    stop
  end if
  if (command_argument_count() /= 2) then
    call print_usage(error_unit)
    stop 2, quiet=.true.
  end if
  call get_command_argument(1, input)
  call get_command_argument(2, output)
  PetscCallA(PetscInitializeNoArguments(ierr))
  exit_status = 0
  call read_run_config(trim(input), config, failure)
  if (failure%failed()) then
    write (error_unit, '(a)') 'eme_structure: '//failure%text()
    exit_status = 2
  else
    call write_structure_file(config, trim(output), failure)
    if (failure%failed()) then
      write (error_unit, '(a)') 'eme_structure: '//failure%text()
      exit_status = 1
    else
      write (output_unit, '(a)') 'eme_structure: wrote '//trim(output)
    end if
  end if
  PetscCallA(PetscFinalize(ierr))
  if (exit_status /= 0) stop exit_status, quiet=.true.

contains

  !> The usage line and what the program writes.
  subroutine print_usage(unit)
    integer, intent(in) :: unit

    write (unit, '(a)') 'usage: eme_structure FILE.nml OUT.h5 (L, K, grad E, grad S of the scene at its '// &
      'initial state, for each thermodynamic variable)', &
      '--help, -h, -help: this text; --version: the code''s and the libraries'' versions. Exit status: 0 '// &
      'written, 2 bad input or usage (nothing written), 1 HDF5 failed.'
  end subroutine print_usage

end program eme_structure
