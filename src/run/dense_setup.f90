!> What the dense run (src/run/simulation) checks before its time loop: the model's size against
!> the dense solvers' limit, and the integrator set up and freed again with every option read, so
!> that the drivers refuse bad PETSc options with nothing written.
module dense_setup
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry, find_integrator, build_integrator
  use stepper, only: time_stepper
  use run_config, only: run_configuration
  use command_line, only: petsc_error_text
  use number_text, only: integer_text
  use failures, only: failure_type, set_failure => fail, code_input => failure_input, code_library => failure_library
  implicit none (type, external)
  private
  public :: dense_max_unknowns, set_up_only, check_dense_size, setup_failure_text

  !> The most unknowns the dense solvers take: an 8 MB Jacobian, about 1e9 flops an LU.
  integer, parameter :: dense_max_unknowns = 1000

contains

  !> Sets up the run's integrator and frees it again, without integrating or writing anything:
  !> every option it reads is read (PETSc's -help lists them), so the drivers call it before a
  !> run to refuse bad PETSc options (an unknown type) with nothing written. A failure if the
  !> scene cannot be built (its domain code) or PETSc fails (failure_library, in PETSc's words).
  subroutine set_up_only(config, failure)
    type(run_configuration), intent(in) :: config
    type(failure_type), intent(out) :: failure
    class(time_stepper), allocatable :: integrator
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)
    type(integrator_entry) :: entry
    real(real64), allocatable :: z0(:)
    logical :: found
    type(failure_type) :: release_failure, building

    call find_integrator(config%integrator%scheme, entry, found)
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, building)
    if (.not. building%failed()) call check_dense_size(size(z0), building)
    if (building%failed()) then
      ! The scene's words with the input file, as the time loop gives them.
      call set_failure(failure, building%code, config%input_file//': '//building%message)
      return
    end if
    call build_integrator(entry, integrator)
    call integrator%start(config%integrator, model, constraints, z0, failure)
    ! PETSc's own words say what was refused; the message is the whole story (the drivers print it
    ! as before), so the PETSc procedure's origin is not added.
    ! A refusal of the solver's own (failure_input) says what and why in its words.
    if (failure%failed() .and. failure%code /= code_input) call set_failure(failure, code_input, setup_failure_text())
    call integrator%release(release_failure)
    if (.not. failure%failed() .and. release_failure%failed()) &
      call set_failure(failure, code_library, 'PETSc could not free the solver: '//petsc_error_text(), &
                       'set_up_only')
  end subroutine set_up_only

  !> The time loop's solvers are dense (Jacobian and LU of state_size^2 numbers, state_size^3 work):
  ! a larger model is refused before anything is allocated.
  subroutine check_dense_size(unknowns, failure)
    integer, intent(in) :: unknowns
    type(failure_type), intent(inout) :: failure

    if (unknowns <= dense_max_unknowns) return
    call set_failure(failure, code_input, '&model: '//integer_text(unknowns)//' unknowns; the dense path (eme_run '// &
                     'on one rank, an eme_ensemble case) takes at most '//integer_text(dense_max_unknowns)// &
                     ' (state_size^2 memory, state_size^3 work); a longer spring chain runs on the sparse, '// &
                     'distributed path: eme_run FILE.nml (without -eme_dense), or mpirun -n P eme_run FILE.nml '// &
                     '(docs/performance.md)')
  end subroutine check_dense_size

  !> Why the solver could not be set up: PETSc's own words (an unknown -snes_type, ...).
  function setup_failure_text() result(text)
    character(len=:), allocatable :: text

    text = 'PETSc could not set up the solver with the options given: '//petsc_error_text()// &
           '; allowed: the options of docs/running.md and PETSc''s own (eme_run FILE.nml -help lists them)'
  end function setup_failure_text

end module dense_setup
