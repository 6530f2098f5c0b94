!> A second model for the tests, to show that the schemes, the solver and the structure checks
!> work on the model interface (src/structure/model_interface) whatever the model: one mass m on
!> a thermoviscoelastic spring fixed at the origin (the paper's spring 2 alone, its law, mass and
!> viscosity from &model), under gravity, without conduction. 8 unknowns and one subsystem:
!>   z = (q(3), p(3), gamma, tau),   invariants (C = q.q, gamma, tau),
!>   dq/dt = p/m,   dp/dt = m g - 2 q (U_C - Theta S_C),   dgamma/dt = (Theta S_gamma - U_gamma)/eta(Theta),
!>   dtau/dt = -2 S_C q.(p/m)/S_tau - (U_gamma/U_tau) dgamma/dt,   Theta = U_tau/S_tau,
!> docs/formulation.md section 4 with one spring; L0 is canonical on (q, p), K0 has Theta/eta(Theta) on gamma.
module single_spring_model
  use, intrinsic :: iso_fortran_env, only: real64
  use model_parameters, only: pendulum_parameters
  use free_energy, only: spring_law_of, viscosity
  use invariant_function, only: potential_u, potential_s
  use thermo_variable, only: spring_potential
  use model_interface, only: generic_model, angular_momentum_components, component_values, conserved_component
  implicit none (type, external)
  private
  public :: single_spring, make_single_spring

  integer, parameter :: gamma_column = 7, tau_column = 8
  integer, parameter :: slot_c = 1, slot_gamma = 2, slot_tau = 3
  character(len=*), parameter :: column_names(8) = [character(len=16) :: 'q_x', 'q_y', 'q_z', 'p_x', 'p_y', 'p_z', &
                                                    'gamma', 'tau']

  !> The spring, its mass and gravity.
  type, extends(generic_model) :: single_spring
    type(pendulum_parameters) :: params
    type(spring_potential) :: spring
    real(real64) :: mass = 1.0_real64
  contains
    procedure :: invariants
    procedure :: vector_field
    procedure :: mechanical_energy
    procedure :: mechanical_energy_gradient
    procedure :: momenta => angular_momentum
    procedure :: poisson_matrix_0
    procedure :: friction_matrix_0
    procedure :: in_variable
    procedure :: conserved_in_momenta
    procedure :: conserved_momenta_gradient
    procedure :: state_from_temperature
  end type single_spring

