!> What a run split over ranks (src/run/distributed_simulation) is before its time loop: whether a
!> run goes to the split path, the split model of its scene for its integrator with the settings
!> its steps need, the path's own per-step figures, and the set-up that refuses what the path
!> cannot run before anything is written (docs/performance.md, Which path serves which model).
module split_run_setup
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use distributed_model, only: distributed_system, distributed_settings
  use integrator_registry, only: integrator_entry, find_integrator, family_discrete_gradient
  use distributed_step_control, only: controlled_system
  use butcher_tableaux, only: butcher_tableau, tableau_named
  use stepper, only: step_diagnostic
  use run_config, only: run_configuration
  use failures, only: failure_type, set_failure => fail, code_input => failure_input
  implicit none (type, external)
  private
  public :: split_run_wanted, distributed_settings_of, split_system, set_up_distributed_only, diagnostics

contains

  !> Whether `config`'s run goes to the split path on `ranks` ranks: its model can be split
  !> (model_scene's `distributed`) and it runs on several ranks or has more than `dense_limit`
  !> unknowns (the dense path's). A scene that cannot be built is left to the caller's run.
  logical function split_run_wanted(config, ranks, dense_limit)
    type(run_configuration), intent(in) :: config
    integer, intent(in) :: ranks, dense_limit
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)
    type(failure_type) :: building

    call config%scene%distributed(config%integrator%scheme, system)
    split_run_wanted = allocated(system)
    if (.not. split_run_wanted .or. ranks > 1) return
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, building)
    split_run_wanted = .not. building%failed() .and. size(z0) > dense_limit
  end function split_run_wanted

  !> What the split path's steps need of the input's &integrator.
  function distributed_settings_of(config) result(settings)
    type(run_configuration), intent(in) :: config
    type(distributed_settings) :: settings
    type(butcher_tableau) :: tableau
    logical :: found

    settings%input_file = config%input_file
    settings%scheme = config%integrator%scheme
    settings%discrete_gradient = config%integrator%discrete_gradient
    settings%metric = config%integrator%metric
    settings%newton_tol = config%integrator%newton_tol
    settings%newton_max_iterations = config%integrator%newton_max_iterations
    settings%tolerance_given = config%integrator%tolerance_given
    settings%tolerance = config%integrator%tolerance
    settings%dt = config%integrator%dt
    settings%t_end = config%integrator%t_end
    call tableau_named(config%integrator%scheme, tableau, found)
    if (.not. found) return
    settings%stage_matrix = tableau%a
    settings%weights = tableau%b
    settings%order = tableau%order
    settings%implicit_stages = tableau%implicit
    settings%embedded_weights = tableau%embedded
  end function distributed_settings_of

  !> The split model of `config`'s scene for its integrator: EME's and the midpoint rule's steps
  !> under the dense path's control (src/integrator/distributed_step_control: halving, adaptive
  !> steps), others as the scene gives them; a failure (failure_input) for &output interval,
  !> which the split path's rows do not follow.
  subroutine split_system(config, system, failure)
    type(run_configuration), intent(in) :: config
    class(distributed_system), allocatable, intent(out) :: system
    type(failure_type), intent(out) :: failure
    type(integrator_entry) :: entry
    type(controlled_system), allocatable :: controlled
    logical :: found

    if (config%output_interval > 0.0_real64) then
      call set_failure(failure, code_input, config%input_file//', &output: interval: a run split over ranks '// &
                       'writes its rows every &output every accepted steps, not at output times; allowed: leave it '// &
                       'out (0)', 'interval')
      return
    end if
    call config%scene%distributed(config%integrator%scheme, system)
    call find_integrator(config%integrator%scheme, entry, found)
    if (.not. found .or. entry%family /= family_discrete_gradient) return
    allocate (controlled)
    call move_alloc(system, controlled%inner)
    call move_alloc(controlled, system)
  end subroutine split_system

  !> Sets the split model up on `comm` and frees it again, writing nothing (as simulation's
  !> set_up_only): what the path cannot run, and PETSc options it cannot take, are refused
  !> (failure_input) before anything is written.
  subroutine set_up_distributed_only(config, comm, failure)
    type(run_configuration), intent(in) :: config
    integer, intent(in) :: comm
    type(failure_type), intent(out) :: failure
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)

    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, failure)
    if (failure%failed()) then
      call set_failure(failure, failure%code, config%input_file//': '//failure%message)
      return
    end if
    call split_system(config, system, failure)
    if (failure%failed()) return
    call system%start(distributed_settings_of(config), model, z0, comm, failure)
    if (failure%failed() .and. failure%code /= code_input) &
      call set_failure(failure, code_input, config%input_file//': the split run could not be set up with the '// &
                       'options given: '//failure%message)
    call system%finish(failure)
  end subroutine set_up_distributed_only

  !> The per-step figures of the split path beyond the schema's.
  function diagnostics() result(items)
    type(step_diagnostic) :: items(2)

    items(1) = step_diagnostic('min_viscous_production', 'W/K', 'the step''s smallest entropy production of a '// &
                               'spring''s viscous branch, Theta y^2/eta (docs/formulation.md section 10); NaN '// &
                               'without viscous branches', 'min')
    items(2) = step_diagnostic('min_link_production', 'W/K', 'the step''s smallest entropy production of a '// &
                               'conducting link, kappa (Theta_a - Theta_b)^2/(Theta_a Theta_b); NaN without links', &
                               'min')
  end function diagnostics

end module split_run_setup
