!> State layout and the mechanical (non-spring) parts of the double pendulum:
!> mass matrix (1), kinetic energy, gravity and angular momentum (docs/formulation.md section 2).
!> z = (q1, q2, p1, p2, gamma, tau1, tau2); q2 is m2's position relative to m1.
module double_pendulum
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  implicit none (type, external)
  private
  public :: state_size, q_index, p_index, gamma_index, tau_index, state_column_names, state_column_units
  public :: tau_symbols, tau_units
  public :: inverse_mass_times, kinetic_energy, gravity_potential, gravity_force
  public :: angular_momentum, cross, spring_invariants, spring_columns

  integer, parameter :: state_size = 15
  !> q_index(:, a) and p_index(:, a) are the columns of q_a and p_a in z.
  integer, parameter :: q_index(3, 2) = reshape([1, 2, 3, 4, 5, 6], [3, 2])
  integer, parameter :: p_index(3, 2) = reshape([7, 8, 9, 10, 11, 12], [3, 2])
  integer, parameter :: gamma_index = 13
  integer, parameter :: tau_index(2) = [14, 15]

  character(len=*), parameter :: state_column_names(state_size) = [character(len=6) :: &
    'q1_x', 'q1_y', 'q1_z', 'q2_x', 'q2_y', 'q2_z', 'p1_x', 'p1_y', 'p1_z', &
    'p2_x', 'p2_y', 'p2_z', 'gamma', 'tau1', 'tau2']
  !> The columns' units; tau_a's depend on the thermodynamic variable (tau_units).
  character(len=*), parameter :: state_column_units(state_size) = [character(len=6) :: &
    'm', 'm', 'm', 'm', 'm', 'm', 'N s', 'N s', 'N s', 'N s', 'N s', 'N s', 'm', '', '']
  !> tau_a's column name (symbol and a) and units for thermo_variable's tau_entropy,
  !> tau_temperature and tau_internal_energy.
  character(len=*), parameter :: tau_symbols(3) = [character(len=5) :: 's', 'theta', 'u']
  character(len=*), parameter :: tau_units(3) = [character(len=3) :: 'J/K', 'K', 'J']

contains

  !> v = m^-1 p with m^-1 = [[I/m1, -I/m1], [-I/m1, (m1+m2)/(m1 m2) I]]; p and v are (3, 2).
  pure function inverse_mass_times(params, p) result(v)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: p(3, 2)
    real(real64) :: v(3, 2)
    real(real64) :: m1, m2

    m1 = params%mass(1)
    m2 = params%mass(2)
    v(:, 1) = (p(:, 1) - p(:, 2))/m1
    v(:, 2) = -p(:, 1)/m1 + (m1 + m2)/(m1*m2)*p(:, 2)
  end function inverse_mass_times

  !> T = 1/2 p . m^-1 p, eq. (6).
  pure function kinetic_energy(params, z) result(t)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: z(:)
    real(real64) :: t
    real(real64) :: p(3, 2)

    p(:, 1) = z(p_index(1, 1):p_index(3, 1))     ! contiguous sections: no reshape call a step
    p(:, 2) = z(p_index(1, 2):p_index(3, 2))
    t = 0.5_real64*sum(p*inverse_mass_times(params, p))
  end function kinetic_energy

  !> V_g = -(m1+m2) g.q1 - m2 g.q2.
  pure function gravity_potential(params, z) result(vg)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: z(:)
    real(real64) :: vg
    real(real64) :: q(3, 2)

    q(:, 1) = z(q_index(1, 1):q_index(3, 1))
    q(:, 2) = z(q_index(1, 2):q_index(3, 2))
    vg = -sum(gravity_force(params)*q)
  end function gravity_potential

  !> -grad_q V_g: the constant gravity forces on the coordinates q1 and q2, as columns.
  pure function gravity_force(params) result(force)
    type(pendulum_parameters), intent(in) :: params
    real(real64) :: force(3, 2)

    force(:, 1) = (params%mass(1) + params%mass(2))*params%gravity
    force(:, 2) = params%mass(2)*params%gravity
  end function gravity_force

  !> J = q1 x p1 + q2 x p2 (docs/formulation.md section 2).
  pure function angular_momentum(z) result(j)
    real(real64), intent(in) :: z(:)
    real(real64) :: j(3)

    j = cross(z(q_index(1, 1):q_index(3, 1)), z(p_index(1, 1):p_index(3, 1))) &
        + cross(z(q_index(1, 2):q_index(3, 2)), z(p_index(1, 2):p_index(3, 2)))
  end function angular_momentum

  !> Spring a's invariants x = (C, tau) for a = 1 or (C, gamma, tau) for a = 2, C = q_a.q_a,
  !> and optionally dx_dz(i, j) = d x(i)/d z(spring_columns(a)(j)).
  pure subroutine spring_invariants(z, a, x, dx_dz)
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)

    x(1) = dot_product(z(q_index(:, a)), z(q_index(:, a)))
    if (a == 2) x(2) = z(gamma_index)
    x(a + 1) = z(tau_index(a))
    if (present(dx_dz)) then
      ! columns (q_a, [gamma,] tau_a): dC/dq = 2 q; gamma and tau are columns of z themselves.
      dx_dz = 0.0_real64
      dx_dz(1, 1:3) = 2.0_real64*z(q_index(:, a))
      if (a == 2) dx_dz(2, 4) = 1.0_real64
      dx_dz(a + 1, a + 3) = 1.0_real64
    end if
  end subroutine spring_invariants

  !> The columns of z spring a's invariants depend on: q_a, [gamma,] tau_a.
  pure function spring_columns(a) result(columns)
    integer, intent(in) :: a
    integer :: columns(a + 3)

    columns(1:3) = q_index(:, a)
    if (a == 2) columns(4) = gamma_index
    columns(a + 3) = tau_index(a)
  end function spring_columns

  !> The cross product a x b.
  pure function cross(a, b) result(c)
    real(real64), intent(in) :: a(3), b(3)
    real(real64) :: c(3)

    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross

end module double_pendulum