contains

  !> The model with spring 2's law and mass from `params`, in thermodynamic variable `variable`.
  pure function make_single_spring(params, variable) result(model)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: variable
    type(single_spring) :: model
    type(conserved_component), allocatable :: conserved(:)

    model%params = params
    model%mass = params%mass(2)
    model%spring%law = spring_law_of(params, 2)
    model%spring%variable = variable
    model%thermo_variable = variable
    model%spring%n_invariants = 3
    model%state_size = 8
    allocate (model%column_names(size(column_names)))
    model%column_names(:) = column_names
    model%max_invariants = 3
    model%momentum_names = [character(len=8) :: 'J_x', 'J_y', 'J_z']
    conserved = angular_momentum_components(params%gravity)
    call move_alloc(conserved, model%conserved)
    allocate (model%subsystems(1))
    associate (part => model%subsystems(1))
      part%name = 'spring'
      allocate (part%potentials, source=model%spring)
      part%invariant_count = 3
      part%columns = [1, 2, 3, gamma_column, tau_column]
      part%tau_column = tau_column
      part%metric_scale = model%spring%metric_scale()
    end associate
  end function make_single_spring

  pure subroutine invariants(self, z, a, x, dx_dz)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)

    x = [dot_product(z(1:3), z(1:3)), z(gamma_column), z(tau_column)]
    if (present(dx_dz)) then
      dx_dz = 0.0_real64
      dx_dz(1, 1:3) = 2.0_real64*z(1:3)
      dx_dz(2, 4) = 1.0_real64
      dx_dz(3, 5) = 1.0_real64
    end if
  end subroutine invariants

  pure subroutine vector_field(self, z, partials, f, df_dz, df_dpartials)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df_dz(:, :), df_dpartials(:, :, :, :)
    real(real64) :: v(3), theta, thermal_force, work_rate, inv_eta, rate, drate_dtheta, df_dtheta(8)
    integer :: i

    associate (u_c => partials(slot_c, potential_u, 1), s_c => partials(slot_c, potential_s, 1), &
               u_g => partials(slot_gamma, potential_u, 1), s_g => partials(slot_gamma, potential_s, 1), &
               u_tau => partials(slot_tau, potential_u, 1), s_tau => partials(slot_tau, potential_s, 1), &
               q => z(1:3))
      v = z(4:6)/self%mass
      theta = u_tau/s_tau
      thermal_force = u_c - theta*s_c
      work_rate = dot_product(q, v)
      inv_eta = 1.0_real64/viscosity(self%params, theta)
      rate = (theta*s_g - u_g)*inv_eta
      f(1:3) = v
      f(4:6) = self%mass*self%params%gravity - 2.0_real64*thermal_force*q
      f(gamma_column) = rate
      f(tau_column) = -2.0_real64*s_c*work_rate/s_tau - u_g/u_tau*rate
      if (present(df_dz)) then
        df_dz = 0.0_real64
        do i = 1, 3
          df_dz(i, 3 + i) = 1.0_real64/self%mass
          df_dz(3 + i, i) = -2.0_real64*thermal_force
        end do
        df_dz(tau_column, 1:3) = -2.0_real64*s_c*v/s_tau
        df_dz(tau_column, 4:6) = -2.0_real64*s_c*q/(s_tau*self%mass)
      end if
      if (present(df_dpartials)) then
        df_dpartials = 0.0_real64
        ! Derivatives at fixed Theta, then Theta = U_tau/S_tau by the chain rule.
        drate_dtheta = s_g*inv_eta + rate*self%params%viscosity_activation/theta**2
        df_dtheta = 0.0_real64
        df_dtheta(4:6) = 2.0_real64*s_c*q
        df_dtheta(gamma_column) = drate_dtheta
        df_dtheta(tau_column) = -u_g/u_tau*drate_dtheta
        df_dpartials(4:6, slot_c, potential_u, 1) = -2.0_real64*q
        df_dpartials(4:6, slot_c, potential_s, 1) = 2.0_real64*theta*q
        df_dpartials(gamma_column, slot_gamma, potential_s, 1) = theta*inv_eta
        df_dpartials(gamma_column, slot_gamma, potential_u, 1) = -inv_eta
        df_dpartials(tau_column, slot_c, potential_s, 1) = -2.0_real64*work_rate/s_tau
        df_dpartials(tau_column, slot_tau, potential_s, 1) = 2.0_real64*s_c*work_rate/s_tau**2
        df_dpartials(tau_column, slot_gamma, potential_s, 1) = -u_g/u_tau*theta*inv_eta
        df_dpartials(tau_column, slot_gamma, potential_u, 1) = -rate/u_tau + u_g/u_tau*inv_eta
        df_dpartials(tau_column, slot_tau, potential_u, 1) = u_g*rate/u_tau**2
        df_dpartials(:, slot_tau, potential_u, 1) = df_dpartials(:, slot_tau, potential_u, 1) + df_dtheta/s_tau
        df_dpartials(:, slot_tau, potential_s, 1) = df_dpartials(:, slot_tau, potential_s, 1) - df_dtheta*theta/s_tau
      end if
    end associate
  end subroutine vector_field

  !> T + V_g = p.p/(2 m) - m g.q.
  pure function mechanical_energy(self, z) result(energy)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: energy

    energy = 0.5_real64*dot_product(z(4:6), z(4:6))/self%mass - self%mass*dot_product(self%params%gravity, z(1:3))
  end function mechanical_energy

  pure function mechanical_energy_gradient(self, z) result(gradient)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradient(size(z))

    gradient = 0.0_real64
    gradient(1:3) = -self%mass*self%params%gravity
    gradient(4:6) = z(4:6)/self%mass
  end function mechanical_energy_gradient

  !> J = q x p.
  pure function angular_momentum(self, z) result(j)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: j(self%momentum_count())

    j = [z(2)*z(6) - z(3)*z(5), z(3)*z(4) - z(1)*z(6), z(1)*z(5) - z(2)*z(4)]
  end function angular_momentum

  pure function poisson_matrix_0(self) result(l0)
    class(single_spring), intent(in) :: self
    real(real64) :: l0(self%state_size, self%state_size)
    integer :: i

    l0 = 0.0_real64
    do i = 1, 3
      l0(i, 3 + i) = 1.0_real64
      l0(3 + i, i) = -1.0_real64
    end do
  end function poisson_matrix_0

  pure function friction_matrix_0(self, partials) result(k0)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: partials(:, :, :)
    real(real64) :: k0(self%state_size, self%state_size)
    real(real64) :: theta

    theta = partials(slot_tau, potential_u, 1)/partials(slot_tau, potential_s, 1)
    k0 = 0.0_real64
    k0(gamma_column, gamma_column) = theta/viscosity(self%params, theta)
  end function friction_matrix_0

  subroutine in_variable(self, variable, other)
    class(single_spring), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: other

    allocate (other, source=make_single_spring(self%params, variable))
  end subroutine in_variable

  !> J.a about each conserved axis a (J_z under the tests' gravity along z), from J.
  pure function conserved_in_momenta(self, momenta) result(values)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: momenta(:)
    real(real64) :: values(self%conserved_count())

    values = component_values(self%conserved, momenta)
  end function conserved_in_momenta

  !> d(J.a)/dp = a x q for each conserved axis a.
  pure function conserved_momenta_gradient(self, z) result(gradients)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradients(size(z), self%conserved_count())
    integer :: k

    gradients = 0.0_real64
    do k = 1, size(gradients, 2)
      associate (a => self%conserved(k)%axis)
        gradients(4:6, k) = [a(2)*z(3) - a(3)*z(2), a(3)*z(1) - a(1)*z(3), a(1)*z(2) - a(2)*z(1)]
      end associate
    end do
  end function conserved_momenta_gradient

  !> The state from position, momentum, gamma and temperature.
  subroutine state_from_temperature(self, q, p, gamma, theta, z)
    class(single_spring), intent(in) :: self
    real(real64), intent(in) :: q(3), p(3), gamma, theta
    real(real64), intent(out) :: z(8)
    integer :: stat

    z = [q, p, gamma, 0.0_real64]
    call self%spring%tau_from_temperature([dot_product(q, q), gamma], theta, z(tau_column), stat)
    if (stat /= 0) error stop 'single_spring_model: state outside the domain'
  end subroutine state_from_temperature

end module single_spring_model
