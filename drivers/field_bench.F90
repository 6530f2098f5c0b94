!> field_bench FILE.nml EVALUATIONS [VARIABLE]: evaluates the GENERIC field z' = f(z) of FILE.nml's
!> scene (the model the registry builds for it: model_interface's `continuous_field`) EVALUATIONS
!> times at its initial state, in the thermodynamic variable VARIABLE (entropy, the default, as
!> the relaxed schemes evaluate it; temperature, as drivers/cvode_baseline.c's C field; or
!> internal_energy), and prints a checksum of the last field. make bench runs it under callgrind at two counts
!> (postprocess/bench_field.py): the difference of their instructions over the difference of the
!> counts is the instructions of one evaluation, start-up and set-up cancelling. Each evaluation's
!> state is moved by a last-digit amount taken from the previous field, so no evaluation can be
!> skipped as a repeat of the one before.
!> Exit status: 0 evaluated, 2 bad input or usage, 1 the field failed at the state.
!> --help, -h, -help and --version print and exit with status 0.
program field_bench
#include <petsc/finclude/petscsys.h>
  use petscsys
  use, intrinsic :: iso_fortran_env, only: real64, error_unit, output_unit
  use run_config, only: run_configuration, read_run_config
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use thermo_variable_kinds, only: thermo_variable_names
  use library_versions, only: print_versions
  use command_line, only: has_argument
  use failures, only: failure_type
  implicit none

  type(run_configuration) :: config
  class(generic_model), allocatable :: model
  type(constraint_slot), allocatable :: constraints(:)
  real(real64), allocatable :: z0(:), z(:), f(:)
  character(len=4096) :: input, count_text, variable
  integer :: evaluations, e, stat, read_status, exit_status, tau
  type(failure_type) :: failure
  PetscErrorCode :: ierr

  if (has_argument([character(len=6) :: '--help', '-h', '-help'])) then
    call print_usage(output_unit)
    stop
  else if (has_argument(['--version'])) then
    call print_versions(output_unit, 'field_bench')
    stop
  end if
  if (command_argument_count() < 2 .or. command_argument_count() > 3) then
    call print_usage(error_unit)
    stop 2, quiet=.true.
  end if
  call get_command_argument(1, input)
  call get_command_argument(2, count_text)
  read (count_text, *, iostat=read_status) evaluations
  if (read_status /= 0 .or. evaluations < 1) then
    write (error_unit, '(a)') 'field_bench: EVALUATIONS must be a whole number >= 1, not '''//trim(count_text)//''''
    stop 2, quiet=.true.
  end if
  variable = 'entropy'
  if (command_argument_count() == 3) call get_command_argument(3, variable)
  tau = findloc(thermo_variable_names, trim(variable), dim=1)
  if (tau == 0) then
    write (error_unit, '(a)') 'field_bench: VARIABLE must be entropy, temperature or internal_energy, not '''// &
      trim(variable)//''''
    stop 2, quiet=.true.
  end if
  PetscCallA(PetscInitializeNoArguments(ierr))
  exit_status = 0
  call read_run_config(trim(input), config, failure)
  if (.not. failure%failed()) call config%scene%build(tau, model, z0, constraints, failure)
  if (failure%failed()) then
    write (error_unit, '(a)') 'field_bench: '//trim(input)//': '//failure%text()
    exit_status = 2
  else
    allocate (f(size(z0)))
    z = z0
    f = 0.0_real64
    do e = 1, evaluations
      z(1) = z0(1) + epsilon(1.0_real64)*abs(z0(1))*sign(1.0_real64, f(1))
      call model%continuous_field(z, f, stat)
      if (stat /= 0) exit
    end do
    if (stat /= 0) then
      write (error_unit, '(a,i0)') 'field_bench: the field failed at the initial state of '//trim(input)// &
        ' with status ', stat
      exit_status = 1
    else
      write (output_unit, '(a,i0,a,es24.16)') 'field_bench: ', evaluations, ' evaluations, sum |f| = ', sum(abs(f))
    end if
  end if
  PetscCallA(PetscFinalize(ierr))
  if (exit_status /= 0) stop exit_status, quiet=.true.

contains

  !> The usage line and what the program prints.
  subroutine print_usage(unit)
    integer, intent(in) :: unit

    write (unit, '(a)') 'usage: field_bench FILE.nml EVALUATIONS [VARIABLE] (evaluates the scene''s field '// &
      'EVALUATIONS times at its initial state in VARIABLE: entropy (default), temperature or internal_energy; '// &
      'make bench counts its instructions)', &
      '--help, -h, -help: this text; --version: the code''s and the libraries'' versions. Exit status: 0 '// &
      'evaluated, 2 bad input or usage, 1 the field failed.'
  end subroutine print_usage

end program field_bench
