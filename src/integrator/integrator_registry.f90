!> Every integrator the code offers, in one table: its namelist name (&integrator scheme), its
!> family, what it supports and how to build it. The input's allowed values, the output's
!> attributes, --help and the Python scripts (through the attributes the output carries) all
!> take names and capabilities from here. Adding an integrator: write its module (extend
!> time_stepper, src/integrator/stepper) and add one row to `registered_integrators`; adding a
!> relaxed Runge-Kutta method: one line of src/integrator/butcher_tableaux's registered_tableaux,
!> whose rows this table takes in.
module integrator_registry
  use stepper, only: time_stepper
  use discrete_gradient_stepper, only: new_eme, new_midpoint
  use ts_stepper, only: new_ts_midpoint, new_ts_bdf2, new_ts_rk4, new_ts_rk5dp
  use relaxed_stepper, only: new_relaxed_runge_kutta
  use butcher_tableaux, only: butcher_tableau, tableau_entry, registered_tableaux
  use cvode_stepper, only: new_cvode_bdf, new_cvode_adams
  implicit none (type, external)
  private
  public :: integrator_entry, registered_integrators, find_integrator, integrator_names, build_integrator
  public :: family_discrete_gradient, family_petsc_ts, family_relaxation, family_sundials

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
    !> Integrates the constrained flow in continuous time (the constraints' continuous forms,
    !> index-1 multipliers): the initial state must satisfy the hidden constraints too.
    logical :: continuous_constraints = .false.
    logical :: thermo_variables(3) = .true.         !! takes tau = s, theta, u (thermo_variable's tau_*)
    character(len=100) :: scheme_temperature = ''   !! what /scheme_temperature holds for it
    procedure(builder), pointer, nopass :: build => null()
  end type integrator_entry

contains

  !> The table.
  function registered_integrators() result(entries)
    type(integrator_entry), allocatable :: entries(:)
    character(len=*), parameter :: ts_temperature = &
      'temperatures at the end of the step (PETSc TS baselines have no discrete temperature)'
    character(len=*), parameter :: cvode_temperature = &
      'temperatures at the end of the step (CVODE baselines have no discrete temperature)'
    character(len=*), parameter :: relaxed_temperature = &
      'temperatures at the end of the step (relaxed Runge-Kutta methods have no discrete temperature)'

    entries = [ &
      integrator_entry(name='eme', family=family_discrete_gradient, label='EME', &
        description='energy-momentum-entropy scheme (15): discrete gradients, one SNES system per step', &
        takes_constraints=.true., uses_discrete_gradient=.true., error_control=.true., build=new_eme, &
        scheme_temperature='discrete temperatures D_tau U_a / D_tau S_a of the step, where K0 is evaluated'), &
      integrator_entry(name='midpoint', family=family_discrete_gradient, label='MP', &
        description='implicit midpoint rule: the exact partials at the midpoint, one SNES system per step', &
        takes_constraints=.true., error_control=.true., build=new_midpoint, &
        scheme_temperature='temperatures at the step''s midpoint, where K0 is evaluated'), &
      integrator_entry(name='ts_midpoint', family=family_petsc_ts, label='TS-midpoint', &
        description='PETSc TSTHETA with theta = 1/2: the implicit midpoint rule with PETSc''s SNES defaults', &
        scheme_temperature=ts_temperature, build=new_ts_midpoint), &
      integrator_entry(name='ts_bdf2', family=family_petsc_ts, label='BDF2', description='PETSc TSBDF of order 2', &
        scheme_temperature=ts_temperature, build=new_ts_bdf2), &
      integrator_entry(name='ts_rk4', family=family_petsc_ts, label='RK4', &
        description='PETSc TSRK 4: the classic explicit Runge-Kutta method', reads_newton_settings=.false., &
        scheme_temperature=ts_temperature, build=new_ts_rk4), &
      integrator_entry(name='ts_rk5dp', family=family_petsc_ts, label='RK5DP', &
        description='PETSc TSRK 5dp: adaptive Dormand-Prince at tolerance, landing on every output time', &
        adaptive=.true., reads_newton_settings=.false., scheme_temperature=ts_temperature, build=new_ts_rk5dp), &
      relaxed_rows(), &
      integrator_entry(name='cvode_bdf', family=family_sundials, label='CVODE-BDF', &
        description='SUNDIALS CVODE: variable-order BDF, Newton with the analytic Jacobian, adaptive at tolerance', &
        adaptive=.true., reads_newton_settings=.false., scheme_temperature=cvode_temperature, build=new_cvode_bdf), &
      integrator_entry(name='cvode_adams', family=family_sundials, label='CVODE-Adams', &
        description='SUNDIALS CVODE: variable-order Adams-Moulton, fixed-point iteration, adaptive at tolerance', &
        adaptive=.true., reads_newton_settings=.false., scheme_temperature=cvode_temperature, build=new_cvode_adams)]

  contains

    ! A row per relaxed tableau, its capabilities from the tableau.
    function relaxed_rows() result(rows)
      type(integrator_entry), allocatable :: rows(:)
      type(tableau_entry), allocatable :: tableaux(:)
      type(butcher_tableau) :: tableau
      integer :: k

      allocate (tableaux, source=registered_tableaux())
      allocate (rows(size(tableaux)))
      do k = 1, size(tableaux)
        tableau = tableaux(k)%make()
        rows(k) = integrator_entry(name=tableaux(k)%name, family=family_relaxation, label=tableaux(k)%label, &
                                   description=tableaux(k)%description, adaptive=tableau%embedded, chooses_time=.true., &
                                   error_control=.not. tableau%embedded, reads_newton_settings=tableau%implicit, &
                                   scheme_temperature=relaxed_temperature, takes_constraints=.true., &
                                   continuous_constraints=.true., build=new_relaxed_runge_kutta)
      end do
    end function relaxed_rows
  end function registered_integrators


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
