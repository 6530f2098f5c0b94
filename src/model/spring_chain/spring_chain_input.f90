!> The values of the spring chain's input (docs/input.md; docs/formulation.md section 10): &model
!> (the chain's shape, and its springs either one by one, family = 'springs', or as the
!> discretisation of a rod, family = 'rod') and &initial (the masses' positions and momenta, the
!> dampers and the temperatures, an optional perturbation of the positions, or an HDF5 file of
!> them), with their defaults. A per-spring array holds `unset` in every element no value was
!> given for until `complete_defaults` fills it.
module spring_chain_input
  use, intrinsic :: iso_fortran_env, only: real64
  use spring_chain_spring, only: spring_data, rung_of, law_thermoviscoelastic
  use spring_chain_layout, only: ends_fixed_free, ends_fixed_fixed
  use spring_chain_continuum, only: rod_data, rod_springs
  implicit none (type, external)
  private
  public :: chain_input, size_arrays, complete_defaults, unset, max_links
  public :: family_springs, family_rod, family_names
  public :: perturbation_none, perturbation_mode, perturbation_random, perturbation_names

  !> The most masses a chain may have: the sparse path's (eme_run's dense path refuses more than
  !> 1000 unknowns, src/run/simulation).
  integer, parameter :: max_links = 100000
  !> An element no value was given for (compared with >= and <: reals are not compared for equality).
  real(real64), parameter :: unset = huge(1.0_real64)
  !> &model family: the springs' values given one by one, or those of a rod's elements.
  character(len=*), parameter :: family_springs = 'springs', family_rod = 'rod'
  character(len=*), parameter :: family_names = family_springs//' '//family_rod
  !> &initial perturbation of the masses' positions along x.
  character(len=*), parameter :: perturbation_none = 'none', perturbation_mode = 'mode', perturbation_random = 'random'
  character(len=*), parameter :: perturbation_names = perturbation_none//' '//perturbation_mode//' '//perturbation_random

  !> The values of &model and &initial, in their namelist names; arrays sized for the chain.
  type :: chain_input
    character(len=24) :: model_name = 'spring_chain'
    integer :: links = 2
    character(len=16) :: ends = ends_fixed_free
    real(real64) :: span = unset
    integer :: dimension = 3
    real(real64) :: gravity(3) = [0.0_real64, 0.0_real64, -9.81_real64]
    character(len=24) :: spring_law = law_thermoviscoelastic
    character(len=16) :: family = family_springs
    !> The rod of family = 'rod' (section 10's table), by default the one whose two elements are
    !> the default springs (h = 2 m): EA h = 200 J, c h = 10 J/K, kA/h = 1 W/K, ...
    type(rod_data) :: rod = rod_data(length=4.0_real64, mass_per_length=0.5_real64, axial_stiffness=100.0_real64, &
                                     stiffness_slope=0.25_real64, thermal_stress=0.01_real64, &
                                     heat_capacity=5.0_real64, maxwell_stiffness=10.0_real64, &
                                     maxwell_slope=0.2_real64, viscosity=200.0_real64, conductivity=2.0_real64)
    real(real64), allocatable :: natural_length(:), mu_eq_const(:), mu_eq_slope(:), mu_neq_const(:), mu_neq_slope(:)
    real(real64), allocatable :: heat_capacity(:), viscosity_const(:), viscosity_activation(:), theta_ref(:)
    real(real64), allocatable :: beta(:), beta_v(:), conductivity(:), mass(:)
    real(real64), allocatable :: x(:), p(:), gamma(:), theta(:)
    real(real64) :: stretch = 1.0_real64
    character(len=16) :: perturbation = perturbation_none
    integer :: mode_number = 1
    real(real64) :: amplitude = 0.01_real64      !! [m], along x
    integer :: seed = 1
    character(len=4096) :: file = ''             !! &initial file: an HDF5 file of q, p, gamma, theta
    integer :: snapshot = -1                      !! with a run file: the row of /snapshots (from 0; -1 the last)
    character(len=4096) :: spring_file = ''      !! &model spring_file: an HDF5 file of per-spring arrays
    !> The &model fields whose values spring_file gave (not in the group's table from then on, so
    !> that the run's namelist names the file, not its values).
    character(len=24), allocatable :: from_file(:)
    !> The choices that select the fields (spring_law, ends, family, perturbation, file) were read:
    !> before, the tables hold every field any chain takes (--help, a study's field names).
    logical :: chosen = .false.
  contains
    procedure :: springs
    procedure :: rung
  end type chain_input

contains

  !> n_s: N springs ('fixed-free') or N + 1 ('fixed-fixed').
  pure integer function springs(self)
    class(chain_input), intent(in) :: self

    springs = self%links
    if (self%ends == ends_fixed_fixed) springs = self%links + 1
  end function springs

  !> The ladder's rung (spring_chain_spring's rung_*).
  pure integer function rung(self)
    class(chain_input), intent(in) :: self

    rung = rung_of(trim(self%spring_law))
  end function rung

  !> Every array sized for n_s springs, N masses in d components, no value given.
  pure subroutine size_arrays(self, n_s, masses, d)
    type(chain_input), intent(inout) :: self
    integer, intent(in) :: n_s, masses, d

    self%natural_length = spread(unset, 1, n_s)
    self%mu_eq_const = self%natural_length
    self%mu_eq_slope = self%natural_length
    self%mu_neq_const = self%natural_length
    self%mu_neq_slope = self%natural_length
    self%heat_capacity = self%natural_length
    self%viscosity_const = self%natural_length
    self%viscosity_activation = self%natural_length
    self%theta_ref = self%natural_length
    self%beta = self%natural_length
    self%beta_v = self%natural_length
    self%gamma = self%natural_length
    self%theta = self%natural_length
    self%conductivity = spread(unset, 1, max(1, n_s - 1))
    self%mass = spread(unset, 1, masses)
    self%x = spread(unset, 1, d*masses)
    self%p = self%x
  end subroutine size_arrays

  !> One value given: every element; none: the default (spring_data's, mass 1, conductivity 1,
  !> p 0, gamma 0, theta 280, span the sum of the natural lengths, x the uniform stretch). With
  !> family = 'rod' the springs, masses and links are the rod's elements (rod_springs), but for
  !> beta_v, theta_ref and viscosity_activation, which the rod passes to its springs unscaled.
  pure subroutine complete_defaults(self)
    type(chain_input), intent(inout) :: self
    type(spring_data) :: d
    real(real64) :: along
    integer :: i

    if (self%family == family_rod) then
      call rod_springs(self%rod, self%ends == ends_fixed_fixed, d, self%mass, self%conductivity(1:self%springs() - 1))
      self%natural_length = d%natural_length
      self%mu_eq_const = d%mu_eq_const
      self%mu_eq_slope = d%mu_eq_slope
      self%mu_neq_const = d%mu_neq_const
      self%mu_neq_slope = d%mu_neq_slope
      self%heat_capacity = d%heat_capacity
      self%viscosity_const = d%viscosity_const
      self%beta = d%beta
      d = spring_data()
    end if
    call fill(self%natural_length, d%natural_length)
    call fill(self%mu_eq_const, d%mu_eq_const)
    call fill(self%mu_eq_slope, d%mu_eq_slope)
    call fill(self%mu_neq_const, d%mu_neq_const)
    call fill(self%mu_neq_slope, d%mu_neq_slope)
    call fill(self%heat_capacity, d%heat_capacity)
    call fill(self%viscosity_const, d%viscosity_const)
    call fill(self%viscosity_activation, d%viscosity_activation)
    call fill(self%theta_ref, d%theta_ref)
    call fill(self%beta, d%beta)
    call fill(self%beta_v, d%beta_v)
    call fill(self%conductivity, 1.0_real64)
    call fill(self%mass, 1.0_real64)
    call fill(self%p, 0.0_real64)
    call fill(self%gamma, 0.0_real64)
    call fill(self%theta, 280.0_real64)
    if (self%span >= unset) self%span = sum(self%natural_length)
    if (all(self%x >= unset)) then
      self%x = 0.0_real64
      along = 0.0_real64
      do i = 1, self%links
        along = along + self%natural_length(i)
        if (self%ends == ends_fixed_fixed) then
          self%x((i - 1)*self%dimension + 1) = self%span*along/sum(self%natural_length)
        else
          self%x((i - 1)*self%dimension + 1) = self%stretch*along
        end if
      end do
    end if

  contains

    pure subroutine fill(values, default)
      real(real64), intent(inout) :: values(:)
      real(real64), intent(in) :: default

      if (all(values >= unset)) then
        values = default
      else if (count(values < unset) == 1) then
        values = values(1)
      end if
    end subroutine fill
  end subroutine complete_defaults

end module spring_chain_input
