!> The double pendulum's rungs (docs/formulation.md section 9) as the registry builds them, every one generated
!> from src/model/pendulum/description.py (paper_pendulum: spatial thermoviscoelastic; planar_pendulum;
!> thermoelastic_pendulum; planar_thermoelastic_pendulum; elastic_pendulum; planar_elastic_pendulum). &model's
!> values (pendulum_parameters, the scene's) become the generated model's parameters here, and back for the
!> fused step kernel (pendulum_step_kernel), which keeps the closed-form springs it was written around.
module pendulum_rungs
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters, law_thermoviscoelastic, law_thermoelastic, law_elastic
  use model_interface, only: generic_model
  use paper_pendulum_potential, only: paper_pendulum_parameters
  use paper_pendulum_model, only: paper_pendulum, make_paper_pendulum
  use planar_pendulum_potential, only: planar_pendulum_parameters
  use planar_pendulum_model, only: planar_pendulum, make_planar_pendulum
  use thermoelastic_pendulum_potential, only: thermoelastic_pendulum_parameters
  use thermoelastic_pendulum_model, only: thermoelastic_pendulum, make_thermoelastic_pendulum
  use planar_thermoelastic_pendulum_potential, only: planar_thermoelastic_pendulum_parameters
  use planar_thermoelastic_pendulum_model, only: planar_thermoelastic_pendulum, make_planar_thermoelastic_pendulum
  use elastic_pendulum_potential, only: elastic_pendulum_parameters
  use elastic_pendulum_model, only: elastic_pendulum, make_elastic_pendulum
  use planar_elastic_pendulum_potential, only: planar_elastic_pendulum_parameters
  use planar_elastic_pendulum_model, only: planar_elastic_pendulum, make_planar_elastic_pendulum
  implicit none (type, external)
  private
  public :: rung_model, rung_parameters

contains

  !> The generated model of the rung `params` declares (spring_law, dimension) in thermodynamic variable
  !> `variable` (the elastic rungs have none: their model keeps `variable` and ignores it).
  subroutine rung_model(params, variable, model)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: model

    associate (m => params%mass, l => params%natural_length, a => params%mu_eq_const, b => params%mu_eq_slope, &
               c => params%heat_capacity, g => params%gravity)
      if (params%spring_law == law_thermoviscoelastic .and. params%dimension == 3) then
        allocate (model, source=make_paper_pendulum(paper_pendulum_parameters(mass_1=m(1), mass_2=m(2), &
          natural_length_1=l(1), natural_length_2=l(2), mu_eq_const_1=a(1), mu_eq_const_2=a(2), mu_eq_slope_1=b(1), &
          mu_eq_slope_2=b(2), mu_neq_const=params%mu_neq_const, mu_neq_slope=params%mu_neq_slope, &
          heat_capacity_1=c(1), heat_capacity_2=c(2), viscosity_const=params%viscosity_const, &
          viscosity_activation=params%viscosity_activation, conductivity=params%conductivity, &
          theta_ref=params%theta_ref, beta=params%beta, beta_v=params%beta_v, gravity_x=g(1), gravity_y=g(2), &
          gravity_z=g(3)), variable))
      else if (params%spring_law == law_thermoviscoelastic) then
        allocate (model, source=make_planar_pendulum(planar_pendulum_parameters(mass_1=m(1), mass_2=m(2), &
          natural_length_1=l(1), natural_length_2=l(2), mu_eq_const_1=a(1), mu_eq_const_2=a(2), mu_eq_slope_1=b(1), &
          mu_eq_slope_2=b(2), mu_neq_const=params%mu_neq_const, mu_neq_slope=params%mu_neq_slope, &
          heat_capacity_1=c(1), heat_capacity_2=c(2), viscosity_const=params%viscosity_const, &
          viscosity_activation=params%viscosity_activation, conductivity=params%conductivity, &
          theta_ref=params%theta_ref, beta=params%beta, beta_v=params%beta_v, gravity_x=g(1), gravity_y=g(2)), &
          variable))
      else if (params%spring_law == law_thermoelastic .and. params%dimension == 3) then
        allocate (model, source=make_thermoelastic_pendulum(thermoelastic_pendulum_parameters(mass_1=m(1), &
          mass_2=m(2), natural_length_1=l(1), natural_length_2=l(2), mu_eq_const_1=a(1), mu_eq_const_2=a(2), &
          mu_eq_slope_1=b(1), mu_eq_slope_2=b(2), heat_capacity_1=c(1), heat_capacity_2=c(2), &
          conductivity=params%conductivity, theta_ref=params%theta_ref, beta=params%beta, gravity_x=g(1), &
          gravity_y=g(2), gravity_z=g(3)), variable))
      else if (params%spring_law == law_thermoelastic) then
        allocate (model, source=make_planar_thermoelastic_pendulum(planar_thermoelastic_pendulum_parameters( &
          mass_1=m(1), mass_2=m(2), natural_length_1=l(1), natural_length_2=l(2), mu_eq_const_1=a(1), &
          mu_eq_const_2=a(2), mu_eq_slope_1=b(1), mu_eq_slope_2=b(2), heat_capacity_1=c(1), heat_capacity_2=c(2), &
          conductivity=params%conductivity, theta_ref=params%theta_ref, beta=params%beta, gravity_x=g(1), &
          gravity_y=g(2)), variable))
      else if (params%dimension == 3) then
        allocate (model, source=make_elastic_pendulum(elastic_pendulum_parameters(mass_1=m(1), mass_2=m(2), &
          natural_length_1=l(1), natural_length_2=l(2), mu_eq_const_1=a(1), mu_eq_const_2=a(2), gravity_x=g(1), &
          gravity_y=g(2), gravity_z=g(3)), variable))
      else
        allocate (model, source=make_planar_elastic_pendulum(planar_elastic_pendulum_parameters(mass_1=m(1), &
          mass_2=m(2), natural_length_1=l(1), natural_length_2=l(2), mu_eq_const_1=a(1), mu_eq_const_2=a(2), &
          gravity_x=g(1), gravity_y=g(2)), variable))
      end if
    end associate
  end subroutine rung_model

  !> &model's values of `model`, a rung of rung_model's (its spring_law, dimension and parameters; the others
  !> Table 1's); found = .false. for any other model.
  pure subroutine rung_parameters(model, params, found)
    class(generic_model), intent(in) :: model
    type(pendulum_parameters), intent(out) :: params
    logical, intent(out) :: found

    found = .true.
    select type (model)
    type is (paper_pendulum)
      associate (p => model%parameters)
        params = pendulum_parameters(spring_law=law_thermoviscoelastic, dimension=3, mass=[p%mass_1, p%mass_2], &
          natural_length=[p%natural_length_1, p%natural_length_2], mu_eq_const=[p%mu_eq_const_1, p%mu_eq_const_2], &
          mu_eq_slope=[p%mu_eq_slope_1, p%mu_eq_slope_2], mu_neq_const=p%mu_neq_const, mu_neq_slope=p%mu_neq_slope, &
          heat_capacity=[p%heat_capacity_1, p%heat_capacity_2], viscosity_const=p%viscosity_const, &
          viscosity_activation=p%viscosity_activation, conductivity=p%conductivity, theta_ref=p%theta_ref, &
          beta=p%beta, beta_v=p%beta_v, gravity=[p%gravity_x, p%gravity_y, p%gravity_z])
      end associate
    type is (planar_pendulum)
      associate (p => model%parameters)
        params = pendulum_parameters(spring_law=law_thermoviscoelastic, dimension=2, mass=[p%mass_1, p%mass_2], &
          natural_length=[p%natural_length_1, p%natural_length_2], mu_eq_const=[p%mu_eq_const_1, p%mu_eq_const_2], &
          mu_eq_slope=[p%mu_eq_slope_1, p%mu_eq_slope_2], mu_neq_const=p%mu_neq_const, mu_neq_slope=p%mu_neq_slope, &
          heat_capacity=[p%heat_capacity_1, p%heat_capacity_2], viscosity_const=p%viscosity_const, &
          viscosity_activation=p%viscosity_activation, conductivity=p%conductivity, theta_ref=p%theta_ref, &
          beta=p%beta, beta_v=p%beta_v, gravity=[p%gravity_x, p%gravity_y, 0.0_real64])
      end associate
    type is (thermoelastic_pendulum)
      associate (p => model%parameters)
        params = pendulum_parameters(spring_law=law_thermoelastic, dimension=3, mass=[p%mass_1, p%mass_2], &
          natural_length=[p%natural_length_1, p%natural_length_2], mu_eq_const=[p%mu_eq_const_1, p%mu_eq_const_2], &
          mu_eq_slope=[p%mu_eq_slope_1, p%mu_eq_slope_2], heat_capacity=[p%heat_capacity_1, p%heat_capacity_2], &
          conductivity=p%conductivity, theta_ref=p%theta_ref, beta=p%beta, &
          gravity=[p%gravity_x, p%gravity_y, p%gravity_z])
      end associate
    type is (planar_thermoelastic_pendulum)
      associate (p => model%parameters)
        params = pendulum_parameters(spring_law=law_thermoelastic, dimension=2, mass=[p%mass_1, p%mass_2], &
          natural_length=[p%natural_length_1, p%natural_length_2], mu_eq_const=[p%mu_eq_const_1, p%mu_eq_const_2], &
          mu_eq_slope=[p%mu_eq_slope_1, p%mu_eq_slope_2], heat_capacity=[p%heat_capacity_1, p%heat_capacity_2], &
          conductivity=p%conductivity, theta_ref=p%theta_ref, beta=p%beta, &
          gravity=[p%gravity_x, p%gravity_y, 0.0_real64])
      end associate
    type is (elastic_pendulum)
      associate (p => model%parameters)
        params = pendulum_parameters(spring_law=law_elastic, dimension=3, mass=[p%mass_1, p%mass_2], &
          natural_length=[p%natural_length_1, p%natural_length_2], mu_eq_const=[p%mu_eq_const_1, p%mu_eq_const_2], &
          gravity=[p%gravity_x, p%gravity_y, p%gravity_z])
      end associate
    type is (planar_elastic_pendulum)
      associate (p => model%parameters)
        params = pendulum_parameters(spring_law=law_elastic, dimension=2, mass=[p%mass_1, p%mass_2], &
          natural_length=[p%natural_length_1, p%natural_length_2], mu_eq_const=[p%mu_eq_const_1, p%mu_eq_const_2], &
          gravity=[p%gravity_x, p%gravity_y, 0.0_real64])
      end associate
    class default
      found = .false.
    end select
  end subroutine rung_parameters

end module pendulum_rungs
