!> The spring chain (docs/formulation.md section 10) as a GENERIC model of the engine
!> (src/structure/model_interface), on the dense path: N masses in `dimension` components, one
!> subsystem per spring a with its potentials (U_a, S_a) in x_a = (C_a, [gamma_a,] [tau_a]) (the
!> pendulum's closed forms through spring_chain_spring), T + V_g of the masses as the mechanical
!> energy, the written-out field summed from the mass, spring and link blocks of
!> spring_chain_blocks at fixed partials, L0 canonical mass by mass, K0 with Theta_a/eta_a on each
!> gamma_a and kappa Theta_a Theta_b [[1, -1], [-1, 1]] on each link's (tau_a, tau_b). Its momenta
!> are the angular momentum J = sum_i x_i x p_i (3 components in 3D, the scalar in 2D, none in
!> 1D), kept about the axes of section 10's table. Dense L0, K0 and Jacobians: for small N.
module spring_chain_model
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use number_text, only: integer_text
  use invariant_function, only: potential_u, potential_s
  use model_interface, only: generic_model, conserved_component, angular_momentum_components, &
                             model_step_figure
  use spring_chain_figures, only: production_figures, whole_chain_minima
  use spring_chain_spring, only: spring_data, chain_spring, make_chain_spring, spring_invariants, rung_elastic
  use spring_chain_layout, only: chain_layout, slots_of
  use spring_chain_partials, only: spring_partials
  use spring_chain_blocks, only: mass_block, spring_block, link_block
  use spring_chain_step, only: scatter
  implicit none (type, external)
  private
  public :: spring_chain, make_spring_chain

  !> tau_a's column name and units for thermo_variable's tau_entropy, tau_temperature and
  !> tau_internal_energy; the axes' names.
  character(len=*), parameter :: tau_symbols(3) = [character(len=5) :: 's', 'theta', 'u']
  character(len=*), parameter :: tau_units(3) = [character(len=3) :: 'J/K', 'K', 'J']
  character(len=*), parameter :: axis_names(3) = ['x', 'y', 'z']

  !> The chain: its layout, each spring's data and potentials, the masses, the links'
  !> conductivities and gravity (`dimension` components).
  type, extends(generic_model) :: spring_chain
    type(chain_layout) :: layout
    type(spring_data), allocatable :: data(:)
    type(chain_spring), allocatable :: springs(:)
    real(real64), allocatable :: masses(:)
    real(real64), allocatable :: conductivity(:)     !! one per link (a, a+1), n_s - 1
    real(real64), allocatable :: gravity(:)
  contains
    procedure :: invariants
    procedure :: vector_field
    procedure :: mechanical_energy
    procedure :: mechanical_energy_gradient
    procedure :: mechanical_energy_difference => chain_energy_difference
    procedure :: mechanical_energy_scale
    procedure :: momentum_scale
    procedure :: momenta => chain_angular_momentum
    procedure :: conserved_in_momenta
    procedure :: conserved_momenta_gradient
    procedure :: poisson_matrix_0
    procedure :: friction_matrix_0
    procedure :: in_variable
    procedure :: column_units => chain_column_units
    procedure :: state_from_temperatures
    procedure :: step_figure_list => chain_step_figure_list
    procedure :: step_figures => chain_step_figures
  end type spring_chain

  ! Implemented in spring_chain_mechanics.
  interface
    !> T + V_g = sum_i |p_i|^2/(2 m_i) - m_i g.x_i.
    pure module function mechanical_energy(self, z) result(energy)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64) :: energy
    end function mechanical_energy

    !> grad (T + V_g): -m_i g on x_i, p_i/m_i on p_i.
    pure module function mechanical_energy_gradient(self, z) result(gradient)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64) :: gradient(size(z))
    end function mechanical_energy_gradient

    !> (T + V_g)(z_b) - (T + V_g)(z_a), mass by mass without cancellation (spring_chain_balance).
    pure module function chain_energy_difference(self, z_a, z_b) result(delta)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z_a(:), z_b(:)
      real(real64) :: delta
    end function chain_energy_difference

    !> The rounding scale of T + V_g (model_interface): the sum of its terms' absolute values,
    !> |p_i|^2/(2 m_i) and |m_i g_c x_i,c| for every mass and component.
    pure module real(real64) function mechanical_energy_scale(self, z)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z(:)
    end function mechanical_energy_scale

    !> The rounding scale of J = sum_i x_i x p_i (model_interface): sum_i |x_i| |p_i|, which bounds
    !> the sum of the absolute values of every component's terms.
    pure module real(real64) function momentum_scale(self, z)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z(:)
    end function momentum_scale

    !> The momenta: J = sum_i x_i x p_i whole in 3D, its component about the plane's normal in 2D
    !> (none in 1D).
    pure module function chain_angular_momentum(self, z) result(j)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64) :: j(self%momentum_count())
    end function chain_angular_momentum

    !> The conserved components J.a (their axes a: `conserved`) from the momenta (component_values).
    pure module function conserved_in_momenta(self, momenta) result(values)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: momenta(:)
      real(real64) :: values(self%conserved_count())
    end function conserved_in_momenta

    !> d(J.a)/dp_i = a x x_i for each conserved axis a (J.a = sum_i p_i.(a x x_i)).
    pure module function conserved_momenta_gradient(self, z) result(gradients)
      class(spring_chain), intent(in) :: self
      real(real64), intent(in) :: z(:)
      real(real64) :: gradients(size(z), self%conserved_count())
    end function conserved_momenta_gradient
  end interface

