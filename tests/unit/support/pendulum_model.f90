!> The thermoviscoelastic double pendulum as a GENERIC model (src/structure/model_interface):
!> two springs, each a subsystem with (U_a, S_a) in its invariants (C_a, [gamma,] tau_a) for one
!> choice of thermodynamic variable; kinetic energy and gravity as the mechanical energy; the
!> written-out vector field of src/model/pendulum/pendulum_vector_field. The scene's parts
!> (params%spring_law, params%dimension) decide its unknowns (double_pendulum's layout).
module pendulum_model
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use free_energy, only: spring_law_of, viscosity
  use thermo_variable, only: spring_potential
  use elastic_potential, only: elastic_spring, make_elastic_spring
  use model_interface, only: generic_model, angular_momentum_components, component_values, conserved_component
  use double_pendulum, only: pendulum_layout, make_layout, tau_symbols, inverse_mass_times, cross
  use pendulum_vector_field, only: vector_field
  implicit none (type, external)
  private
  public :: pendulum, make_pendulum

  !> Parameters and the spring potentials (U_a, S_a) in the chosen thermodynamic variable.
  type, extends(generic_model) :: pendulum
    type(pendulum_parameters) :: params
    type(pendulum_layout) :: layout
    type(spring_potential) :: spring(2)
  contains
    procedure :: invariants
    procedure :: vector_field => pendulum_field
    procedure :: mechanical_energy
    procedure :: mechanical_energy_scale
    procedure :: momentum_scale
    procedure :: mechanical_energy_gradient
    procedure :: momenta => pendulum_angular_momentum
    procedure :: poisson_matrix_0
    procedure :: friction_matrix_0
    procedure :: in_variable
    procedure :: conserved_in_momenta
    procedure :: conserved_momenta_gradient
    procedure :: mechanical_energy_difference => pendulum_energy_difference
    procedure :: state_from_temperatures
    procedure :: column_units => pendulum_column_units
  end type pendulum

contains

  !> The model for parameters `params` and thermodynamic variable `variable` (tau_* constant).
  pure function make_pendulum(params, variable) result(model)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: variable
    type(pendulum) :: model
    integer :: a

    model%params = params
    model%layout = make_layout(params%dimension, params%viscous(), params%thermal())
    model%thermo_variable = variable
    model%state_size = model%layout%state_size
    allocate (model%column_names(model%state_size))
    model%column_names(:) = model%layout%column_names()
    model%max_invariants = maxval([(model%layout%invariant_count(a), a=1, 2)])
    model%words%temperature = 'spring temperatures'
    model%words%energy = 'total energy E = T + V_g + U_1 + U_2'
    model%words%entropy = 'total entropy S = S_1 + S_2'
    model%words%momentum_units = 'J s'
    model%words%metric_scales = 'C by (l^0)^2, gamma by 1 m, theta by theta_ref, s by Cap, u by Cap theta_ref'
    allocate (model%conserved(0))
    if (params%dimension == 3) then
      ! In space J is recorded whole; gravity keeps its component along g (J_z in the paper's
      ! scenes), no gravity all three (docs/formulation.md section 2).
      model%words%momenta = 'J = q1 x p1 + q2 x p2'
      model%momentum_names = [character(len=8) :: 'J_x', 'J_y', 'J_z']
      model%conserved = angular_momentum_components(params%gravity)
    else if (.not. any(abs(params%gravity(1:2)) > 0.0_real64)) then
      ! In the plane without gravity: J about the plane's normal; with gravity, no momentum is kept.
      model%words%momenta = 'J = q1_x p1_y - q1_y p1_x + q2_x p2_y - q2_y p2_x'
      model%momentum_names = [character(len=8) :: 'J']
      model%conserved = [conserved_component('J', [0.0_real64, 0.0_real64, 1.0_real64])]
    end if
    allocate (model%subsystems(2))
    do a = 1, 2
      model%spring(a)%law = spring_law_of(params, a)
      model%spring(a)%variable = variable
      model%spring(a)%n_invariants = model%layout%invariant_count(a)
      associate (part => model%subsystems(a))
        part%name = 'spring '//achar(iachar('0') + a)
        part%invariant_count = model%layout%invariant_count(a)
        part%columns = model%layout%spring_columns(a)
        part%tau_column = model%layout%tau(a)
        if (params%thermal()) then
          allocate (part%potentials, source=model%spring(a))
          ! s_1, theta_1, u_1: spelt as /temperature's columns theta_1 theta_2 (docs/output.md).
          model%column_names(model%layout%tau(a)) = trim(tau_symbols(variable))//'_'//achar(iachar('0') + a)
          part%metric_scale = model%spring(a)%metric_scale()
        else
          allocate (part%potentials, source=make_elastic_spring(params, a))
          part%metric_scale = [params%natural_length(a)**2]
        end if
      end associate
    end do
    if (.not. params%thermal()) then
      model%words%energy = 'total energy E = T + V_g + W_1 + W_2'
      model%words%metric_scales = 'C by (l^0)^2'
    end if
  end function make_pendulum

  !> The units of z's columns: m, N s, m (gamma), and tau_a's in the model's variable.
  pure subroutine pendulum_column_units(self, units)
    class(pendulum), intent(in) :: self
    character(len=*), intent(out) :: units(:)

    units = self%layout%column_units(self%thermo_variable)
  end subroutine pendulum_column_units

  !> Spring a's invariants (C_a, [gamma,] tau_a) and their derivatives in its columns.
  pure subroutine invariants(self, z, a, x, dx_dz)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)

    call self%layout%spring_invariants(z, a, x, dx_dz)
  end subroutine invariants

  !> The written-out field of docs/formulation.md section 4 (pendulum_vector_field).
  pure subroutine pendulum_field(self, z, partials, f, df_dz, df_dpartials)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df_dz(:, :), df_dpartials(:, :, :, :)

    call vector_field(self%params, self%layout, z, partials, f, df_dz, df_dpartials)
  end subroutine pendulum_field

  !> T + V_g: kinetic energy (6) and gravity.
  pure function mechanical_energy(self, z) result(energy)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: energy

    energy = self%layout%kinetic_energy(self%params, z) + self%layout%gravity_potential(self%params, z)
  end function mechanical_energy

  !> The rounding scale of T + V_g (model_interface): T's terms p_a.(m^-1 p)_b in absolute value,
  !> 1/2 (|p1|^2/m1 + 2 |p1||p2|/m1 + (m1+m2)/(m1 m2) |p2|^2), and gravity's |f_a . q_a| summed
  !> by component, f_1 = (m1+m2) g and f_2 = m2 g (read from z in place: the step check's cost).
  pure real(real64) function mechanical_energy_scale(self, z)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: p1_squared, p2_squared, gravity_terms, m1, m2
    integer :: i

    m1 = self%params%mass(1)
    m2 = self%params%mass(2)
    p1_squared = 0.0_real64
    p2_squared = 0.0_real64
    gravity_terms = 0.0_real64
    associate (q => self%layout%q, p => self%layout%p, g => self%params%gravity)
      do i = 1, self%layout%dimension
        p1_squared = p1_squared + z(p(i, 1))**2
        p2_squared = p2_squared + z(p(i, 2))**2
        gravity_terms = gravity_terms + abs(g(i))*((m1 + m2)*abs(z(q(i, 1))) + m2*abs(z(q(i, 2))))
      end do
    end associate
    mechanical_energy_scale = 0.5_real64*(p1_squared/m1 + 2*sqrt(p1_squared*p2_squared)/m1 &
                                          + (m1 + m2)/(m1*m2)*p2_squared) + gravity_terms
  end function mechanical_energy_scale

  !> The rounding scale of J = q1 x p1 + q2 x p2 (model_interface): |q1||p1| + |q2||p2|.
  pure real(real64) function momentum_scale(self, z)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: q_squared(2), p_squared(2)
    integer :: i

    q_squared = 0.0_real64
    p_squared = 0.0_real64
    associate (q => self%layout%q, p => self%layout%p)
      do i = 1, self%layout%dimension
        q_squared = q_squared + z(q(i, :))**2
        p_squared = p_squared + z(p(i, :))**2
      end do
    end associate
    momentum_scale = sum(sqrt(q_squared*p_squared))
  end function momentum_scale

  !> grad (T + V_g): -gravity forces on q, m^-1 p on p.
  pure function mechanical_energy_gradient(self, z) result(gradient)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradient(size(z))
    real(real64) :: force(self%layout%dimension, 2), v(self%layout%dimension, 2)
    integer :: a

    force = self%layout%gravity_force(self%params)
    v = inverse_mass_times(self%params, self%layout%momenta(z))
    gradient = 0.0_real64
    do a = 1, 2
      gradient(self%layout%q(1:self%layout%dimension, a)) = -force(:, a)
      gradient(self%layout%p(1:self%layout%dimension, a)) = v(:, a)
    end do
  end function mechanical_energy_gradient

  !> The momenta: J = q1 x p1 + q2 x p2 (docs/formulation.md section 2), in the plane its
  !> component about the normal.
  pure function pendulum_angular_momentum(self, z) result(j)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: j(self%momentum_count())
    real(real64) :: all_components(3)

    all_components = self%layout%angular_momentum(z)
    if (size(j) == 3) then
      j = all_components
    else if (size(j) == 1) then
      j = all_components(3)
    end if
  end function pendulum_angular_momentum

  !> L0 of eq. (12): the canonical symplectic matrix on (q, p), zero elsewhere.
  pure function poisson_matrix_0(self) result(l0)
    class(pendulum), intent(in) :: self
    real(real64) :: l0(self%state_size, self%state_size)
    integer :: i, a

    l0 = 0.0_real64
    do a = 1, 2
      do i = 1, self%layout%dimension
        l0(self%layout%q(i, a), self%layout%p(i, a)) = 1.0_real64
        l0(self%layout%p(i, a), self%layout%q(i, a)) = -1.0_real64
      end do
    end do
  end function poisson_matrix_0

  !> K0 of eq. (12) at the temperatures Theta_a of the partials: Theta_2/eta(Theta_2) on gamma,
  !> kappa Theta_1 Theta_2 [[1, -1], [-1, 1]] on (tau_1, tau_2).
  pure function friction_matrix_0(self, partials) result(k0)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: partials(:, :, :)
    real(real64) :: k0(self%state_size, self%state_size)
    real(real64) :: theta(2), conduction

    k0 = 0.0_real64
    if (.not. self%layout%thermal) return      ! elastic springs: no dissipation
    theta = self%partials_temperatures(partials)
    if (self%layout%viscous) k0(self%layout%gamma, self%layout%gamma) = theta(2)/viscosity(self%params, theta(2))
    conduction = self%params%conductivity*theta(1)*theta(2)
    k0(self%layout%tau, self%layout%tau) = reshape([conduction, -conduction, -conduction, conduction], [2, 2])
  end function friction_matrix_0

  !> The pendulum in another thermodynamic variable.
  subroutine in_variable(self, variable, other)
    class(pendulum), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: other

    allocate (other, source=make_pendulum(self%params, variable))
  end subroutine in_variable

  !> The conserved components J.a of J = q1 x p1 + q2 x p2 (their axes a: `conserved`) from the
  !> momenta (component_values).
  pure function conserved_in_momenta(self, momenta) result(values)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: momenta(:)
    real(real64) :: values(self%conserved_count())

    values = component_values(self%conserved, momenta)
  end function conserved_in_momenta

  !> d(J.a)/dp for each axis a: a x q1 for p1, a x q2 for p2 (J.a = p1.(a x q1) + p2.(a x q2)).
  pure function conserved_momenta_gradient(self, z) result(gradients)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradients(size(z), self%conserved_count())
    real(real64) :: q(3)
    integer :: a, d, k

    d = self%layout%dimension
    gradients = 0.0_real64
    do k = 1, size(gradients, 2)
      do a = 1, 2
        q = 0.0_real64
        q(1:d) = z(self%layout%q(1:d, a))
        associate (gradient_p => cross(self%conserved(k)%axis, q))
          gradients(self%layout%p(1:d, a), k) = gradient_p(1:d)
        end associate
      end do
    end do
  end function conserved_momenta_gradient

  !> (T + V_g)(z_b) - (T + V_g)(z_a) without cancellation: T is quadratic, so its difference is
  !> 1/2 (p_b - p_a).m^-1 (p_b + p_a); V_g is linear.
  pure function pendulum_energy_difference(self, z_a, z_b) result(delta)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: z_a(:), z_b(:)
    real(real64) :: delta
    real(real64) :: p_a(self%layout%dimension, 2), p_b(self%layout%dimension, 2)
    real(real64) :: q_a(self%layout%dimension, 2), q_b(self%layout%dimension, 2)

    p_a = self%layout%momenta(z_a)
    p_b = self%layout%momenta(z_b)
    q_a = self%layout%positions(z_a)
    q_b = self%layout%positions(z_b)
    delta = 0.5_real64*sum((p_b - p_a)*inverse_mass_times(self%params, p_b + p_a)) &
            - sum(self%layout%gravity_force(self%params)*(q_b - q_a))
  end function pendulum_energy_difference

  !> The state z built from positions, momenta (`dimension` components each), gamma (used with
  !> the viscous branch only) and spring temperatures theta(2).
  pure subroutine state_from_temperatures(self, q1, q2, p1, p2, gamma, theta, z, stat)
    class(pendulum), intent(in) :: self
    real(real64), intent(in) :: q1(:), q2(:), p1(:), p2(:), gamma, theta(2)
    real(real64), intent(out) :: z(:)
    integer, intent(out) :: stat
    real(real64) :: x(3)
    integer :: a, n

    associate (layout => self%layout, d => self%layout%dimension)
      z(layout%q(1:d, 1)) = q1
      z(layout%q(1:d, 2)) = q2
      z(layout%p(1:d, 1)) = p1
      z(layout%p(1:d, 2)) = p2
      if (layout%viscous) z(layout%gamma) = gamma
      stat = 0
      if (.not. layout%thermal) return
      z(layout%tau) = 0.0_real64
      do a = 1, 2
        n = layout%invariant_count(a)
        call layout%spring_invariants(z, a, x(1:n))
        call self%spring(a)%tau_from_temperature(x(1:n - 1), theta(a), z(layout%tau(a)), stat)
        if (stat /= 0) return
      end do
    end associate
  end subroutine state_from_temperatures

end module pendulum_model
