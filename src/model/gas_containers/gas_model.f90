!> The two gas containers (docs/formulation.md section 8): a piston at q between two containers
!> of volumes v_1 = q and v_2 = 2 - q, with momentum p (unit mass), each container a
!> thermodynamic subsystem with its variable tau_a. E = p^2/2 + U_1(v_1, tau_1) + U_2(v_2, tau_2),
!> S = S_1 + S_2; L0 is canonical in (q, p), K0 = friction [[1, -1], [-1, 1]] on (tau_1, tau_2)
!> through the split of docs/formulation.md section 4. Written out, with Theta_a = dU_a/dtau / dS_a/dtau:
!>   dq/dt     = p
!>   dp/dt     = -(dU_1/dv - Theta_1 dS_1/dv) + (dU_2/dv - Theta_2 dS_2/dv)
!>   dtau_a/dt = -(dS_a/dv) w_a / (dS_a/dtau) + friction (1/Theta_a - 1/Theta_b) / (dU_a/dtau)
!> with w_1 = p, w_2 = -p (dv_a/dt), so that dE/dt = 0 and dS/dt = friction (1/Theta_1 - 1/Theta_2)^2.
!> No momentum is conserved.
module gas_model
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use model_interface, only: generic_model, add_temperature_chain
  use gas_potential, only: container_potential
  implicit none (type, external)
  private
  public :: gas_containers, make_gas_containers, q_column, p_column, tau_columns

  integer, parameter :: q_column = 1, p_column = 2
  integer, parameter :: tau_columns(2) = [3, 4]
  integer, parameter :: slot_v = 1, slot_tau = 2          !! a container's invariants
  !> The total volume of the two containers.
  real(real64), parameter :: total_volume = 2.0_real64
  character(len=5), parameter :: tau_symbols(3) = [character(len=5) :: 's', 'theta', 'u']

  !> The model, with its friction coefficient.
  type, extends(generic_model) :: gas_containers
    real(real64) :: friction = 8.0_real64
  contains
    procedure :: invariants
    procedure :: vector_field
    procedure :: mechanical_energy
    procedure :: mechanical_energy_gradient
    procedure :: mechanical_energy_difference
    procedure :: poisson_matrix_0
    procedure :: friction_matrix_0
    procedure :: in_variable
    procedure :: column_units
  end type gas_containers

