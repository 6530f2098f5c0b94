!> Residual and analytic Jacobian of one time step, for both schemes:
!>   R(z') = (z' - z)/dt - f(z_mid, partials),   z_mid = (z + z')/2,
!> where f is the GENERIC vector field (generic_vector_field) and `partials` are
!>  - EME (eq. (15), FORMULATION section 5): discrete gradients of U_a and S_a between the
!>    invariants of z and z', per spring; grad_qa of a spring is 2 q_mid D_C by the chain rule,
!>    and K0 is taken at the discrete temperatures Theta_a = D_tau U_a / D_tau S_a;
!>  - midpoint (FORMULATION section 6): exact partials at z_mid.
!> Kinetic energy and gravity are quadratic and linear, so their midpoint gradients are exact
!> discrete gradients; f evaluates them at z_mid in both schemes.
!> Active constraints (FORMULATION section 7) append their multipliers to the unknowns and
!> their equations g(z') = 0 to the residual (`add_constraints`).
module step_residual
  use, intrinsic :: iso_fortran_env, only: real64
  use thermo_variable, only: spring_potential, potential_u, potential_s, domain_ok, domain_nonpositive_temperature, &
                             domain_nonpositive_length, domain_overflow
  use pendulum_model, only: pendulum
  use double_pendulum, only: state_size, q_index, p_index, tau_index, var_tau, &
                             spring_invariants, invariant_slots, chain_to_state
  use discrete_gradient, only: gradient_gonzalez, metric_nondimensional, metric_euclidean, &
                               discrete_gradient_of
  use generic_vector_field, only: vector_field, add_partials_chain
  implicit none (type, external)
  private
  public :: step_problem, scheme_eme, scheme_midpoint, scheme_names

  integer, parameter :: scheme_eme = 1
  integer, parameter :: scheme_midpoint = 2
  character(len=*), parameter :: scheme_names(2) = [character(len=8) :: 'eme', 'midpoint']

  !> One step z -> z' of a scheme: the model, the scheme's choices, dt and the old state.
  type :: step_problem
    type(pendulum) :: model
    integer :: scheme = scheme_eme
    integer :: gradient = gradient_gonzalez
    integer :: metric = metric_nondimensional
    real(real64) :: dt = 0.0_real64
    real(real64) :: z_old(state_size) = 0.0_real64
    logical :: fix_length = .false.        !! constraint g1 = (q1.q1 - length^2)/2, eq. (13)
    real(real64) :: length = 1.0_real64    !! lbar_1 [m]
    logical :: fix_temperature = .false.   !! constraint g2 = Theta_1 - temperature, eq. (13)
    real(real64) :: temperature = 1.0_real64   !! thetabar_1 [K]
  contains
    procedure :: unknowns
    procedure :: constraint_count
    procedure :: length_multiplier
    procedure :: temperature_multiplier
    procedure :: evaluate
    procedure :: scheme_partials
    procedure :: scheme_temperatures
    procedure :: check_root
  end type step_problem

contains

  !> Number of unknowns of the step's nonlinear system: the state and one multiplier per
  !> active constraint (the system grows only with what the scene switches on).
  pure function unknowns(self) result(n)
    class(step_problem), intent(in) :: self
    integer :: n

    n = state_size + self%constraint_count()
  end function unknowns

  !> Number of active constraints.
  pure function constraint_count(self) result(k)
    class(step_problem), intent(in) :: self
    integer :: k

    k = count([self%fix_length, self%fix_temperature])
  end function constraint_count

  !> Position of lambda_1 (length constraint) in the unknowns, 0 if inactive.
  pure function length_multiplier(self) result(k)
    class(step_problem), intent(in) :: self
    integer :: k

    k = merge(state_size + 1, 0, self%fix_length)
  end function length_multiplier

  !> Position of lambda_2 (temperature constraint) in the unknowns, 0 if inactive.
  pure function temperature_multiplier(self) result(k)
    class(step_problem), intent(in) :: self
    integer :: k

    k = merge(state_size + self%constraint_count(), 0, self%fix_temperature)
  end function temperature_multiplier

  !> R(x') and optionally dR/dx' for x' = (z', multipliers of the active constraints).
  !> stat /= 0: z' (or a point the scheme needs) is outside the model's domain, e.g. a
  !> non-positive temperature; R is then undefined.
  pure subroutine evaluate(self, x_new, residual, jacobian, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: x_new(:)
    real(real64), intent(out) :: residual(:)
    real(real64), intent(out), optional :: jacobian(:, :)
    integer, intent(out) :: stat

    real(real64) :: z_mid(state_size), partials(3, 2, 2), dpartials_dz(3, 2, 2, state_size)
    real(real64) :: f(state_size), df_dz(state_size, state_size), df_dpartials(state_size, 3, 2, 2)
    integer :: i

    z_mid = 0.5_real64*(self%z_old + x_new(1:state_size))
    if (present(jacobian)) then
      call self%scheme_partials(x_new, partials, dpartials_dz, stat)
      if (stat /= domain_ok) return
      call vector_field(self%model%params, z_mid, partials, f, df_dz, df_dpartials)
      jacobian = 0.0_real64
      jacobian(1:state_size, 1:state_size) = -0.5_real64*df_dz
      call add_partials_chain(df_dpartials, dpartials_dz, -1.0_real64, jacobian)
      do i = 1, state_size
        jacobian(i, i) = jacobian(i, i) + 1.0_real64/self%dt
      end do
    else
      call self%scheme_partials(x_new, partials, stat=stat)
      if (stat /= domain_ok) return
      call vector_field(self%model%params, z_mid, partials, f)
    end if
    residual(1:state_size) = (x_new(1:state_size) - self%z_old)/self%dt - f
    if (self%fix_length .or. self%fix_temperature) then
      call add_constraints(self, x_new, z_mid, partials, dpartials_dz, residual, jacobian, stat)
      if (stat /= domain_ok) return
    end if
    if (.not. all(abs(residual) <= huge(1.0_real64))) stat = domain_overflow
  end subroutine evaluate

  ! The constraint terms N lambda of eq. (15) and the equations g(z') = 0 (FORMULATION section 7):
  !  - g1 = (q1.q1 - length^2)/2: force -lambda_1 q1_mid on p1 (q1_mid is g1's exact discrete
  !    gradient, so the constraint does no work and is parallel to q1_mid: E and J_z stay conserved);
  !  - g2 = Theta_1(z') - temperature: heat supply lambda_2 / D_tau U_1 into tau_1, so that
  !    E_{n+1} - E_n = dt lambda_2.
  pure subroutine add_constraints(self, x_new, z_mid, partials, dpartials_dz, residual, jacobian, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: x_new(:), z_mid(state_size), partials(3, 2, 2), dpartials_dz(3, 2, 2, state_size)
    real(real64), intent(inout) :: residual(:)
    real(real64), intent(inout), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    real(real64) :: lambda, u_tau, theta, dtheta_dz(state_size)
    integer :: k, i

    stat = domain_ok
    if (self%fix_length) then
      k = self%length_multiplier()
      lambda = x_new(k)
      associate (q1 => x_new(q_index(:, 1)))
        residual(p_index(:, 1)) = residual(p_index(:, 1)) + lambda*z_mid(q_index(:, 1))
        residual(k) = 0.5_real64*(dot_product(q1, q1) - self%length**2)
        if (present(jacobian)) then
          jacobian(p_index(:, 1), k) = z_mid(q_index(:, 1))
          do i = 1, 3
            jacobian(p_index(i, 1), q_index(i, 1)) = jacobian(p_index(i, 1), q_index(i, 1)) + 0.5_real64*lambda
          end do
          jacobian(k, q_index(:, 1)) = q1
        end if
      end associate
    end if
    if (self%fix_temperature) then
      k = self%temperature_multiplier()
      lambda = x_new(k)
      u_tau = partials(var_tau, potential_u, 1)
      residual(tau_index(1)) = residual(tau_index(1)) - lambda/u_tau
      call spring_temperature_gradient(self%model%spring(1), x_new, theta, dtheta_dz, stat)
      if (stat /= domain_ok) return
      residual(k) = theta - self%temperature
      if (present(jacobian)) then
        jacobian(tau_index(1), k) = -1.0_real64/u_tau
        jacobian(tau_index(1), 1:state_size) = jacobian(tau_index(1), 1:state_size) &
                                               + lambda/u_tau**2*dpartials_dz(var_tau, potential_u, 1, :)
        jacobian(k, 1:state_size) = dtheta_dz
      end if
    end if
  end subroutine add_constraints

  ! Spring 1's temperature Theta = dU/dtau / dS/dtau (eq. (2)) at z and its gradient in z.
  pure subroutine spring_temperature_gradient(spring, z, theta, dtheta_dz, stat)
    type(spring_potential), intent(in) :: spring
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: theta, dtheta_dz(state_size)
    integer, intent(out) :: stat
    real(real64) :: f(2), g(2, 2), h(2, 2, 2), dtheta_dx(2)

    dtheta_dz = 0.0_real64
    theta = 0.0_real64
    call spring%evaluate(spring_invariants(z, 1), f, g, h, stat)
    if (stat /= domain_ok) return
    associate (u_tau => g(2, potential_u), s_tau => g(2, potential_s))
      theta = u_tau/s_tau
      dtheta_dx = (h(2, :, potential_u)*s_tau - u_tau*h(2, :, potential_s))/s_tau**2
    end associate
    dtheta_dz(q_index(:, 1)) = dtheta_dx(1)*2.0_real64*z(q_index(:, 1))
    dtheta_dz(tau_index(1)) = dtheta_dx(2)
  end subroutine spring_temperature_gradient

  !> The scheme's partials of U_a, S_a (discrete gradients or midpoint derivatives) for the
  !> step to z', and optionally their derivatives with respect to z'.
  pure subroutine scheme_partials(self, z_new, partials, dpartials_dz, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: z_new(:)
    real(real64), intent(out) :: partials(3, 2, 2)
    real(real64), intent(out), optional :: dpartials_dz(3, 2, 2, state_size)
    integer, intent(out) :: stat

    real(real64) :: g(3, 2), dg(3, 3, 2), scale(3)
    integer :: a, n

    if (self%scheme /= scheme_eme) then
      ! Midpoint: exact partials at z_mid = (z + z')/2, so d/dz' is half of d/dz_mid.
      call self%model%exact_partials(0.5_real64*(self%z_old + z_new(1:state_size)), partials, dpartials_dz, stat)
      if (present(dpartials_dz)) dpartials_dz = 0.5_real64*dpartials_dz
      return
    end if
    partials = 0.0_real64
    if (present(dpartials_dz)) dpartials_dz = 0.0_real64
    do a = 1, 2
      n = a + 1
      if (self%metric == metric_euclidean) then
        scale = 1.0_real64
      else
        scale(1:n) = self%model%spring(a)%metric_scale()
      end if
      associate (x_old => spring_invariants(self%z_old, a), x_new => spring_invariants(z_new, a), &
                 slots => invariant_slots(a))
        if (present(dpartials_dz)) then
          call discrete_gradient_of(self%gradient, self%model%spring(a), x_old, x_new, scale(1:n), g(1:n, :), &
                                    dg(1:n, 1:n, :), stat=stat)
        else
          call discrete_gradient_of(self%gradient, self%model%spring(a), x_old, x_new, scale(1:n), g(1:n, :), &
                                    stat=stat)
        end if
        if (stat /= domain_ok) return
        partials(slots, :, a) = g(1:n, :)
        ! Chain rule through x' = (q'.q', [gamma'], tau').
        if (present(dpartials_dz)) call chain_to_state(dg(1:n, 1:n, :), z_new, a, dpartials_dz)
      end associate
    end do
  end subroutine scheme_partials

  !> The temperatures the scheme's K0 uses for the step to z': the discrete temperatures
  !> D_tau U_a / D_tau S_a for EME, the midpoint temperatures for the midpoint rule.
  pure subroutine scheme_temperatures(self, z_new, theta, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: z_new(:)
    real(real64), intent(out) :: theta(2)
    integer, intent(out) :: stat
    real(real64) :: partials(3, 2, 2)

    theta = 0.0_real64
    call self%scheme_partials(z_new, partials, stat=stat)
    if (stat /= domain_ok) return
    theta = partials(var_tau, potential_u, :)/partials(var_tau, potential_s, :)
  end subroutine scheme_temperatures

  !> Why x' is not a physical root of the step ('' if it is): the temperatures at z' and the
  !> temperatures the scheme's K0 used must be positive (FORMULATION section 5).
  pure subroutine check_root(self, x_new, problem_text)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: x_new(:)
    character(len=:), allocatable, intent(out) :: problem_text
    real(real64) :: theta(2)
    integer :: stat, a
    character(len=120) :: text

    problem_text = ''
    do a = 1, 2
      call self%model%spring(a)%temperature(spring_invariants(x_new, a), theta(a), stat)
      if (stat == domain_nonpositive_temperature) then
        write (text, '(a, i0, a, es10.3, a)') 'non-positive temperature at the new state (theta_', a, ' = ', &
          theta(a), ' K)'
      else if (stat /= domain_ok) then
        write (text, '(a, i0, a)') 'spring ', a, ' at the new state is outside the model''s domain ('// &
          domain_text(stat)//')'
      end if
      if (stat /= domain_ok) then
        problem_text = trim(text)
        return
      end if
    end do
    call self%scheme_temperatures(x_new, theta, stat)
    if (stat /= domain_ok .and. stat /= domain_nonpositive_temperature) then
      problem_text = 'the scheme''s temperatures are undefined between the states ('//domain_text(stat)//')'
    else if (stat /= domain_ok .or. .not. all(theta > 0.0_real64 .and. theta < huge(1.0_real64))) then
      if (self%scheme == scheme_eme) then
        write (text, '(a, 2(1x, es10.3), a)') 'non-positive discrete temperature (D_tau U/D_tau S =', theta, ' K)'
      else
        write (text, '(a, 2(1x, es10.3), a)') 'non-positive midpoint temperature (theta =', theta, ' K)'
      end if
      problem_text = trim(text)
    end if
  end subroutine check_root

  ! What a domain status means, for messages.
  pure function domain_text(stat) result(text)
    integer, intent(in) :: stat
    character(len=:), allocatable :: text

    select case (stat)
    case (domain_nonpositive_length)
      text = 'a non-positive spring length'
    case (domain_nonpositive_temperature)
      text = 'a non-positive temperature'
    case (domain_overflow)
      text = 'an overflow'
    case default
      text = 'inside the domain'
    end select
  end function domain_text

end module step_residual
