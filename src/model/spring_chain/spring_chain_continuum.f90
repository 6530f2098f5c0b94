!> The continuum family (docs/formulation.md section 10): a thermoviscoelastic rod's data, per unit
!> length or per cross-section, and the springs, masses and links of its discretisation by n_s
!> linear elements of length h = L/n_s with lumped masses. Energies per element scale with h:
!> masses, natural lengths, the equilibrium stiffness mu^eq = EA h, its slope, beta and the heat
!> capacities with L/N; the Maxwell stiffness, the viscosity and the link conductances with N/L.
!> Refining N converges to the rod, and an explicit step must shrink like 1/N^2 (the discrete heat
!> equation's fastest rate, 4 kappa/Cap = 4 kA/(c (1 + beta_v) h^2)).
module spring_chain_continuum
  use, intrinsic :: iso_fortran_env, only: real64
  use spring_chain_spring, only: spring_data
  implicit none (type, external)
  private
  public :: rod_data, rod_springs

  !> A rod in SI units (section 10's table).
  type :: rod_data
    real(real64) :: length = 1.0_real64                !! L [m], natural
    real(real64) :: mass_per_length = 1.0_real64       !! rho A [kg/m]
    real(real64) :: axial_stiffness = 1.0e3_real64     !! EA [N]
    real(real64) :: stiffness_slope = 0.0_real64       !! -d(EA)/dtheta [N/K], a softening rate (the paper's sign)
    real(real64) :: thermal_stress = 0.0_real64        !! E A alpha [N/K]
    real(real64) :: heat_capacity = 1.0_real64         !! c [J/(K m)]
    real(real64) :: beta_v = 0.0_real64                !! Maxwell coupling [-]
    real(real64) :: maxwell_stiffness = 0.0_real64     !! E^neq A [N], half the Maxwell modulus (the paper's mu^neq gamma^2)
    real(real64) :: maxwell_slope = 0.0_real64         !! -d(E^neq A)/dtheta [N/K]
    real(real64) :: viscosity = 1.0_real64             !! eta A [N s]
    real(real64) :: viscosity_activation = 0.0_real64  !! eta_theta [K]
    real(real64) :: conductivity = 0.0_real64          !! k A [W m/K]
    real(real64) :: theta_ref = 300.0_real64           !! [K]
  end type rod_data

contains

  !> The rod's n_s springs (spring), the masses of its N moving nodes (n_s with 'fixed-free',
  !> the free end's half an element's; n_s - 1 with 'fixed-fixed') and the n_s - 1 link conductances.
  pure subroutine rod_springs(rod, fixed_fixed, spring, masses, conductivity)
    type(rod_data), intent(in) :: rod
    logical, intent(in) :: fixed_fixed
    type(spring_data), intent(out) :: spring
    real(real64), intent(out) :: masses(:)          !! N = n_s or n_s - 1 values
    real(real64), intent(out) :: conductivity(:)    !! n_s - 1 values
    real(real64) :: h

    h = rod%length/real(size(conductivity) + 1, real64)
    spring%natural_length = h
    spring%mu_eq_const = rod%axial_stiffness*h
    spring%mu_eq_slope = rod%stiffness_slope*h
    spring%beta = rod%thermal_stress*h
    spring%heat_capacity = rod%heat_capacity*h
    spring%theta_ref = rod%theta_ref
    spring%beta_v = rod%beta_v
    spring%mu_neq_const = rod%maxwell_stiffness/h
    spring%mu_neq_slope = rod%maxwell_slope/h
    spring%viscosity_const = rod%viscosity/h
    spring%viscosity_activation = rod%viscosity_activation
    masses = rod%mass_per_length*h
    if (.not. fixed_fixed) masses(size(masses)) = 0.5_real64*masses(size(masses))
    conductivity = rod%conductivity/h
  end subroutine rod_springs

end module spring_chain_continuum