contains

  !> The model with friction coefficient `friction` in thermodynamic variable `variable`.
  pure function make_gas_containers(friction, variable) result(model)
    real(real64), intent(in) :: friction
    integer, intent(in) :: variable
    type(gas_containers) :: model
    integer :: a

    model%friction = friction
    model%thermo_variable = variable
    model%state_size = 4
    model%max_invariants = 2
    allocate (model%column_names(4))
    model%column_names(:) = [character(len=16) :: 'q', 'p', trim(tau_symbols(variable))//'_1', &
                             trim(tau_symbols(variable))//'_2']
    model%words%temperature = 'temperatures of the two gas containers'
    model%words%energy = 'total energy E = p^2/2 + U_1 + U_2'
    model%words%entropy = 'total entropy S = S_1 + S_2'
    model%words%metric_scales = 'every invariant by 1 (the model is nondimensional)'
    model%words%energy_units = '1'
    model%words%entropy_units = '1'
    model%words%temperature_units = '1'
    allocate (model%momentum_names(0))
    allocate (model%subsystems(2))
    do a = 1, 2
      associate (part => model%subsystems(a))
        part%name = 'container '//achar(iachar('0') + a)
        allocate (part%potentials, source=container_potential(variable=variable))
        part%invariant_count = 2
        part%columns = [q_column, tau_columns(a)]
        part%tau_column = tau_columns(a)
        part%metric_scale = [1.0_real64, 1.0_real64]
      end associate
    end do
  end function make_gas_containers

  !> x_a = (v_a, tau_a): v_1 = q, v_2 = 2 - q.
  pure subroutine invariants(self, z, a, x, dx_dz)
    class(gas_containers), intent(in) :: self
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: a
    real(real64), intent(out) :: x(:)
    real(real64), intent(out), optional :: dx_dz(:, :)

    if (a == 1) then
      x = [z(q_column), z(tau_columns(1))]
    else
      x = [total_volume - z(q_column), z(tau_columns(2))]
    end if
    if (present(dx_dz)) then
      dx_dz = 0.0_real64
      dx_dz(slot_v, 1) = merge(1.0_real64, -1.0_real64, a == 1)
      dx_dz(slot_tau, 2) = 1.0_real64
    end if
  end subroutine invariants

  !> The written-out field (module header), df/dz at fixed partials and df/dpartials.
  pure subroutine vector_field(self, z, partials, f, df_dz, df_dpartials)
    class(gas_containers), intent(in) :: self
    real(real64), intent(in) :: z(:), partials(:, :, :)
    real(real64), intent(out) :: f(:)
    real(real64), intent(out), optional :: df_dz(:, :), df_dpartials(:, :, :, :)
    real(real64) :: theta(2), rate(2), sign(2), df_dtheta(4, 2), friction_term(2)
    integer :: a, b

    sign = [1.0_real64, -1.0_real64]            ! dv_a/dq
    theta = partials(slot_tau, potential_u, :)/partials(slot_tau, potential_s, :)
    rate = sign*z(p_column)                       ! dv_a/dt
    f(q_column) = z(p_column)
    f(p_column) = 0.0_real64
    do a = 1, 2
      b = 3 - a
      f(p_column) = f(p_column) - sign(a)*(partials(slot_v, potential_u, a) - theta(a)*partials(slot_v, potential_s, a))
      friction_term(a) = self%friction*(1.0_real64/theta(a) - 1.0_real64/theta(b))
      f(tau_columns(a)) = -partials(slot_v, potential_s, a)*rate(a)/partials(slot_tau, potential_s, a) &
                          + friction_term(a)/partials(slot_tau, potential_u, a)
    end do
    if (present(df_dz)) then
      df_dz = 0.0_real64
      df_dz(q_column, p_column) = 1.0_real64
      do a = 1, 2
        df_dz(tau_columns(a), p_column) = -partials(slot_v, potential_s, a)*sign(a)/partials(slot_tau, potential_s, a)
      end do
    end if
    if (present(df_dpartials)) then
      df_dpartials = 0.0_real64
      df_dtheta = 0.0_real64
      do a = 1, 2
        b = 3 - a
        associate (s_v => partials(slot_v, potential_s, a), s_tau => partials(slot_tau, potential_s, a), &
                   u_tau => partials(slot_tau, potential_u, a))
          df_dpartials(p_column, slot_v, potential_u, a) = -sign(a)
          df_dpartials(p_column, slot_v, potential_s, a) = sign(a)*theta(a)
          df_dtheta(p_column, a) = sign(a)*s_v
          df_dpartials(tau_columns(a), slot_v, potential_s, a) = -rate(a)/s_tau
          df_dpartials(tau_columns(a), slot_tau, potential_s, a) = s_v*rate(a)/s_tau**2
          df_dpartials(tau_columns(a), slot_tau, potential_u, a) = -friction_term(a)/u_tau**2
          df_dtheta(tau_columns(a), a) = -self%friction/(theta(a)**2*u_tau)
          df_dtheta(tau_columns(a), b) = self%friction/(theta(b)**2*u_tau)
        end associate
      end do
      call add_temperature_chain(partials, [slot_tau, slot_tau], df_dtheta, df_dpartials)
    end if
  end subroutine vector_field

  !> p^2/2 (unit mass; no external potential).
  pure function mechanical_energy(self, z) result(value)
    class(gas_containers), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: value

    value = 0.5_real64*z(p_column)**2
  end function mechanical_energy

  pure function mechanical_energy_gradient(self, z) result(gradient)
    class(gas_containers), intent(in) :: self
    real(real64), intent(in) :: z(:)
    real(real64) :: gradient(size(z))

    gradient = 0.0_real64
    gradient(p_column) = z(p_column)
  end function mechanical_energy_gradient

  !> (p_b^2 - p_a^2)/2 = (p_b - p_a)(p_b + p_a)/2, without cancellation.
  pure function mechanical_energy_difference(self, z_a, z_b) result(delta)
    class(gas_containers), intent(in) :: self
    real(real64), intent(in) :: z_a(:), z_b(:)
    real(real64) :: delta

    delta = 0.5_real64*(z_b(p_column) - z_a(p_column))*(z_b(p_column) + z_a(p_column))
  end function mechanical_energy_difference

  !> L0: canonical in (q, p).
  pure function poisson_matrix_0(self) result(l0)
    class(gas_containers), intent(in) :: self
    real(real64) :: l0(self%state_size, self%state_size)

    l0 = 0.0_real64
    l0(q_column, p_column) = 1.0_real64
    l0(p_column, q_column) = -1.0_real64
  end function poisson_matrix_0

  !> K0 = friction [[1, -1], [-1, 1]] on (tau_1, tau_2), whatever the temperatures.
  pure function friction_matrix_0(self, partials) result(k0)
    class(gas_containers), intent(in) :: self
    real(real64), intent(in) :: partials(:, :, :)
    real(real64) :: k0(self%state_size, self%state_size)

    k0 = 0.0_real64
    k0(tau_columns, tau_columns) = self%friction*reshape([1.0_real64, -1.0_real64, -1.0_real64, 1.0_real64], [2, 2])
  end function friction_matrix_0

  !> The same model in another thermodynamic variable.
  subroutine in_variable(self, variable, other)
    class(gas_containers), intent(in) :: self
    integer, intent(in) :: variable
    class(generic_model), allocatable, intent(out) :: other

    allocate (other, source=make_gas_containers(self%friction, variable))
  end subroutine in_variable

  !> Nondimensional: every column in units of 1.
  pure subroutine column_units(self, units)
    class(gas_containers), intent(in) :: self
    character(len=*), intent(out) :: units(:)

    units = '1'
  end subroutine column_units

end module gas_model
