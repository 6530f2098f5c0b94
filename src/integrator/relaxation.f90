!> Relaxation of a Runge-Kutta step (Ketcheson 2019; Ranocha, Sayyari, Dalcin, Parsani,
!> Ketcheson 2020; docs/integrators.md): the step z + d is replaced by z_new(gamma) = P(z + gamma d),
!> where P projects onto the constraints and every conserved component of the momenta
!> (src/integrator/constrained_flow: positions, then the momenta, then slaved entries), and
!> gamma is the root near 1 of
!>   r(gamma) = [E(z_new) - E(z)] - thetabar [S(z_new) - S(z) - gamma e_S] = 0,
!> evaluated with the model's cancellation-free differences. thetabar = 0 for a closed system:
!> then E(z_new) = E(z). With a heat bath at thetabar (constraint g2), V = E - thetabar S
!> changes by exactly -thetabar gamma e_S. In entropy variables, with e_S the step's entropy
!> estimate h sum_i b_i sigma_i, the projection leaves the free subsystems' entropy alone, so
!> S(z_new) - S(z) = gamma e_S in a closed system.
!>
!> "To round-off" has a floor: z_new is rounded to doubles, which moves E by up to about
!> eps sum_i |z_i dE/dz_i| (1e-13 J on the paper scene) whatever gamma is. A gamma whose r is
!> below that floor is a root; an accurate small step can have r(1) below it already.
module relaxation
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use failures, only: failure_none, domain_overflow
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use constrained_flow, only: project_state, bath_temperature_of
  implicit none (type, external)
  private
  public :: relax, gamma_min, gamma_max

  !> The gamma a step may take (docs/integrators.md); outside, the step is rejected.
  real(real64), parameter :: gamma_min = 0.2_real64, gamma_max = 2.0_real64
  integer, parameter :: max_secant_steps = 30
  real(real64), parameter :: settled = 1.0e-13_real64   !! a secant step this small ends the iteration

contains

  !> gamma and z_new = P(z + gamma d) with r(gamma) = 0 to round-off; found = .false. when no
  !> root lies in [gamma_min, gamma_max] or an evaluation leaves the model's domain.
  !> `evaluations` counts the energy differences taken.
  subroutine relax(model, constraints, z, d, entropy_estimate, gamma, z_new, found, evaluations, resolution)
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z(:), d(:), entropy_estimate
    real(real64), intent(out) :: gamma, z_new(:)
    logical, intent(out) :: found
    integer, intent(out) :: evaluations
    !> How far rounding alone moves the root: the floor of r over its slope in gamma (2 floor /
    !> |dq/dgamma| at the root). A short step's r(gamma) is flat (its slope ~ |d|^2), so this
    !> grows like (|z|/|d|)^2 eps: at tight tolerances and in slivers of steps it can exceed the
    !> band an order allows, which then cannot be asked of gamma.
    real(real64), intent(out), optional :: resolution
    real(real64) :: momenta(model%conserved_count()), bath, floor, g_a, g_b, q_a, q_b, g_next, best, best_r
    integer :: k, stat
    logical :: stalled

    found = .false.
    evaluations = 0
    gamma = 1.0_real64
    momenta = model%conserved_momenta(z)
    bath = bath_temperature_of(constraints)
    call rounding_floor(floor, stat)
    if (stat /= failure_none) return
    ! r(0) = 0: the secant runs on q(gamma) = r(gamma)/gamma, whose root is the nontrivial one,
    ! from gamma = 1 (an order-p step has r(1) = O(h^(p+1))) and 1 - 1e-3. It always takes a
    ! secant step: r(1) is the method's own energy error, which may lie below the floor and yet
    ! accumulate over many steps if accepted; the secant's root has only rounding left in r.
    g_a = 1.0_real64
    call scaled_residual(g_a, q_a, stat)
    if (stat /= failure_none) return
    g_b = 1.0_real64 - 1.0e-3_real64
    call scaled_residual(g_b, q_b, stat)
    if (stat /= failure_none) return
    best = 1.0_real64
    best_r = abs(q_a)
    ! Secant steps (q is nearly linear near the root, so they converge fast) until |r| is an
    ! eighth of the floor or a step moves gamma by less than `settled` (then only rounding is
    ! left to change). The best gamma is a root if its |r| is within the floor.
    do k = 1, max_secant_steps
      if (.not. (abs(q_b - q_a) > 0.0_real64)) exit
      g_next = g_b - q_b*(g_b - g_a)/(q_b - q_a)
      if (.not. (g_next >= 0.5_real64*gamma_min .and. g_next <= 2.0_real64*gamma_max)) exit
      stalled = abs(g_next - g_b) <= settled
      g_a = g_b
      q_a = q_b
      g_b = g_next
      call scaled_residual(g_b, q_b, stat)
      if (stat /= failure_none) return
      if (abs(q_b*g_b) < best_r) then
        best = g_b
        best_r = abs(q_b*g_b)
      end if
      if (stalled .or. best_r <= 0.125_real64*floor) exit
    end do
    gamma = best
    if (present(resolution)) then
      resolution = huge(1.0_real64)
      if (abs(g_b - g_a) > 0.0_real64 .and. abs(q_b - q_a) > 0.0_real64) &
        resolution = 2.0_real64*floor/abs((q_b - q_a)/(g_b - g_a))
    end if
    found = best_r <= floor .and. gamma >= gamma_min .and. gamma <= gamma_max
    if (found) call increment(gamma, stat)
    found = found .and. stat == failure_none

  contains

    ! The rounding floor of r (above): 8 eps sum_i |z_i| (|dE/dz_i| + thetabar |dS/dz_i|).
    subroutine rounding_floor(floor, stat)
      real(real64), intent(out) :: floor
      integer, intent(out) :: stat
      real(real64) :: partials(model%max_invariants, 2, model%subsystem_count()), weights(size(z))

      floor = 0.0_real64
      call model%exact_partials(z, partials, stat=stat)
      if (stat /= failure_none) return
      weights = abs(model%mechanical_energy_gradient(z) + model%subsystem_gradient(z, partials, potential_u))
      if (bath > 0.0_real64) weights = weights + bath*abs(model%subsystem_gradient(z, partials, potential_s))
      floor = 8*epsilon(1.0_real64)*sum(abs(z)*weights)
      if (.not. (floor > 0.0_real64)) floor = tiny(1.0_real64)
    end subroutine rounding_floor

    ! z_new = P(z + g d).
    subroutine increment(g, stat)
      real(real64), intent(in) :: g
      integer, intent(out) :: stat

      z_new = z + g*d
      call project_state(model, constraints, momenta, z_new, stat)
    end subroutine increment

    ! q = r(g)/g at z_new = P(z + g d).
    subroutine scaled_residual(g, q, stat)
      real(real64), intent(in) :: g
      real(real64), intent(out) :: q
      integer, intent(out) :: stat
      real(real64) :: energy_change, entropy_change

      call increment(g, stat)
      if (stat /= failure_none) return
      call model%energy_difference(z, z_new, energy_change, stat, entropy_change)
      evaluations = evaluations + 1
      q = energy_change/g
      if (bath > 0.0_real64) q = q - bath*(entropy_change/g - entropy_estimate)
      if (.not. (abs(q) <= huge(q))) stat = domain_overflow
    end subroutine scaled_residual
  end subroutine relax

end module relaxation