contains

  !> The chain of `layout` with per-spring `data` (n_s), `masses` (N), link `conductivity`
  !> (n_s - 1) and `gravity` (`dimension` components) in thermodynamic variable `variable`.
  pure function make_spring_chain(layout, data, masses, conductivity, gravity, variable) result(model)
    type(chain_layout), intent(in) :: layout
    type(spring_data), intent(in) :: data(:)
    real(real64), intent(in) :: masses(:), conductivity(:), gravity(:)
    integer, intent(in) :: variable
    type(spring_chain) :: model
    integer :: a, i, c, n, d

    d = layout%dimension
    n = layout%invariant_count
    model%layout = layout
    allocate (model%data, source=data)
    model%masses = masses
    model%conductivity = conductivity
    model%gravity = gravity
    model%thermo_variable = variable
    model%state_size = layout%state_size()
    model%max_invariants = n
    allocate (model%column_names(model%state_size), model%springs(layout%springs), model%subsystems(layout%springs))
    do i = 1, layout%masses
      do c = 1, d
        model%column_names(layout%q_index(i, c)) = 'x'//integer_text(i)//'_'//axis_names(c)
        model%column_names(layout%p_index(i, c)) = 'p'//integer_text(i)//'_'//axis_names(c)
      end do
    end do
    do a = 1, layout%springs
      model%springs(a) = make_chain_spring(data(a), n, variable)
      associate (part => model%subsystems(a), spring => model%springs(a))
        part%name = 'spring '//integer_text(a)
        part%invariant_count = n
        part%columns = spring_columns(layout, a)
        part%tau_column = layout%tau_index(a)
        part%metric_scale = spring%metric_scale()
        allocate (part%potentials, source=spring%potentials)
        if (n /= rung_elastic) &
          model%column_names(layout%tau_index(a)) = trim(tau_symbols(variable))//'_'//integer_text(a)
        if (n == 3) model%column_names(layout%gamma_index(a)) = 'gamma_'//integer_text(a)
      end associate
    end do
    model%words%temperature = 'spring temperatures'
    model%words%energy = 'total energy E = T + V_g + sum_a U_a'
    model%words%entropy = 'total entropy S = sum_a S_a'
    model%words%metric_scales = 'C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref'
    if (n == rung_elastic) then
      model%words%energy = 'total energy E = T + V_g + sum_a W_a'
      model%words%metric_scales = 'C by (l^0)^2'
    end if
    model%words%momentum_units = 'J s'
    call declare_momenta(model)
  end function make_spring_chain

  ! J's components and the conserved ones (docs/formulation.md section 10's table).
  pure subroutine declare_momenta(model)
    type(spring_chain), intent(inout) :: model
    real(real64) :: g(3)

    g = 0.0_real64
    g(1:size(model%gravity)) = model%gravity
    allocate (model%conserved(0))
    select case (model%layout%dimension)
    case (1)
      allocate (model%momentum_names(0))
    case (2)
      model%words%momenta = 'J = sum_i x_i,x p_i,y - x_i,y p_i,x'
      model%momentum_names = [character(len=8) :: 'J']
      if (.not. model%layout%fixed_fixed .and. .not. any(abs(g) > 0.0_real64)) &
        model%conserved = [conserved_component('J', [0.0_real64, 0.0_real64, 1.0_real64])]
    case default
      model%words%momenta = 'J = sum_i x_i x p_i'
      model%momentum_names = [character(len=8) :: 'J_x', 'J_y', 'J_z']
      if (.not. model%layout%fixed_fixed) then
        model%conserved = angular_momentum_components(g)
      else if (.not. any(abs(g(2:3)) > 0.0_real64)) then
        ! Both supports lie on the x axis: J_x is kept if gravity exerts no torque about it.
        model%conserved = [conserved_component('J_x', [1.0_real64, 0.0_real64, 0.0_real64])]
      end if
    end select
  end subroutine declare_momenta

  ! The columns spring a's invariants depend on: x_{a-1} (not a support), x_a (not a support),
  ! [gamma_a,] [tau_a].
  pure function spring_columns(layout, a) result(columns)
    type(chain_layout), intent(in) :: layout
    integer, intent(in) :: a
    integer, allocatable :: columns(:)
    integer :: c

    allocate (columns(0))
    if (a > 1) columns = [columns, (layout%q_index(a - 1, c), c=1, layout%dimension)]
    if (a <= layout%masses) columns = [columns, (layout%q_index(a, c), c=1, layout%dimension)]
    if (layout%invariant_count == 3) columns = [columns, layout%gamma_index(a)]
    if (layout%invariant_count >= 2) columns = [columns, layout%tau_index(a)]
  end function spring_columns

  !> Spring a's invariants (C_a, [gamma_a,] [tau_a]) and their derivatives in its columns
  !> (spring_columns' order): dC/dx_{a-1} = -2 r_a, dC/dx_a = 2 r_a, 1 for gamma_a and tau_a.
  pure subroutine invariants(self, z, a, x, dx_dz)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)
    real(real64) :: r(self%layout%dimension), dc_dr(self%layout%dimension), gamma, tau
    integer :: n, d, k

    n = self%layout%invariant_count
    d = self%layout%dimension
    r = position(self, z, a) - position(self, z, a - 1)
    gamma = 0.0_real64
    tau = 0.0_real64
    if (n == 3) gamma = z(self%layout%gamma_index(a))
    if (n >= 2) tau = z(self%layout%tau_index(a))
    call spring_invariants(r, gamma, tau, n, x, dc_dr)
    if (.not. present(dx_dz)) return
    dx_dz = 0.0_real64
    k = 0
    if (a > 1) then
      dx_dz(1, 1:d) = -dc_dr
      k = d
    end if
    if (a <= self%layout%masses) then
      dx_dz(1, k + 1:k + d) = dc_dr
      k = k + d
    end if
    if (n == 3) dx_dz(2, k + 1) = 1.0_real64
    if (n >= 2) dx_dz(n, size(self%subsystems(a)%columns)) = 1.0_real64
  end subroutine invariants

  ! x_i from z, or the support's position (i = 0, or N + 1 with 'fixed-fixed' ends).
  pure function position(self, z, i) result(x)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: i
    real(real64) :: x(self%layout%dimension)
    integer :: c

    if (i < 1 .or. i > self%layout%masses) then
      x = self%layout%support(i)
    else
      x = [(z(self%layout%q_index(i, c)), c=1, self%layout%dimension)]
    end if
  end function position

  !> The written-out field of docs/formulation.md section 10 at z with the given partials: the
  !> blocks of spring_chain_blocks at the state itself (weight 1, no derivatives of the partials
  !> in z), so df/dz is at fixed partials; df/dpartials from the blocks' derivatives in them.
  pure subroutine vector_field(self, z, partials, f, df_dz, df_dpartials)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df_dz(:, :), df_dpartials(:, :, :, :)
    type(spring_partials) :: parts(self%layout%springs)
    integer :: a, i, d, n, r

    d = self%layout%dimension
    n = self%layout%invariant_count
    f = 0.0_real64
    if (present(df_dz)) df_dz = 0.0_real64
    if (present(df_dpartials)) df_dpartials = 0.0_real64
    do a = 1, self%layout%springs
      parts(a)%invariants = n
      parts(a)%slots = slots_of(d, n)
      parts(a)%partials(1:n, :) = partials(1:n, :, a)
      parts(a)%weight = 1.0_real64
      parts(a)%r(1:d) = position(self, z, a) - position(self, z, a - 1)
      if (n >= 2) parts(a)%theta = partials(n, potential_u, a)/partials(n, potential_s, a)
    end do
    do i = 1, self%layout%masses
      block
        integer :: indices(2*d)
        real(real64) :: fl(2*d), dfl(2*d, 2*d)

        indices = self%layout%mass_indices(i)
        call mass_block(self%masses(i), self%gravity, z(indices(d + 1:)), z(indices(d + 1:)), 1.0_real64, fl, dfl)
        call scatter(indices, fl, dfl, f, df_dz)
      end block
    end do
    do a = 1, self%layout%springs
      block
        integer :: indices(self%layout%spring_size())
        real(real64) :: fl(size(indices)), dfl(size(indices), size(indices)), values(size(indices))
        real(real64) :: dfl_dpartials(size(indices), 3, 2)

        indices = self%layout%spring_indices(a)
        values = self%layout%gather_spring(z, a)
        call spring_block(self%springs(a), parts(a), values, values, inverse_mass(a - 1), inverse_mass(a), fl, dfl, &
                          dfl_dpartials)
        call scatter(indices, fl, dfl, f, df_dz)
        if (present(df_dpartials)) then
          do r = 1, size(indices)
            if (indices(r) > 0) df_dpartials(indices(r), 1:n, :, a) = df_dpartials(indices(r), 1:n, :, a) &
                                                                      + dfl_dpartials(r, 1:n, :)
          end do
        end if
      end block
    end do
    if (n == rung_elastic) return
    do a = 1, self%layout%springs - 1
      block
        integer :: indices(3*d + 2*(n - 1))
        real(real64) :: fl(size(indices)), dfl(size(indices), size(indices)), dfl_dtau(size(indices), 2, 2)

        indices = self%layout%link_indices(a)
        call link_block(self%conductivity(a), parts(a), parts(a + 1), fl, dfl, dfl_dtau)
        call scatter(indices, fl, dfl, f, df_dz)
        if (present(df_dpartials)) then
          do r = 1, size(indices)
            if (indices(r) == 0) cycle
            df_dpartials(indices(r), n, :, a) = df_dpartials(indices(r), n, :, a) + dfl_dtau(r, :, 1)
            df_dpartials(indices(r), n, :, a + 1) = df_dpartials(indices(r), n, :, a + 1) + dfl_dtau(r, :, 2)
          end do
        end if
      end block
    end do

  contains

    pure real(real64) function inverse_mass(k)
      integer, intent(in) :: k

      inverse_mass = 0.0_real64
      if (k >= 1 .and. k <= self%layout%masses) inverse_mass = 1.0_real64/self%masses(k)
    end function inverse_mass
  end subroutine vector_field

  !> L0: canonical on (x_i, p_i), mass by mass; zero on gamma and tau.
  pure function poisson_matrix_0(self) result(l0)
    class(spring_chain), intent(in) :: self
    real(real64) :: l0(self%state_size, self%state_size)
    integer :: i, c

    l0 = 0.0_real64
    do i = 1, self%layout%masses
      do c = 1, self%layout%dimension
        l0(self%layout%q_index(i, c), self%layout%p_index(i, c)) = 1.0_real64
        l0(self%layout%p_index(i, c), self%layout%q_index(i, c)) = -1.0_real64
      end do
    end do
  end function poisson_matrix_0

  !> K0 at the temperatures Theta_a of the partials: Theta_a/eta_a(Theta_a) on each gamma_a and,
  !> for each link (a, a+1), kappa_a Theta_a Theta_{a+1} [[1, -1], [-1, 1]] on (tau_a, tau_{a+1}).
  pure function friction_matrix_0(self, partials) result(k0)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: partials(:, :, :)
    real(real64) :: k0(self%state_size, self%state_size)
    real(real64) :: theta(self%temperature_count()), eta, conduction
    integer :: a, g, t(2)

    k0 = 0.0_real64
    if (self%layout%invariant_count == rung_elastic) return
    theta = self%partials_temperatures(partials)
    do a = 1, self%layout%springs
      g = self%layout%gamma_index(a)
      if (g == 0) cycle
      call self%springs(a)%viscosity(theta(a), eta)
      k0(g, g) = theta(a)/eta
    end do
    do a = 1, self%layout%springs - 1
      conduction = self%conductivity(a)*theta(a)*theta(a + 1)
      t = [self%layout%tau_index(a), self%layout%tau_index(a + 1)]
      k0(t, t) = k0(t, t) + reshape([conduction, -conduction, -conduction, conduction], [2, 2])
    end do
  end function friction_matrix_0

  !> The same chain in another thermodynamic variable.
  subroutine in_variable(self, variable, other)
    class(spring_chain), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: other

    allocate (other, source=make_spring_chain(self%layout, self%data, self%masses, self%conductivity, self%gravity, &
                                              variable))
  end subroutine in_variable

  !> The units of z's columns: m, N s, m (gamma), and tau_a's in the model's variable.
  pure subroutine chain_column_units(self, units)
    class(spring_chain), intent(in) :: self
    character(len=*), intent(out) :: units(:)
    integer :: i, a

    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i), d => self%layout%dimension)
        units(k(1:d)) = 'm'
        units(k(d + 1:)) = 'N s'
      end associate
    end do
    do a = 1, self%layout%springs
      if (self%layout%gamma_index(a) > 0) units(self%layout%gamma_index(a)) = 'm'
      if (self%layout%tau_index(a) > 0) units(self%layout%tau_index(a)) = tau_units(self%thermo_variable)
    end do
  end subroutine chain_column_units

  !> The state z from the masses' positions x(:, i) and momenta p(:, i) (`dimension` x N), each
  !> spring's gamma (used on the thermoviscoelastic rung) and temperature theta (n_s; the thermal
  !> rungs); stat a domain code if a spring cannot have that temperature there.
  pure subroutine state_from_temperatures(self, x, p, gamma, theta, z, stat)
    class(spring_chain), intent(in) :: self
    real(real64), intent(in) :: x(:, :), p(:, :), gamma(:), theta(:)
    real(real64), intent(out) :: z(:)
    integer, intent(out) :: stat
    real(real64) :: invariant(3)
    integer :: i, a, n, d

    d = self%layout%dimension
    n = self%layout%invariant_count
    z = 0.0_real64
    do i = 1, self%layout%masses
      associate (k => self%layout%mass_indices(i))
        z(k(1:d)) = x(:, i)
        z(k(d + 1:)) = p(:, i)
      end associate
    end do
    stat = failure_none
    do a = 1, self%layout%springs
      if (n == 3) z(self%layout%gamma_index(a)) = gamma(a)
      if (n == rung_elastic) cycle
      call self%invariants(z, a, invariant(1:n))
      call self%subsystems(a)%potentials%tau_from_temperature(invariant(1:n - 1), theta(a), &
                                                              z(self%layout%tau_index(a)), stat)
      if (stat /= failure_none) return
    end do
  end subroutine state_from_temperatures

  !> The chain's figures of each step in a run's rows (generic_model's step_figure_list): the
  !> smallest entropy production of a viscous branch and of a conducting link.
  function chain_step_figure_list(self) result(figures)
    class(spring_chain), intent(in) :: self
    type(model_step_figure), allocatable :: figures(:)

    figures = production_figures()
  end function chain_step_figure_list

  !> Their values for the step old -> new of `scheme` (generic_model's step_figures).
  subroutine chain_step_figures(self, scheme, gradient, metric, old, new, values, stat)
    class(spring_chain), intent(in) :: self
    character(len=*), intent(in) :: scheme
    integer, intent(in) :: gradient, metric
    real(real64), intent(in) :: old(:), new(:)
    real(real64), allocatable, intent(out) :: values(:)
    integer, intent(out) :: stat

    allocate (values(2))
    call whole_chain_minima(self%layout, self%springs, self%conductivity, scheme, gradient, metric, old, new, values, stat)
  end subroutine chain_step_figures

end module spring_chain_model
