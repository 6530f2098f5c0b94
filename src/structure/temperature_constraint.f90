!> Constraint g2 of eq. (13) for any subsystem a of a model: Theta_a(z) = thetabar, held by a heat
!> supply lambda (a power, [W]) from the surroundings into tau_a: lambda / D_tau U_a in tau_a's
!> row of the step, so that E_{n+1} - E_n = dt lambda exactly (docs/formulation.md section 7).
!>
!> Its continuous-time form (the relaxed Runge-Kutta family; docs/integrators.md, Constraints): tau_a
!> is slaved to the mechanical invariants by Theta_a = thetabar, so the subsystem is an
!> isothermal one in a heat bath at thetabar, and the conserved energy gives way to the Lyapunov
!> function V = E - thetabar S.
module temperature_constraint
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use failures, only: failure_none
  use model_interface, only: generic_model
  use model_constraint, only: constraint
  implicit none (type, external)
  private
  public :: fixed_temperature, make_fixed_temperature

  !> Subsystem `part` held at `temperature` [K].
  type, extends(constraint) :: fixed_temperature
    integer :: part = 1
    real(real64) :: temperature = 1.0_real64
  contains
    procedure :: add_terms
    procedure :: value
    procedure :: slave_state
    procedure :: bath_temperature
  end type fixed_temperature

contains

  !> The constraint Theta_part = temperature.
  pure function make_fixed_temperature(part, temperature) result(bath)
    integer, intent(in) :: part
    real(real64), intent(in) :: temperature
    type(fixed_temperature) :: bath

    bath%name = 'temperature'
    bath%multiplier_units = 'W'
    bath%value_units = 'K'
    bath%meaning = 'g = Theta - temperature of the held subsystem; lambda: the heat supply into it'
    bath%supplies_heat = .true.
    bath%part = part
    bath%temperature = temperature
    bath%continuous_form = .true.
  end function make_fixed_temperature

  !> Heat supply lambda / D_tau U_a into tau_a, and g = Theta_a(z') - temperature with Theta_a
  !> = d_tau U_a / d_tau S_a of eq. (2) at z'.
  pure subroutine add_terms(self, model, z_new, z_mid, partials, dpartials_dz, lambda, row, residual, jacobian, stat)
    class(fixed_temperature), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z_new(:), z_mid(:), partials(:, :, :), dpartials_dz(:, :, :, :), lambda
    integer, intent(in) :: row
    real(real64), intent(inout) :: residual(:)
    real(real64), intent(inout), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    real(real64) :: u_tau, theta, dtheta_dz(model%state_size)
    integer :: n, tau

    n = model%subsystems(self%part)%invariant_count
    tau = model%subsystems(self%part)%tau_column
    u_tau = partials(n, potential_u, self%part)
    residual(tau) = residual(tau) - lambda/u_tau
    call temperature_gradient(model, self%part, z_new, theta, dtheta_dz, stat)
    if (stat /= failure_none) return
    residual(row) = theta - self%temperature
    if (present(jacobian)) then
      jacobian(tau, row) = -1.0_real64/u_tau
      jacobian(tau, 1:model%state_size) = jacobian(tau, 1:model%state_size) &
                                          + lambda/u_tau**2*dpartials_dz(n, potential_u, self%part, :)
      jacobian(row, 1:model%state_size) = dtheta_dz
    end if
  end subroutine add_terms

  !> g = Theta_a(z) - temperature, with the subsystem's own temperature function.
  pure subroutine value(self, model, z, g, stat)
    class(fixed_temperature), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: g
    integer, intent(out) :: stat
    real(real64) :: x(model%max_invariants), theta
    integer :: n

    n = model%subsystems(self%part)%invariant_count
    call model%invariants(z, self%part, x(1:n))
    call model%subsystems(self%part)%potentials%temperature(x(1:n), theta, stat)
    g = theta - self%temperature
  end subroutine value

  !> tau_a <- the value with Theta_a = thetabar at z's mechanical invariants; with `chain`, its
  !> row becomes (d tau_a/dz) chain, d tau_a/dz_j = -(dTheta_a/dz_j)/(dTheta_a/dtau_a) (j /= tau_a).
  pure subroutine slave_state(self, model, z, stat, chain)
    class(fixed_temperature), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(inout) :: z(:)
    integer, intent(out) :: stat
    real(real64), intent(inout), optional :: chain(:, :)
    real(real64) :: x(model%max_invariants), theta, dtheta_dz(size(z)), row(size(z))
    integer :: n, tau

    n = model%subsystems(self%part)%invariant_count
    tau = model%subsystems(self%part)%tau_column
    call model%invariants(z, self%part, x(1:n))
    call model%subsystems(self%part)%potentials%tau_from_temperature(x(1:n - 1), self%temperature, z(tau), stat)
    if (stat /= failure_none .or. .not. present(chain)) return
    call temperature_gradient(model, self%part, z, theta, dtheta_dz, stat)
    if (stat /= failure_none) return
    row = -dtheta_dz/dtheta_dz(tau)
    row(tau) = 0.0_real64
    chain(tau, :) = matmul(row, chain)
  end subroutine slave_state

  !> The bath's temperature thetabar.
  pure real(real64) function bath_temperature(self)
    class(fixed_temperature), intent(in) :: self

    bath_temperature = self%temperature
  end function bath_temperature

  ! Theta_a = d_tau U / d_tau S at z (eq. (2)) and its gradient in z.
  pure subroutine temperature_gradient(model, a, z, theta, dtheta_dz, stat)
    class(generic_model), intent(in) :: model
    integer, intent(in) :: a
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: theta, dtheta_dz(:)
    integer, intent(out) :: stat
    real(real64) :: x(model%max_invariants), dx(model%max_invariants, model%state_size), f(2)
    real(real64) :: g(model%max_invariants, 2), h(model%max_invariants, model%max_invariants, 2)
    real(real64) :: dtheta_dx(model%max_invariants)
    integer :: n, m, j

    dtheta_dz = 0.0_real64
    theta = 0.0_real64
    n = model%subsystems(a)%invariant_count
    m = size(model%subsystems(a)%columns)
    call model%invariants(z, a, x(1:n), dx(1:n, 1:m))
    call model%subsystems(a)%potentials%evaluate(x(1:n), f, g(1:n, :), h(1:n, 1:n, :), stat)
    if (stat /= failure_none) return
    associate (u_tau => g(n, potential_u), s_tau => g(n, potential_s))
      theta = u_tau/s_tau
      dtheta_dx(1:n) = (h(n, 1:n, potential_u)*s_tau - u_tau*h(n, 1:n, potential_s))/s_tau**2
    end associate
    do j = 1, m
      dtheta_dz(model%subsystems(a)%columns(j)) = dot_product(dtheta_dx(1:n), dx(1:n, j))
    end do
  end subroutine temperature_gradient

end module temperature_constraint
