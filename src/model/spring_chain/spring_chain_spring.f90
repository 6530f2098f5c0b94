!> One spring of the chain (docs/formulation.md section 10): its data, its potentials (U_a, S_a) in
!> its invariants x_a = (C_a, [gamma_a,] [tau_a]) and eta(Theta) of eq. (17), all generated from the
!> shared element of the paper's spring (src/model/paper_spring/description.py: section 3's law with the
!> spring's own data, paper_spring_potential), and its local discrete gradient. A spring without a Maxwell element
!> (beta_v = mu_neq = 0) is the pendulum's spring 1, otherwise its spring 2. The rung of the ladder
!> (section 9) sets the invariants: C (elastic), (C, tau) (thermoelastic), (C, gamma, tau)
!> (thermoviscoelastic).
module spring_chain_spring
  use, intrinsic :: iso_fortran_env, only: real64
  use paper_spring_potential, only: spring_data => paper_spring_parameters, paper_spring_potentials, &
                                    make_paper_spring_potentials
  use discrete_gradient, only: discrete_gradient_of, gonzalez_from_parts, gradient_gonzalez, metric_euclidean, &
                               quotient_threshold
  use failures, only: failure_none
  implicit none (type, external)
  private
  public :: spring_data, chain_spring, make_chain_spring, rung_of, spring_invariants
  public :: rung_elastic, rung_thermoelastic, rung_thermoviscoelastic
  public :: law_elastic, law_thermoelastic, law_thermoviscoelastic, spring_law_names

  !> The rungs, numbered by their invariant count (the generated element's kinds).
  integer, parameter :: rung_elastic = 1
  integer, parameter :: rung_thermoelastic = 2
  integer, parameter :: rung_thermoviscoelastic = 3

  !> The rungs' names, `spring_law`'s values (the pendulum's ladder's, docs/formulation.md section 9).
  character(len=*), parameter :: law_thermoviscoelastic = 'thermoviscoelastic'
  character(len=*), parameter :: law_thermoelastic = 'thermoelastic'
  character(len=*), parameter :: law_elastic = 'elastic'
  character(len=*), parameter :: spring_law_names = law_thermoviscoelastic//' '//law_thermoelastic//' '//law_elastic

  !> A spring's potentials in one thermodynamic variable, and its viscosity; spring_data (the generated
  !> element's data, in SI units named as the pendulum's &model fields; defaults Table 1's spring 2)
  !> is what it is made of.
  type :: chain_spring
    integer :: invariant_count = 0                 !! the rung (rung_*): 1, 2 or 3 invariants
    type(paper_spring_potentials) :: potentials    !! (U, S) of (C, [gamma,] [tau]); S = 0 on the elastic rung
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

  !> The rung named `law` (spring_law_names), 0 for another name.
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

  !> The spring of `data` on rung `rung` (rung_*) in thermodynamic variable `variable` (tau_*).
  pure function make_chain_spring(data, rung, variable) result(spring)
    type(spring_data), intent(in) :: data
    integer, intent(in) :: rung, variable
    type(chain_spring) :: spring

    spring%invariant_count = rung
    spring%potentials = make_paper_spring_potentials(data, rung, variable)
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

    call self%potentials%evaluate(x, f, grad, hess, stat)
  end subroutine evaluate

  !> (U(b) - U(a), S(b) - S(a)) without cancellation.
  pure subroutine difference(self, a, b, delta, stat)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: delta(:)
    integer, intent(out) :: stat

    call self%potentials%difference(a, b, delta, stat)
  end subroutine difference

  !> The local discrete gradient D(U, S)(a, b) in the spring's invariants (`kind`: Gonzalez's or the
  !> partitioned one; `metric`), with ddg_db(i, l, k) = d dg(i, k)/d b(l): src/scheme's
  !> discrete_gradient_of, except Gonzalez's quotient above its threshold, whose parts the generated
  !> element gives in one call (gonzalez_parts, their subexpressions shared: the discrete gradients of
  !> chain_bench's time loop took 263e6 instructions where three calls of the potentials took 326e6)
  !> and gonzalez_from_parts combines.
  pure subroutine discrete_gradient(self, kind, metric, a, b, dg, ddg_db, stat)
    class(chain_spring), intent(in) :: self
    integer, intent(in) :: kind, metric
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: dg(:, :)
    real(real64), intent(out), optional :: ddg_db(:, :, :)
    integer, intent(out) :: stat
    real(real64) :: scale(size(a)), d(size(a)), weight(size(a)), dwd, grad_m(size(a), 2), delta(2)
    real(real64) :: hess_m(size(a), size(a), 2), grad_b(size(a), 2)

    scale = self%metric_scale()
    if (metric == metric_euclidean) scale = 1.0_real64
    d = b - a
    weight = 1.0_real64/scale**2
    dwd = dot_product(d, weight*d)
    if (kind /= gradient_gonzalez .or. sqrt(dwd) < quotient_threshold) then
      call discrete_gradient_of(kind, self%potentials, a, b, scale, dg, ddg_db, stat=stat)
      return
    end if
    if (present(ddg_db)) then
      call self%potentials%gonzalez_parts(a, b, grad_m, delta, stat, hess_m, grad_b)
      if (stat /= failure_none) return
      call gonzalez_from_parts(d, weight, dwd, grad_m, delta, dg, hess_m, grad_b, ddg_db)
    else
      call self%potentials%gonzalez_parts(a, b, grad_m, delta, stat)
      if (stat /= failure_none) return
      call gonzalez_from_parts(d, weight, dwd, grad_m, delta, dg)
    end if
  end subroutine discrete_gradient

  !> (U, S) and the temperature at x (an elastic spring has none: theta = 0).
  pure subroutine values_and_temperature(self, x, f, theta, stat, scales)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), theta
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: scales(:)   !! the values' rounding scales (|f| for an elastic spring)

    call self%potentials%values_and_temperature(x, f, theta, stat, scales)
  end subroutine values_and_temperature

  !> tau giving temperature theta at the mechanical invariants (C, [gamma]); an elastic spring has
  !> no tau (stat = domain_overflow).
  pure subroutine tau_from_temperature(self, mechanical, theta, tau, stat)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: mechanical(:), theta
    real(real64), intent(out) :: tau
    integer, intent(out) :: stat

    call self%potentials%tau_from_temperature(mechanical, theta, tau, stat)
  end subroutine tau_from_temperature

  !> The nondimensional metric's typical sizes of the invariants (docs/formulation.md section 5).
  pure function metric_scale(self) result(scale)
    class(chain_spring), intent(in) :: self
    real(real64) :: scale(self%invariant_count)

    scale = self%potentials%metric_scale(1:self%invariant_count)
  end function metric_scale

  !> eta(theta) of eq. (17) with the spring's data, and optionally d(1/eta)/dtheta = eta_theta/(eta theta^2).
  pure subroutine spring_viscosity(self, theta, eta, dinverse_dtheta)
    class(chain_spring), intent(in) :: self
    real(real64), intent(in) :: theta
    real(real64), intent(out) :: eta
    real(real64), intent(out), optional :: dinverse_dtheta

    call self%potentials%viscosity(theta, eta, dinverse_dtheta)
  end subroutine spring_viscosity

end module spring_chain_spring
