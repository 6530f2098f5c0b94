!> State layout and the mechanical (non-spring) parts of the double pendulum:
!> mass matrix (1), kinetic energy, gravity and angular momentum (docs/formulation.md section 2).
!> The full layout is z = (q1, q2, p1, p2, gamma, tau1, tau2), 15 unknowns, q2 being m2's position
!> relative to m1; a scene that needs less (docs/formulation.md section 9) has its own
!> `pendulum_layout`: planar positions and momenta (dimension 2, y vertical), no gamma without
!> the viscous branch, and no tau for elastic springs.
module double_pendulum
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  implicit none (type, external)
  private
  public :: state_size, q_index, p_index, gamma_index, tau_index
  public :: pendulum_layout, make_layout, full_layout
  public :: tau_symbols, tau_units, inverse_mass_times, cross

  !> The full (spatial, thermoviscoelastic) layout's columns, whose numbering the fused step kernel
  !> (pendulum_step_kernel) works in for every thermal layout.
  integer, parameter :: state_size = 15
  !> q_index(:, a) and p_index(:, a) are the columns of q_a and p_a in z.
  integer, parameter :: q_index(3, 2) = reshape([1, 2, 3, 4, 5, 6], [3, 2])
  integer, parameter :: p_index(3, 2) = reshape([7, 8, 9, 10, 11, 12], [3, 2])
  integer, parameter :: gamma_index = 13
  integer, parameter :: tau_index(2) = [14, 15]

  !> Where a scene's unknowns sit in z: q1, q2, p1, p2 (`dimension` components each), gamma
  !> (the viscous branch only) and tau1, tau2 (thermal springs only).
  type :: pendulum_layout
    integer :: dimension = 3
    logical :: viscous = .true.
    logical :: thermal = .true.
    integer :: state_size = state_size
    integer :: q(3, 2) = q_index                !! q(1:dimension, a): q_a's columns
    integer :: p(3, 2) = p_index                !! p(1:dimension, a): p_a's columns
    integer :: gamma = gamma_index              !! 0 without the viscous branch
    integer :: tau(2) = tau_index               !! 0 for elastic springs
  contains
    procedure :: positions
    procedure :: momenta
    procedure :: kinetic_energy
    procedure :: gravity_potential
    procedure :: gravity_force
    procedure :: angular_momentum
    procedure :: spring_invariants
    procedure :: spring_columns
    procedure :: invariant_count
    procedure :: column_names
    procedure :: column_units
    procedure :: is_full
  end type pendulum_layout

  !> The paper's model: spatial, thermoviscoelastic.
  type(pendulum_layout), parameter :: full_layout = pendulum_layout()

  !> tau_a's column name (symbol and a) and units for thermo_variable's tau_entropy,
  !> tau_temperature and tau_internal_energy.
  character(len=*), parameter :: tau_symbols(3) = [character(len=5) :: 's', 'theta', 'u']
  character(len=*), parameter :: tau_units(3) = [character(len=3) :: 'J/K', 'K', 'J']
  character(len=*), parameter :: axis_names(3) = ['x', 'y', 'z']

