!> The whole model for one choice of thermodynamic variable: parameters plus the two spring
!> potentials, with the totals E = T + V_g + U_1 + U_2, S = S_1 + S_2 and the temperatures (2).
module pendulum_model
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use free_energy, only: spring_law_of
  use thermo_variable, only: spring_potential, potential_u, potential_s, domain_ok
  use double_pendulum, only: state_size, q_index, p_index, gamma_index, tau_index, &
                             kinetic_energy, gravity_potential, spring_invariants, invariant_slots, chain_to_state
  implicit none (type, external)
  private
  public :: pendulum, make_pendulum

  !> Parameters and the spring potentials (U_a, S_a) in the chosen thermodynamic variable.
  type :: pendulum
    type(pendulum_parameters) :: params
    integer :: variable = 0
    type(spring_potential) :: spring(2)
  contains
    procedure :: observe
    procedure :: exact_partials
    procedure :: state_from_temperatures
  end type pendulum

contains

  !> The model for parameters `params` and thermodynamic variable `variable` (tau_* constant).
  pure function make_pendulum(params, variable) result(model)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: variable
    type(pendulum) :: model
    integer :: a

    model%params = params
    model%variable = variable
    do a = 1, 2
      model%spring(a)%law = spring_law_of(params, a)
      model%spring(a)%variable = variable
      model%spring(a)%n_invariants = a + 1
    end do
  end function make_pendulum

  !> Total energy (6) with gravity, total entropy and the spring temperatures (2) at state z.
  pure subroutine observe(self, z, energy, entropy, temperature, stat)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(state_size)
    real(real64), intent(out) :: energy, entropy, temperature(2)
    integer, intent(out) :: stat
    real(real64) :: f(2), grad(3, 2)
    integer :: a

    energy = kinetic_energy(self%params, z) + gravity_potential(self%params, z)
    entropy = 0.0_real64
    temperature = 0.0_real64
    do a = 1, 2
      associate (x => spring_invariants(z, a))
        call self%spring(a)%evaluate(x, f, grad(1:a + 1, :), stat=stat)
        if (stat /= domain_ok) return
        call self%spring(a)%temperature(x, temperature(a), stat)
        if (stat /= domain_ok) return
      end associate
      energy = energy + f(potential_u)
      entropy = entropy + f(potential_s)
    end do
  end subroutine observe

  !> The exact partials of U_a and S_a in each spring's invariants at z, as partials(var,
  !> potential, a), and optionally their derivatives with respect to z.
  pure subroutine exact_partials(self, z, partials, dpartials_dz, stat)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: partials(3, 2, 2)
    real(real64), intent(out), optional :: dpartials_dz(3, 2, 2, state_size)
    integer, intent(out) :: stat
    real(real64) :: f(2), g(3, 2), h(3, 3, 2)
    integer :: a, n

    partials = 0.0_real64
    if (present(dpartials_dz)) dpartials_dz = 0.0_real64
    do a = 1, 2
      n = a + 1
      if (present(dpartials_dz)) then
        call self%spring(a)%evaluate(spring_invariants(z, a), f, g(1:n, :), h(1:n, 1:n, :), stat)
      else
        call self%spring(a)%evaluate(spring_invariants(z, a), f, g(1:n, :), stat=stat)
      end if
      if (stat /= domain_ok) return
      partials(invariant_slots(a), :, a) = g(1:n, :)
      if (present(dpartials_dz)) call chain_to_state(h(1:n, 1:n, :), z, a, dpartials_dz)
    end do
  end subroutine exact_partials

  !> The state z built from positions, momenta, gamma and spring temperatures theta(2).
  pure subroutine state_from_temperatures(self, q1, q2, p1, p2, gamma, theta, z, stat)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: q1(3), q2(3), p1(3), p2(3), gamma, theta(2)
    real(real64), intent(out) :: z(state_size)
    integer, intent(out) :: stat
    integer :: a

    z(q_index(:, 1)) = q1
    z(q_index(:, 2)) = q2
    z(p_index(:, 1)) = p1
    z(p_index(:, 2)) = p2
    z(gamma_index) = gamma
    z(tau_index) = 0.0_real64
    do a = 1, 2
      associate (x => spring_invariants(z, a))
        call self%spring(a)%tau_from_temperature(x(1:a), theta(a), z(tau_index(a)), stat)
      end associate
      if (stat /= domain_ok) return
    end do
  end subroutine state_from_temperatures

end module pendulum_model
