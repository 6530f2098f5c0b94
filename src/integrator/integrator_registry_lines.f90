!> The rows of the integrator registry (src/integrator/integrator_registry), and of the relaxed
!> Runge-Kutta methods the tableaux' table names. A submodule, so that an edit recompiles this
!> file alone and the programs relink.
submodule (integrator_registry) integrator_registry_lines
  use discrete_gradient_stepper, only: new_eme, new_midpoint
  use ts_stepper, only: new_ts_midpoint, new_ts_bdf2, new_ts_rk4, new_ts_rk5dp
  use relaxed_stepper, only: new_relaxed_runge_kutta
  use butcher_tableaux, only: butcher_tableau, tableau_entry, registered_tableaux
  use cvode_stepper, only: new_cvode_bdf, new_cvode_adams
  implicit none (type, external)

contains

  module procedure registered_integrators
    character(len=*), parameter :: ts_temperature = &
      'temperatures at the end of the step (PETSc TS baselines have no discrete temperature)'
    character(len=*), parameter :: cvode_temperature = &
      'temperatures at the end of the step (CVODE baselines have no discrete temperature)'
    character(len=*), parameter :: relaxed_temperature = &
      'temperatures at the end of the step (relaxed Runge-Kutta methods have no discrete temperature)'

    entries = [ &
      integrator_entry(name='eme', family=family_discrete_gradient, label='EME', &
        description='energy-momentum-entropy scheme (15): discrete gradients, one SNES system per step', &
        takes_constraints=.true., uses_discrete_gradient=.true., error_control=.true., guarantees=all_balances, build=new_eme, &
        scheme_temperature='discrete temperatures D_tau U_a / D_tau S_a of the step, where K0 is evaluated'), &
      integrator_entry(name='midpoint', family=family_discrete_gradient, label='MP', &
        description='implicit midpoint rule: the exact partials at the midpoint, one SNES system per step', &
        takes_constraints=.true., error_control=.true., guarantees=momentum_balance, build=new_midpoint, &
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
                                   continuous_constraints=.true., guarantees=all_balances, build=new_relaxed_runge_kutta)
      end do
    end function relaxed_rows
  end procedure registered_integrators

end submodule integrator_registry_lines