contains

  !> The layout of a scene in `dimension` (2 or 3) with or without the viscous branch and the
  !> thermodynamic variables (an elastic scene has neither).
  pure function make_layout(dimension, viscous, thermal) result(layout)
    integer, intent(in) :: dimension
    logical, intent(in) :: viscous, thermal
    type(pendulum_layout) :: layout
    integer :: i

    layout%dimension = dimension
    layout%viscous = viscous
    layout%thermal = thermal
    layout%q = 0
    layout%p = 0
    layout%q(1:dimension, 1) = [(i, i=1, dimension)]
    layout%q(1:dimension, 2) = dimension + layout%q(1:dimension, 1)
    layout%p(1:dimension, :) = 2*dimension + layout%q(1:dimension, :)
    layout%gamma = 0
    if (viscous) layout%gamma = 4*dimension + 1
    layout%tau = 0
    if (thermal) layout%tau = 4*dimension + merge(1, 0, viscous) + [1, 2]
    layout%state_size = 4*dimension + merge(1, 0, viscous) + merge(2, 0, thermal)
  end function make_layout

  !> The spatial thermoviscoelastic layout, which the fused step kernel serves without picking rows.
  pure logical function is_full(self)
    class(pendulum_layout), intent(in) :: self

    is_full = self%dimension == 3 .and. self%viscous .and. self%thermal
  end function is_full

  !> q_a as the columns of a (dimension, 2) array.
  pure function positions(self, z) result(q)
    class(pendulum_layout), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: q(self%dimension, 2)

    q(:, 1) = z(self%q(1:self%dimension, 1))
    q(:, 2) = z(self%q(1:self%dimension, 2))
  end function positions

  !> p_a as the columns of a (dimension, 2) array.
  pure function momenta(self, z) result(p)
    class(pendulum_layout), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: p(self%dimension, 2)

    p(:, 1) = z(self%p(1:self%dimension, 1))
    p(:, 2) = z(self%p(1:self%dimension, 2))
  end function momenta

  !> v = m^-1 p with m^-1 = [[I/m1, -I/m1], [-I/m1, (m1+m2)/(m1 m2) I]]; p and v are (d, 2).
  pure function inverse_mass_times(params, p) result(v)
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: p(:, :)
    real(real64) :: v(size(p, 1), 2)
    real(real64) :: m1, m2

    m1 = params%mass(1)
    m2 = params%mass(2)
    v(:, 1) = (p(:, 1) - p(:, 2))/m1
    v(:, 2) = -p(:, 1)/m1 + (m1 + m2)/(m1*m2)*p(:, 2)
  end function inverse_mass_times

  !> T = 1/2 p . m^-1 p, eq. (6).
  pure function kinetic_energy(self, params, z) result(t)
    class(pendulum_layout), intent(in) :: self
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: z(:)
    real(real64) :: t
    real(real64) :: p(self%dimension, 2)

    p = self%momenta(z)
    t = 0.5_real64*sum(p*inverse_mass_times(params, p))
  end function kinetic_energy

  !> V_g = -(m1+m2) g.q1 - m2 g.q2.
  pure function gravity_potential(self, params, z) result(vg)
    class(pendulum_layout), intent(in) :: self
    type(pendulum_parameters), intent(in) :: params
    real(real64), intent(in) :: z(:)
    real(real64) :: vg

    vg = -sum(self%gravity_force(params)*self%positions(z))
  end function gravity_potential

  !> -grad_q V_g: the constant gravity forces on the coordinates q1 and q2, as columns
  !> (gravity's first `dimension` components).
  pure function gravity_force(self, params) result(force)
    class(pendulum_layout), intent(in) :: self
    type(pendulum_parameters), intent(in) :: params
    real(real64) :: force(self%dimension, 2)

    force(:, 1) = (params%mass(1) + params%mass(2))*params%gravity(1:self%dimension)
    force(:, 2) = params%mass(2)*params%gravity(1:self%dimension)
  end function gravity_force

  !> J = q1 x p1 + q2 x p2 (docs/formulation.md section 2); in the plane its one component
  !> about the normal, J(3), the others 0.
  pure function angular_momentum(self, z) result(j)
    class(pendulum_layout), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: j(3)
    real(real64) :: q(3, 2), p(3, 2)

    q = 0.0_real64
    p = 0.0_real64
    q(1:self%dimension, :) = self%positions(z)
    p(1:self%dimension, :) = self%momenta(z)
    j = cross(q(:, 1), p(:, 1)) + cross(q(:, 2), p(:, 2))
  end function angular_momentum

  !> Spring a's invariants x = (C, [gamma,] [tau]), C = q_a.q_a, gamma for spring 2 of the viscous
  !> branch, tau for thermal springs, and optionally dx_dz(i, j) = d x(i)/d z(spring_columns(a)(j)).
  pure subroutine spring_invariants(self, z, a, x, dx_dz)
    class(pendulum_layout), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)
    integer :: d, n

    d = self%dimension
    n = self%invariant_count(a)
    x(1) = dot_product(z(self%q(1:d, a)), z(self%q(1:d, a)))
    if (n == 3) x(2) = z(self%gamma)
    if (self%thermal) x(n) = z(self%tau(a))
    if (present(dx_dz)) then
      ! columns (q_a, [gamma,] [tau_a]): dC/dq = 2 q; gamma and tau are columns of z themselves.
      dx_dz = 0.0_real64
      dx_dz(1, 1:d) = 2.0_real64*z(self%q(1:d, a))
      if (n == 3) dx_dz(2, d + 1) = 1.0_real64
      if (self%thermal) dx_dz(n, d + n - 1) = 1.0_real64
    end if
  end subroutine spring_invariants

  !> The number of spring a's invariants: (C, tau), (C, gamma, tau) for spring 2 with the
  !> viscous branch, or C alone for an elastic spring.
  pure integer function invariant_count(self, a)
    class(pendulum_layout), intent(in) :: self
    integer, intent(in) :: a

    invariant_count = 1
    if (self%thermal) invariant_count = 2
    if (a == 2 .and. self%viscous) invariant_count = 3
  end function invariant_count

  !> The columns of z spring a's invariants depend on: q_a, [gamma,] [tau_a].
  pure function spring_columns(self, a) result(columns)
    class(pendulum_layout), intent(in) :: self
    integer, intent(in) :: a
    integer, allocatable :: columns(:)

    columns = self%q(1:self%dimension, a)
    if (self%invariant_count(a) == 3) columns = [columns, self%gamma]
    if (self%thermal) columns = [columns, self%tau(a)]
  end function spring_columns

  !> The columns' names: q1_x, ..., p2_y or p2_z, [gamma,] tau1, tau2 (the model renames the
  !> last two after its thermodynamic variable).
  pure function column_names(self) result(names)
    class(pendulum_layout), intent(in) :: self
    character(len=16) :: names(self%state_size)
    character(len=2), parameter :: vectors(4) = ['q1', 'q2', 'p1', 'p2']
    integer :: v, i

    do v = 1, 4
      do i = 1, self%dimension
        names((v - 1)*self%dimension + i) = vectors(v)//'_'//axis_names(i)
      end do
    end do
    if (self%viscous) names(self%gamma) = 'gamma'
    if (.not. self%thermal) return
    names(self%tau(1)) = 'tau1'
    names(self%tau(2)) = 'tau2'
  end function column_names

  !> The columns' units: m, N s, m (gamma); tau_a's depend on the thermodynamic variable (tau_units).
  pure function column_units(self, variable) result(units)
    class(pendulum_layout), intent(in) :: self
    integer, intent(in) :: variable
    character(len=16) :: units(self%state_size)
    integer :: a

    do a = 1, 2
      units(self%q(1:self%dimension, a)) = 'm'
      units(self%p(1:self%dimension, a)) = 'N s'
    end do
    if (self%viscous) units(self%gamma) = 'm'
    if (self%thermal) units(self%tau) = tau_units(variable)
  end function column_units

  !> The cross product a x b.
  pure function cross(a, b) result(c)
    real(real64), intent(in) :: a(3), b(3)
    real(real64) :: c(3)

    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross

end module double_pendulum
