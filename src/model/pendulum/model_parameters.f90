!> Material and mechanical data of the double pendulum, and the parts its scene declares.
!> Names follow the &model namelist group; defaults are the paper's Table 1.
module model_parameters
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: pendulum_parameters, law_thermoviscoelastic, law_thermoelastic, law_elastic, spring_law_names

  !> The rungs of the ladder (docs/formulation.md section 9), `spring_law`'s values.
  character(len=*), parameter :: law_thermoviscoelastic = 'thermoviscoelastic'
  character(len=*), parameter :: law_thermoelastic = 'thermoelastic'
  character(len=*), parameter :: law_elastic = 'elastic'
  character(len=*), parameter :: spring_law_names = law_thermoviscoelastic//' '//law_thermoelastic//' '//law_elastic

  !> Table 1 of the paper, in SI units (docs/formulation.md section 1: treat all values as plain SI numbers).
  type :: pendulum_parameters
    character(len=24) :: spring_law = law_thermoviscoelastic        !! the rung: elastic, thermoelastic or thermoviscoelastic
    integer :: dimension = 3                                          !! 3: spatial; 2: planar, y vertical
    real(real64) :: mass(2) = [1.0_real64, 1.0_real64]                !! m_a [kg]
    real(real64) :: natural_length(2) = [1.5_real64, 2.0_real64]      !! lambda_a^0 [m]
    real(real64) :: mu_eq_const(2) = [200.0_real64, 200.0_real64]     !! mu^eq_{a,cst}, eq. (17) [J]
    real(real64) :: mu_eq_slope(2) = [0.5_real64, 0.5_real64]         !! mu^eq_{a,theta}, eq. (17) [J/K]
    real(real64) :: mu_neq_const = 5.0_real64                         !! mu^neq_{2,cst}, eq. (17)
    real(real64) :: mu_neq_slope = 0.1_real64                         !! mu^neq_{2,theta}, eq. (17)
    real(real64) :: heat_capacity(2) = [10.0_real64, 10.0_real64]     !! c_a^0, eq. (16) [J/K]
    real(real64) :: viscosity_const = 100.0_real64                    !! eta_cst, eq. (17)
    real(real64) :: viscosity_activation = 10.0_real64                !! eta_theta, eq. (17) [K]
    real(real64) :: conductivity = 1.0_real64                         !! kappa, eq. (12) [J/(K s)]
    real(real64) :: theta_ref = 300.0_real64                          !! theta_ref [K]
    real(real64) :: beta = 0.02_real64                                !! thermal coupling beta [J/K]
    real(real64) :: beta_v = 0.5_real64                               !! Maxwell coupling beta^v
    real(real64) :: gravity(3) = [0.0_real64, 0.0_real64, -9.81_real64] !! g [m/s^2]
  contains
    procedure :: viscous
    procedure :: thermal
  end type pendulum_parameters

contains

  !> True for the thermoviscoelastic law: spring 2 has the Maxwell branch and gamma.
  pure logical function viscous(self)
    class(pendulum_parameters), intent(in) :: self

    viscous = self%spring_law == law_thermoviscoelastic
  end function viscous

  !> True for the thermal laws: each spring has a thermodynamic variable and a temperature.
  pure logical function thermal(self)
    class(pendulum_parameters), intent(in) :: self

    thermal = self%spring_law /= law_elastic
  end function thermal

end module model_parameters
