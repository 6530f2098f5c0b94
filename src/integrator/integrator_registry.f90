!> Every integrator the code offers, in one table: its namelist name (&integrator scheme), its
!> family, what it supports and how to build it. The input's allowed values, the output's
!> attributes, --help and the Python scripts (through the attributes the output carries) all
!> take names and capabilities from here. Adding an integrator: write its module (extend
!> time_stepper, src/integrator/stepper) and add one row to `registered_integrators` in the
!> submodule src/integrator/integrator_registry_lines.f90 (an edit recompiles it alone); adding a
!> relaxed Runge-Kutta method: one line of src/integrator/butcher_tableaux's registered_tableaux,
!> whose rows this table takes in.
module integrator_registry
  use stepper, only: time_stepper
  use step_balances, only: balance_count
  implicit none (type, external)
  private
  public :: integrator_entry, registered_integrators, find_integrator, integrator_names, build_integrator
  public :: keeps_structure, chooses_times, all_balances, momentum_balance
  public :: family_discrete_gradient, family_petsc_ts, family_relaxation, family_sundials

  !> The guarantees of a structure-preserving scheme, and of one that keeps the momenta alone.
  logical, parameter :: all_balances(balance_count) = .true.
  logical, parameter :: momentum_balance(balance_count) = [.false., .true., .false., .false.]

  !> The families, as the output's `scheme_family` attribute names them.
  character(len=*), parameter :: family_discrete_gradient = 'discrete_gradient_step'  !! one SNES system per step
  character(len=*), parameter :: family_petsc_ts = 'petsc_ts'                         !! a PETSc TS method
  character(len=*), parameter :: family_relaxation = 'relaxation'                     !! relaxed Runge-Kutta
  character(len=*), parameter :: family_sundials = 'sundials_cvode'                   !! SUNDIALS CVODE

  abstract interface
    !> Allocates a new, unstarted integrator of the entry's kind.
    subroutine builder(integrator)
      import :: time_stepper
      class(time_stepper), allocatable, intent(out) :: integrator
    end subroutine builder
  end interface

  !> One integrator and its capabilities.
  type :: integrator_entry
    character(len=16) :: name = ''                  !! &integrator scheme = '<name>'
    character(len=24) :: family = ''
    character(len=16) :: label = ''                 !! plain name for figures (the paper's EME, MP, ...)
    character(len=100) :: description = ''
    logical :: takes_constraints = .false.
    logical :: uses_discrete_gradient = .false.     !! reads discrete_gradient and metric
    logical :: adaptive = .false.                   !! chooses its own steps (reads tolerance)
    !> Has a local error estimate or signal that &integrator tolerance switches on: EME and the
    !> midpoint rule then choose their steps, the fixed-step relaxed schemes reject a step whose
    !> relaxation parameter leaves its band.
    logical :: error_control = .false.
    logical :: reads_newton_settings = .true.       !! solves nonlinear systems with newton_tol, newton_max_iterations
    logical :: chooses_time = .false.               !! reaches times of its own (relaxation, adaptive steps)
    !> The balances (src/structure/step_balances: energy, momentum, entropy, lyapunov) it keeps on
    !> every accepted step to round-off, which the time loop checks after each step against their
    !> bounds (docs/faults.md): all four for EME and the relaxed schemes, the momenta for the
    !> midpoint rule, none for the baselines.
    logical :: guarantees(balance_count) = .false.
    !> Integrates the constrained flow in continuous time (the constraints' continuous forms,
    !> index-1 multipliers): the initial state must satisfy the hidden constraints too.
    logical :: continuous_constraints = .false.
    logical :: thermo_variables(3) = .true.         !! takes tau = s, theta, u (thermo_variable's tau_*)
    character(len=100) :: scheme_temperature = ''   !! what /scheme_temperature holds for it
    procedure(builder), pointer, nopass :: build => null()
  end type integrator_entry

  interface
    !> The table, a row per integrator (integrator_registry_lines).
    module function registered_integrators() result(entries)
      type(integrator_entry), allocatable :: entries(:)
    end function registered_integrators
  end interface

contains

  !> Whether the entry keeps the whole structure on every step (E, the conserved momenta, dS >= 0,
  !> dV <= 0); tests/e2e/test_conformance_steps checks it.
  pure logical function keeps_structure(entry)
    type(integrator_entry), intent(in) :: entry

    keeps_structure = all(entry%guarantees)
  end function keeps_structure

  !> Whether a run of `entry` chooses its steps' times (each row at the time its step reached, the
  !> last on t_end) rather than stepping on n dt: the relaxed schemes and the adaptive ones always,
  !> EME and the midpoint rule when &integrator tolerance is given (tolerance_given).
  pure logical function chooses_times(entry, tolerance_given)
    type(integrator_entry), intent(in) :: entry
    logical, intent(in) :: tolerance_given

    chooses_times = entry%chooses_time .or. (tolerance_given .and. entry%error_control)
  end function chooses_times

  !> A new, unstarted integrator of `entry`, knowing its registry name (the relaxed integrators
  !> take their tableau by it).
  subroutine build_integrator(entry, integrator)
    type(integrator_entry), intent(in) :: entry
    class(time_stepper), allocatable, intent(out) :: integrator

    call entry%build(integrator)
    integrator%scheme = entry%name
  end subroutine build_integrator

  !> The entry named `name` (found = .false. if there is none).
  subroutine find_integrator(name, entry, found)
    character(len=*), intent(in) :: name
    type(integrator_entry), intent(out) :: entry
    logical, intent(out) :: found
    type(integrator_entry), allocatable :: entries(:)
    integer :: i

    allocate (entries, source=registered_integrators())
    found = .false.
    do i = 1, size(entries)
      if (entries(i)%name /= name) cycle
      entry = entries(i)
      found = .true.
      return
    end do
  end subroutine find_integrator

  !> The names, blank-separated (those that take constraints only, if `constrained`).
  function integrator_names(constrained) result(list)
    logical, intent(in) :: constrained
    character(len=:), allocatable :: list
    type(integrator_entry), allocatable :: entries(:)
    integer :: i

    allocate (entries, source=registered_integrators())
    list = ''
    do i = 1, size(entries)
      if (constrained .and. .not. entries(i)%takes_constraints) cycle
      list = trim(list//' '//entries(i)%name)
    end do
    list = adjustl(list)
  end function integrator_names

end module integrator_registry
