!> What a run split over ranks (src/run/distributed_simulation) is before its time loop: whether a
!> run goes to the split path, the split model of its scene for its integrator with the settings
!> its steps need, the path's own per-step figures, and the set-up that refuses what the path
!> cannot run before anything is written (docs/performance.md, Which path serves which model).
module split_run_setup
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use distributed_model, only: distributed_system, distributed_settings, distributed_step, distributed_figures
  use integrator_registry, only: integrator_entry, find_integrator, family_discrete_gradient, build_integrator, &
                                 chooses_times
  use distributed_step_control, only: controlled_system, controlled_diagnostics
  use butcher_tableaux, only: tableau_named
  use stepper, only: time_stepper, step_report, step_diagnostic
  use step_balances, only: balanced_state
  use run_config, only: run_configuration
  use command_line, only: petsc_error_text
  use failures, only: failure_type, set_failure => fail, code_input => failure_input
  use dense_setup, only: dense_max_unknowns
  use run_options, only: split_requested, dense_requested
  implicit none (type, external)
  private
  public :: split_run_wanted, distributed_settings_of, split_system, set_up_distributed_only, split_diagnostics
  public :: split_steps_chosen
  public :: report_step, balanced_state_of

  !> Beyond this many unknowns an integrator that solves equations takes a splittable model to the
  !> split path on one process: its sparse LU beat the dense one from between 72 and 100 unknowns
  !> for EME and the midpoint rule, from 48 for PETSc's BDF2 and midpoint, below 32 for
  !> relaxed_gauss6 (docs/performance.md, Which path is faster).
  integer, parameter :: split_from_unknowns = 64

