!> One spring of the chain (docs/formulation.md section 10): its data, its potentials (U_a, S_a) in
!> its invariants x_a = (C_a, [gamma_a,] [tau_a]) and eta(Theta) of eq. (17). The closed forms are
!> the pendulum's, used through their public interfaces: a chain spring is the pendulum's spring 2
!> (free_energy's spring_law_of) with its own data, so a spring without a Maxwell element
!> (beta_v = mu_neq = 0) is the pendulum's spring 1. The rung of the ladder (section 9) sets the
!> invariants: C (elastic), (C, tau) (thermoelastic), (C, gamma, tau) (thermoviscoelastic).
module spring_chain_spring
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters, law_thermoviscoelastic, law_thermoelastic, law_elastic
  use free_energy, only: spring_law_of, viscosity
  use thermo_variable, only: spring_potential
  use elastic_potential, only: elastic_spring, make_elastic_spring
  use discrete_gradient, only: discrete_gradient_of, metric_euclidean
  use failures, only: domain_overflow
  implicit none (type, external)
  private
  public :: spring_data, chain_spring, make_chain_spring, rung_of, spring_invariants
  public :: rung_elastic, rung_thermoelastic, rung_thermoviscoelastic

  !> The rungs, numbered by their invariant count.
  integer, parameter :: rung_elastic = 1
  integer, parameter :: rung_thermoelastic = 2
  integer, parameter :: rung_thermoviscoelastic = 3

  !> One spring's data in SI units, named as the pendulum's &model fields; defaults are Table 1's
  !> spring 2 (the paper's thermoviscoelastic spring).
  type :: spring_data
    real(real64) :: natural_length = 2.0_real64        !! l^0 [m]
    real(real64) :: mu_eq_const = 200.0_real64         !! mu^eq_cst, eq. (17) [J]
    real(real64) :: mu_eq_slope = 0.5_real64           !! mu^eq_theta [J/K]
    real(real64) :: mu_neq_const = 5.0_real64          !! mu^neq_cst [J/m^2]
    real(real64) :: mu_neq_slope = 0.1_real64          !! mu^neq_theta [J/(m^2 K)]
    real(real64) :: heat_capacity = 10.0_real64        !! c^0, eq. (16) [J/K]
    real(real64) :: viscosity_const = 100.0_real64     !! eta_cst [N s/m]
    real(real64) :: viscosity_activation = 10.0_real64 !! eta_theta [K]
    real(real64) :: theta_ref = 300.0_real64           !! theta_ref [K]
    real(real64) :: beta = 0.02_real64                 !! beta [J/K]
    real(real64) :: beta_v = 0.5_real64                !! beta^v
  end type spring_data

  !> A spring's potentials in one thermodynamic variable, and its viscosity.
  type :: chain_spring
    integer :: invariant_count = 0                 !! the rung (rung_*): 1, 2 or 3 invariants
    type(spring_potential) :: thermal              !! (U, S) of (C, [gamma,] tau), the thermal rungs
    type(elastic_spring) :: elastic                !! (W, 0) of C, the elastic rung
    real(real64) :: viscosity_const = 0.0_real64
    real(real64) :: viscosity_activation = 0.0_real64
    real(real64) :: theta_ref = 1.0_real64
  contains
    procedure, non_overridable :: evaluate
    procedure, non_overridable :: difference
    procedure, non_overridable :: discrete_gradient
    procedure, non_overridable :: values_and_temperature
    procedure, non_overridable :: tau_from_temperature
    procedure, non_overridable :: metric_scale
    procedure, non_overridable :: viscosity => spring_viscosity
  end type chain_spring

contains

  !> The rung named `law` (model_parameters' spring_law names), 0 for another name.
  pure integer function rung_of(law)
    character(len=*), intent(in) :: law

    select case (law)
    case (law_elastic)
      rung_of = rung_elastic
    case (law_thermoelastic)
      rung_of = rung_thermoelastic
    case (law_thermoviscoelastic)
      rung_of = rung_thermoviscoelastic
    case default
      rung_of = 0
    end select
  end function rung_of

  !> The spring of `data` on rung `rung` (rung_*) in thermodynamic variable `variable` (tau_*):
  !> section 3's closed forms for the pendulum's spring 2 with these data.
  pure function make_chain_spring(data, rung, variable) result(spring)
    type(spring_data), intent(in) :: data
    integer, intent(in) :: rung, variable
    type(chain_spring) :: spring
    type(pendulum_parameters) :: params

    params%spring_law = law_thermoelastic
    if (rung == rung_thermoviscoelastic) params%spring_law = law_thermoviscoelastic
    params%natural_length(2) = data%natural_length
    params%mu_eq_const(2) = data%mu_eq_const
    params%mu_eq_slope(2) = data%mu_eq_slope
    params%mu_neq_const = data%mu_neq_const
    params%mu_neq_slope = data%mu_neq_slope
    params%heat_capacity(2) = data%heat_capacity
    params%theta_ref = data%theta_ref
    params%beta = data%beta
    params%beta_v = data%beta_v
    spring%invariant_count = rung
    spring%thermal%law = spring_law_of(params, 2)
    spring%thermal%variable = variable
    spring%thermal%n_invariants = max(rung, 2)
    spring%elastic = make_elastic_spring(params, 2)
    spring%viscosity_const = data%viscosity_const
    spring%viscosity_activation = data%viscosity_activation
    spring%theta_ref = data%theta_ref
  end function make_chain_spring

  !> x = (C, [gamma,] [tau]) of the spring from r = right - left, its own gamma and tau, n
  !> invariants; optionally dC/dr = 2 r (dC/d right = 2 r, dC/d left = -2 r).
  pure subroutine spring_invariants(r, gamma, tau, n, x, dc_dr)
    real(real64), intent(in) :: r(:), gamma, tau
    integer, intent(in) :: n
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dc_dr(:)

    x(1) = dot_product(r, r)
    if (n == 3) x(2) = gamma
    if (n >= 2) x(n) = tau
    if (present(dc_dr)) dc_dr = 2.0_real64*r
  end subroutine spring_invariants

  !> (U, S) at x with gradients and optionally Hessians in x (stat: a domain code).
  pure subroutine evaluate(self, x, f, grad, hess, stat)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), grad(:, :)
    real(real64), intent(out), optional :: hess(:, :, :)
    integer, intent(out) :: stat

    if (self%invariant_count == rung_elastic) then
      call self%elastic%evaluate(x, f, grad, hess, stat)
    else
      call self%thermal%evaluate(x, f, grad, hess, stat)
    end if
  end subroutine evaluate

  !> (U(b) - U(a), S(b) - S(a)) without cancellation.
  pure subroutine difference(self, a, b, delta, stat)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: delta(:)
    integer, intent(out) :: stat

    if (self%invariant_count == rung_elastic) then
      call self%elastic%difference(a, b, delta, stat)
    else
      call self%thermal%difference(a, b, delta, stat)
    end if
  end subroutine difference

  !> The local discrete gradient D(U, S)(a, b) in the spring's invariants by src/scheme's
  !> discrete_gradient_of (`kind`: Gonzalez's or the partitioned one; `metric`), with
  !> ddg_db(i, l, k) = d dg(i, k)/d b(l).
  pure subroutine discrete_gradient(self, kind, metric, a, b, dg, ddg_db, stat)
    class(chain_spring), intent(in) :: self
    integer, intent(in) :: kind, metric
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: dg(:, :)
    real(real64), intent(out), optional :: ddg_db(:, :, :)
    integer, intent(out) :: stat
    real(real64) :: scale(size(a))

    scale = self%metric_scale()
    if (metric == metric_euclidean) scale = 1.0_real64
    if (self%invariant_count == rung_elastic) then
      call discrete_gradient_of(kind, self%elastic, a, b, scale, dg, ddg_db, stat=stat)
    else
      call discrete_gradient_of(kind, self%thermal, a, b, scale, dg, ddg_db, stat=stat)
    end if
  end subroutine discrete_gradient

  !> (U, S) and the temperature at x (an elastic spring has none: theta = 0).
  pure subroutine values_and_temperature(self, x, f, theta, stat, scales)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), theta
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: scales(:)   !! the values' rounding scales (|f| for an elastic spring)
    real(real64) :: grad(size(x), 2)

    theta = 0.0_real64
    if (self%invariant_count == rung_elastic) then
      call self%elastic%evaluate(x, f, grad, stat=stat)
      if (present(scales)) scales = abs(f)
    else
      call self%thermal%values_and_temperature(x, f, theta, stat, scales)
    end if
  end subroutine values_and_temperature

  !> tau giving temperature theta at the mechanical invariants (C, [gamma]); an elastic spring has
  !> no tau (stat = domain_overflow).
  pure subroutine tau_from_temperature(self, mechanical, theta, tau, stat)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: mechanical(:), theta
    real(real64), intent(out) :: tau
    integer, intent(out) :: stat

    tau = 0.0_real64
    stat = domain_overflow
    if (self%invariant_count /= rung_elastic) call self%thermal%tau_from_temperature(mechanical, theta, tau, stat)
  end subroutine tau_from_temperature

  !> The nondimensional metric's typical sizes of the invariants (docs/formulation.md section 5).
  pure function metric_scale(self) result(scale)
    class(chain_spring), intent(in) :: self
    real(real64) :: scale(self%invariant_count)

    if (self%invariant_count == rung_elastic) then
      scale = self%elastic%metric_scale()
    else
      scale = self%thermal%metric_scale()
    end if
  end function metric_scale

  !> eta(theta) of eq. (17) with the spring's data (free_energy's viscosity), and optionally
  !> d(1/eta)/dtheta = eta_theta/(eta theta^2).
  pure subroutine spring_viscosity(self, theta, eta, dinverse_dtheta)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: theta
    real(real64), intent(out) :: eta
    real(real64), intent(out), optional :: dinverse_dtheta
    type(pendulum_parameters) :: params

    params%viscosity_const = self%viscosity_const
    params%viscosity_activation = self%viscosity_activation
    params%theta_ref = self%theta_ref
    eta = viscosity(params, theta)
    if (present(dinverse_dtheta)) dinverse_dtheta = self%viscosity_activation/(eta*theta**2)
  end subroutine spring_viscosity

end module spring_chain_spring
