!> What the chain keeps and produces, part by part (docs/formulation.md section 10): each mass's
!> T + V_g and each spring's (U_a, S_a), with their differences between two states free of
!> cancellation (a sum of per-part differences keeps a step's energy balance at round-off for any
!> N, where the difference of two sums of 10^5 parts would not); each viscous branch's and each
!> link's entropy production of a step, whose sum times dt is the step's Delta S at a root; and
!> the angular momentum with the axes the scene keeps it about.
module spring_chain_balance
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use spring_chain_spring, only: chain_spring, spring_invariants
  use spring_chain_partials, only: spring_partials
  use spring_chain_layout, only: chain_layout, spring_slots, slots_of
  implicit none (type, external)
  private
  public :: mass_energy, mass_energy_difference, spring_values, spring_differences
  public :: viscous_production, link_production, angular_momentum, conserved_axes

contains

  !> |p|^2/(2 m) - m g.x of one mass.
  pure real(real64) function mass_energy(mass, gravity, x, p)
    real(real64), intent(in) :: mass, gravity(:), x(:), p(:)

    mass_energy = dot_product(p, p)/(2.0_real64*mass) - mass*dot_product(gravity, x)
  end function mass_energy

  !> The mass's T + V_g at (x_new, p_new) minus at (x_old, p_old): T's difference as
  !> (p_new - p_old).(p_new + p_old)/(2 m), V_g's as -m g.(x_new - x_old).
  pure real(real64) function mass_energy_difference(mass, gravity, x_old, p_old, x_new, p_new)
    real(real64), intent(in) :: mass, gravity(:), x_old(:), p_old(:), x_new(:), p_new(:)

    mass_energy_difference = dot_product(p_new - p_old, p_new + p_old)/(2.0_real64*mass) &
                             - mass*dot_product(gravity, x_new - x_old)
  end function mass_energy_difference

  !> (U_a, S_a) and the temperature of a spring from its local slots' values (gather_spring).
  pure subroutine spring_values(spring, dimension, values, f, theta, stat, scales)
    type(chain_spring), intent(in) :: spring
    integer, intent(in) :: dimension
    real(real64), intent(in) :: values(:)
    real(real64), intent(out) :: f(2), theta
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: scales(2)   !! f's rounding scales (src/structure/step_balances)
    real(real64) :: x(3)

    call invariants_of(spring, dimension, values, x)
    call spring%values_and_temperature(x(1:spring%invariant_count), f, theta, stat, scales)
  end subroutine spring_values

  !> (U_a(new) - U_a(old), S_a(new) - S_a(old)) from the local slots' values, free of cancellation.
  pure subroutine spring_differences(spring, dimension, old, new, delta, stat)
    type(chain_spring), intent(in) :: spring
    integer, intent(in) :: dimension
    real(real64), intent(in) :: old(:), new(:)
    real(real64), intent(out) :: delta(2)
    integer, intent(out) :: stat
    real(real64) :: x_old(3), x_new(3)

    call invariants_of(spring, dimension, old, x_old)
    call invariants_of(spring, dimension, new, x_new)
    call spring%difference(x_old(1:spring%invariant_count), x_new(1:spring%invariant_count), delta, stat)
  end subroutine spring_differences

  !> The viscous branch's entropy production Theta y^2/eta(Theta), y = D_gamma S - D_gamma U/Theta,
  !> of a spring's partials (0 without a viscous branch).
  pure real(real64) function viscous_production(spring, part)
    type(chain_spring), intent(in) :: spring
    type(spring_partials), intent(in) :: part
    real(real64) :: eta, y

    viscous_production = 0.0_real64
    if (part%invariants /= 3) return
    call spring%viscosity(part%theta, eta)
    y = part%partials(2, potential_s) - part%partials(2, potential_u)/part%theta
    viscous_production = part%theta*y**2/eta
  end function viscous_production

  !> The link's entropy production kappa (Theta_a - Theta_b)^2/(Theta_a Theta_b).
  pure real(real64) function link_production(conductivity, part_a, part_b)
    real(real64), intent(in) :: conductivity
    type(spring_partials), intent(in) :: part_a, part_b

    link_production = conductivity*(part_a%theta - part_b%theta)**2/(part_a%theta*part_b%theta)
  end function link_production

  !> x x p of one mass as three components (in 2D only the third, x_1 p_2 - x_2 p_1; in 1D none).
  pure function angular_momentum(x, p) result(j)
    real(real64), intent(in) :: x(:), p(:)
    real(real64) :: j(3), x3(3), p3(3)

    x3 = 0.0_real64
    p3 = 0.0_real64
    x3(1:size(x)) = x
    p3(1:size(p)) = p
    j = [x3(2)*p3(3) - x3(3)*p3(2), x3(3)*p3(1) - x3(1)*p3(3), x3(1)*p3(2) - x3(2)*p3(1)]
  end function angular_momentum

  !> The unit axes about which the scene keeps J (columns; section 10's table): 'fixed-free' in 3D
  !> the gravity axis (every axis without gravity), in 2D e_z without gravity; 'fixed-fixed' in
  !> 3D e_x when gravity is zero or along x; none otherwise.
  pure function conserved_axes(layout, gravity) result(axes)
    type(chain_layout), intent(in) :: layout
    real(real64), intent(in) :: gravity(:)
    real(real64), allocatable :: axes(:, :)
    real(real64) :: g(3)

    g = 0.0_real64
    g(1:size(gravity)) = gravity
    allocate (axes(3, 0))
    if (layout%dimension == 1) return
    if (.not. layout%fixed_fixed) then
      if (layout%dimension == 3 .and. norm2(g) > 0.0_real64) then
        axes = reshape(g/norm2(g), [3, 1])
      else if (layout%dimension == 3) then
        axes = reshape([1.0_real64, 0.0_real64, 0.0_real64, 0.0_real64, 1.0_real64, 0.0_real64, &
                        0.0_real64, 0.0_real64, 1.0_real64], [3, 3])
      else if (norm2(g) <= 0.0_real64) then
        axes = reshape([0.0_real64, 0.0_real64, 1.0_real64], [3, 1])
      end if
    else if (layout%dimension == 3 .and. norm2(g(2:3)) <= 0.0_real64) then
      axes = reshape([1.0_real64, 0.0_real64, 0.0_real64], [3, 1])
    end if
  end function conserved_axes

  ! The invariants (C, [gamma,] [tau]) from a spring's local slots' values.
  pure subroutine invariants_of(spring, dimension, values, x)
    type(chain_spring), intent(in) :: spring
    integer, intent(in) :: dimension
    real(real64), intent(in) :: values(:)
    real(real64), intent(out) :: x(3)
    type(spring_slots) :: s
    real(real64) :: gamma, tau

    s = slots_of(dimension, spring%invariant_count)
    gamma = 0.0_real64
    tau = 0.0_real64
    if (s%gamma > 0) gamma = values(s%gamma)
    if (s%tau > 0) tau = values(s%tau)
    x = 0.0_real64
    call spring_invariants(values(s%x_right(1:dimension)) - values(s%x_left(1:dimension)), gamma, tau, &
                           spring%invariant_count, x(1:spring%invariant_count))
  end subroutine invariants_of

end module spring_chain_balance