contains

  !> Whether `config`'s run goes to the split path on `ranks` ranks: its model can be split
  !> (model_scene's `distributed`) and it runs on several ranks, or on one process with -eme_split,
  !> or, unless -eme_dense, has more than `dense_max_unknowns` unknowns (the dense path's limit), or
  !> more than `split_from_unknowns` with an integrator that solves equations (docs/performance.md,
  !> Which path is faster: the dense LU grows like n^3). A scene that cannot be built is left to
  !> the caller's run.
  logical function split_run_wanted(config, ranks)
    type(run_configuration), intent(in) :: config
    integer, intent(in) :: ranks
    class(distributed_system), allocatable :: system
    class(generic_model), allocatable :: model
    real(real64), allocatable :: z0(:)
    type(constraint_slot), allocatable :: constraints(:)
    type(failure_type) :: building
    type(integrator_entry) :: entry
    logical :: found, forced_split, forced_dense

    forced_split = split_requested()
    forced_dense = dense_requested()
    call config%scene%distributed(config%integrator%scheme, system)
    split_run_wanted = allocated(system)
    if (.not. split_run_wanted .or. ranks > 1 .or. forced_split) return
    call config%scene%build(config%integrator%thermo_variable, model, z0, constraints, building)
    split_run_wanted = .false.
    if (building%failed() .or. forced_dense) return
    call find_integrator(config%integrator%scheme, entry, found)
    split_run_wanted = size(z0) > dense_max_unknowns .or. &
                       (found .and. entry%reads_newton_settings .and. size(z0) > split_from_unknowns)
  end function split_run_wanted

  !> Whether the split path's steps are the integrator's own, each reporting the time it reached, as
  !> on the dense path (integrator_registry's chooses_times): the relaxed family's, and EME's and the
  !> midpoint rule's with &integrator tolerance; the others land on n dt.
  logical function split_steps_chosen(config)
    type(run_configuration), intent(in) :: config
    type(integrator_entry) :: entry
    logical :: found

    call find_integrator(config%integrator%scheme, entry, found)
    split_steps_chosen = found .and. chooses_times(entry, config%integrator%tolerance_given)
  end function split_steps_chosen

  !> What the split path's steps need of the input's &integrator.
  function distributed_settings_of(config) result(settings)
    type(run_configuration), intent(in) :: config
    type(distributed_settings) :: settings
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
    call tableau_named(config%integrator%scheme, settings%tableau, found)     ! no stages when not found
  end function distributed_settings_of

  !> The split model of `config`'s scene for its integrator: EME's and the midpoint rule's steps
  !> under the dense path's control (src/integrator/distributed_step_control: halving, adaptive
  !> steps), others as the scene gives them; a failure (failure_input) for &output interval
  !> unless the steps are chosen (a relaxed scheme, or &integrator tolerance with EME or the
  !> midpoint rule), or with snapshot_every as well.
  subroutine split_system(config, system, failure)
    type(run_configuration), intent(in) :: config
    class(distributed_system), allocatable, intent(out) :: system
    type(failure_type), intent(out) :: failure
    type(integrator_entry) :: entry
    type(controlled_system), allocatable :: controlled
    logical :: found

    call find_integrator(config%integrator%scheme, entry, found)
    if (config%output_interval > 0.0_real64) then
      if (.not. split_steps_chosen(config)) then
        call set_failure(failure, code_input, config%input_file//', &output: interval: a run split over ranks '// &
                         'lands on output times only with steps it chooses (a relaxed scheme, or &integrator '// &
                         'tolerance with scheme = ''eme'' or ''midpoint''); scheme = '''//trim(config%integrator%scheme)// &
                         ''' steps on n dt here; allowed: leave it out (0), or give a tolerance', 'interval')
        return
      else if (config%snapshot_every > 0) then
        call set_failure(failure, code_input, config%input_file//', &output: interval and snapshot_every both '// &
                         'given: with an interval the snapshots are taken at the output times; allowed: one of them', &
                         'snapshot_every')
        return
      end if
    end if
    call config%scene%distributed(config%integrator%scheme, system)
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
                       'options given: '//failure%message//library_words()//'; allowed: the options of '// &
                       'docs/running.md and PETSc''s own (eme_run FILE.nml -help lists them)')
    call system%finish(failure)

  contains

    ! PETSc's own words on the failed call (an unknown -snes_type, ...), if it left any.
    function library_words() result(text)
      character(len=:), allocatable :: text

      text = petsc_error_text()
      if (len(text) > 0) text = ' ('//text//')'
    end function library_words
  end subroutine set_up_distributed_only

  !> The integrator's per-step figures in a split run's file: the step control's
  !> (controlled_diagnostics), or those the dense path's integrator of the same name declares for
  !> a system that runs it on its own steps (a relaxed scheme's); the model's two production
  !> minima follow (src/run/run_file_steps adds a model's own figures).
  function split_diagnostics(system, entry) result(items)
    class(distributed_system), intent(in) :: system
    type(integrator_entry), intent(in) :: entry
    type(step_diagnostic), allocatable :: items(:)
    class(time_stepper), allocatable :: integrator
    type(step_diagnostic), allocatable :: integrator_diagnostics(:)

    allocate (integrator_diagnostics(0))
    if (system%integrator_diagnostics()) then
      call build_integrator(entry, integrator)
      integrator_diagnostics = integrator%diagnostics()
    end if
    items = [controlled_diagnostics(system), integrator_diagnostics]
  end function split_diagnostics

  !> The row of a split step (`outcome`, its figures `values`) in the dense path's step report:
  !> the solver's counts, then the integrator's figures and the two production minima (NaN
  !> where the chain has no such branch or link).
  pure subroutine report_step(outcome, values, report)
    type(distributed_step), intent(in) :: outcome
    type(distributed_figures), intent(in) :: values
    type(step_report), intent(inout) :: report

    report%newton_iterations = outcome%iterations
    report%solves = outcome%solves
    report%rejected = outcome%rejected
    report%residual_norm = outcome%residual_norm
    report%converged_reason = outcome%reason
    report%diagnostics = [values%min_viscous_production, values%min_link_production]
    where (report%diagnostics >= huge(1.0_real64)) report%diagnostics = ieee_value(1.0_real64, ieee_quiet_nan)
    if (allocated(outcome%diagnostics)) report%diagnostics = [outcome%diagnostics, report%diagnostics]
  end subroutine report_step

  !> The balances' state (src/structure/step_balances) of a split state's summed figures.
  pure function balanced_state_of(values) result(state)
    type(distributed_figures), intent(in) :: values
    type(balanced_state) :: state

    state%energy = values%energy
    state%energy_scale = values%energy_scale
    state%entropy = values%entropy
    state%entropy_scale = values%entropy_scale
    state%conserved_count = values%conserved_count
    state%conserved = values%conserved
    state%momentum_scale = values%momentum_scale
  end function balanced_state_of

end module split_run_setup
