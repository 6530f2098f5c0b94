!> The fused, condensed step of the double pendulum: the same equations as the generic step
!> residual (src/scheme/step_residual, which stays the test oracle), in one pass per point.
!>
!> Condensed: the position rows of R(z') = (z' - z)/h - f(z_mid, partials) are linear,
!>   q' = q + h m^-1 p_mid,   p_mid = (p + p')/2,
!> so q' is eliminated exactly and Newton runs on y = (p1', p2', gamma', tau1', tau2', multipliers):
!> 9 unknowns plus one per active constraint (docs/formulation.md section 7). The residual of y is the
!> generic residual's rows of p, gamma, tau and the constraints at z'(y); its Jacobian is
!>   dR/dy = dR/dz'|_(p, gamma, tau, multipliers) + dR/dq' (h/2) m^-1.
!> Layouts: every thermal rung of the ladder (double_pendulum's pendulum_layout), spatial or planar,
!> with or without gamma. Inside, the kernel always works on the full layout's numbering and
!> shapes (3 components per vector, spring 2's invariants (C, gamma, tau), rows 1..9 and the
!> multipliers after them): a planar scene's third components and a thermoelastic scene's gamma
!> stay zero, and their rows and columns are dropped where y, R and dR/dy cross the interface
!> (internal_of). A thermoelastic spring 2 has no Maxwell branch (beta_v = 0, A = 0), so its
!> potentials do not depend on gamma: its gamma partials are exactly 0 and the others are those
!> of (C, tau). So the full layout runs the code it ran before with its sizes known to the
!> compiler (the same operations in the same order, bit for bit; sizes taken from the layout at
!> run time cost it 7 % more instructions a step), and a reduced layout pays for the zeros it
!> carries, not for a second copy of the kernel; without the viscous branch the viscous rate and
!> its heating (an exponential a point) are skipped.
!> Fused: one pass computes the residual and, when asked, the Jacobian, and the rows share the
!> springs' partials and the discrete-gradient quotients between them.
!> Springs: the shared element of the paper's spring (src/model/paper_spring/description.py, the one
!> the spring chain uses), generated: spring 1 is its thermoelastic rung, spring 2 its
!> thermoviscoelastic one (a thermoelastic pendulum's with beta_v = mu_neq = 0). Gonzalez's
!> quotient takes its parts from the element's gonzalez_parts, one generated body that shares the
!> logarithms, roots and exponentials of grad f(m), f(b) - f(a) (free of cancellation) and, for the
!> Jacobian, the Hessian at m and grad f(b). The old state's invariants and temperatures are
!> computed once per step by set_old_state, not once per Newton iteration.
!> Schemes: EME (eq. (15)) with Gonzalez's discrete gradient (its parts assembled here) or the
!> partitioned one (src/scheme/discrete_gradient), and the midpoint rule (exact partials at z_mid),
!> in every thermodynamic variable; constraints g1 (fixed length) and g2 (fixed temperature).
module pendulum_step_kernel
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: potential_u, potential_s
  use failures, only: failure_none, domain_nonpositive_length, domain_overflow
  use model_parameters, only: pendulum_parameters
  use paper_spring_potential, only: paper_spring_parameters, paper_spring_potentials, make_paper_spring_potentials
  use double_pendulum, only: p_index, pendulum_layout, make_layout
  use pendulum_rungs, only: rung_parameters
  use model_constraint, only: constraint_slot
  use length_constraint, only: fixed_length
  use temperature_constraint, only: fixed_temperature
  use discrete_gradient, only: gradient_gonzalez, metric_euclidean, quotient_threshold, gonzalez_from_parts, &
                               discrete_gradient_of
  use condensed_step, only: condensed_step_problem
  use step_residual, only: step_problem, partials_discrete_gradient, partials_midpoint, root_problem_text
  implicit none (type, external)
  private
  public :: pendulum_step, build_pendulum_step, pendulum_fused_step, condensed_offset
  ! For the submodules pendulum_step_residual and pendulum_step_jacobian only: gfortran gives a
  ! module's private procedures internal linkage, which submodules, compiled apart, cannot reach.
  public :: velocity, new_momenta, new_temperature

  !> y = x(condensed_offset + 1:) in the full layout: the positions are the first 6 of the generic
  !> unknowns x (the first 2*dimension in any layout: pendulum_step%eliminated).
  integer, parameter :: condensed_offset = 6
  integer, parameter :: row_gamma = 7
  integer, parameter :: row_tau(2) = [8, 9]
  integer, parameter :: max_rows = 11          !! 9 and both multipliers
  integer, parameter :: identity_rows(max_rows) = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]

  !> What a step needs of a spring's old state.
  type :: spring_old_state
    real(real64) :: x(3) = 0.0_real64             !! invariants (C, [gamma,] tau)
    real(real64) :: theta = 0.0_real64            !! temperature
  end type spring_old_state

  !> What a spring's values pass computed at a point and its derivative pass reuses: its
  !> invariants x' (EME) or x_mid (midpoint), grad f and the Hessian at the midpoint (or x_mid), and
  !> for Gonzalez's quotient d = x' - x, its metric, f(x') - f(x) and grad f(x'). The values pass
  !> asks the element for the Jacobian's parts too: one generated body shares its logarithms and
  !> roots between them, and Newton wants a Jacobian at about half the points it evaluates (the
  !> paper scene: 2.9 Jacobians and 5.3 residuals a step), which a second call would pay again.
  type :: spring_pass
    real(real64) :: x(3) = 0.0_real64, mid(3) = 0.0_real64, d(3) = 0.0_real64, weight(3) = 0.0_real64
    real(real64) :: dwd = 0.0_real64, grad_m(3, 2) = 0.0_real64, delta_f(2) = 0.0_real64
    real(real64) :: hess_m(3, 3, 2) = 0.0_real64, grad_b(3, 2) = 0.0_real64
    logical :: small = .false.            !! Gonzalez's fallback: the midpoint derivative
  end type spring_pass

  !> A point y of the step: the new and midpoint positions and momenta, each spring's partials
  !> P(i, k) with dpartials(i, l, k, a) = dP(i, k)/dxi_l in the variables xi the partials depend
  !> on (the invariants of z' for EME, of z_mid for the midpoint rule) and dxi/dz', and the
  !> scalars of the residual's pass that its Jacobian reuses.
  type :: step_point
    real(real64) :: p_new(3, 2) = 0.0_real64, q_new(3, 2) = 0.0_real64, q_mid(3, 2) = 0.0_real64
    real(real64) :: v(3, 2) = 0.0_real64, gamma_new = 0.0_real64, tau_new(2) = 0.0_real64
    real(real64) :: partials(3, 2, 2) = 0.0_real64
    real(real64) :: dpartials(3, 3, 2, 2) = 0.0_real64
    real(real64) :: chain_c(3, 2) = 0.0_real64   !! dxi_C/dq_a'
    real(real64) :: chain_other = 1.0_real64      !! dxi_gamma/dgamma' = dxi_tau/dtau'
    type(spring_pass) :: spring(2)
    real(real64) :: theta(2) = 0.0_real64, thermal_force(2) = 0.0_real64, work(2) = 0.0_real64
    real(real64) :: work_ratio(2) = 0.0_real64, inv_u_tau(2) = 0.0_real64
    real(real64) :: inv_eta = 0.0_real64, dinv_eta = 0.0_real64, rate = 0.0_real64, heating = 0.0_real64
    real(real64) :: lambda_length = 0.0_real64, lambda_temperature = 0.0_real64
  end type step_point

  !> The condensed step of one scheme for the double pendulum.
  type, extends(condensed_step_problem) :: pendulum_step
    type(pendulum_parameters) :: params
    type(pendulum_layout) :: layout                !! where the scene's unknowns sit in z
    logical :: full = .true.                       !! the full layout: y in the internal numbering
    logical :: viscous = .true.                    !! gamma and the viscous rate
    integer :: internal_count = row_tau(2)         !! internal rows: 9 and the multipliers
    !> internal_of(j): the internal row (1..max_rows) of y's unknown j and of R's row j.
    integer :: internal_of(max_rows) = identity_rows
    type(paper_spring_potentials) :: spring(2)   !! the paper's spring: rung 2 (spring 1) and 3 (spring 2)
    integer :: partials_rule = partials_discrete_gradient
    integer :: gradient = gradient_gonzalez
    real(real64) :: scale(3, 2) = 1.0_real64       !! the discrete gradients' metric scales
    real(real64) :: fraction = 1.0_real64          !! continuation: the step of fraction*dt
    real(real64) :: q_old(3, 2) = 0.0_real64, p_old(3, 2) = 0.0_real64   !! the old state z
    real(real64) :: gamma_old = 0.0_real64, tau_old(2) = 0.0_real64
    type(spring_old_state) :: old(2)
    integer :: old_stat = failure_none                !! the old state's domain status
    real(real64) :: inverse_mass(2, 2) = 0.0_real64
    real(real64) :: force(3, 2) = 0.0_real64       !! gravity
    integer :: constraint_count = 0
    integer :: length_row = 0                      !! g1's internal row and multiplier (0: inactive)
    integer :: length_unknown = 0                  !! ... and its multiplier's place in y
    real(real64) :: length = 0.0_real64
    integer :: temperature_row = 0                 !! g2's internal row and multiplier (0: inactive)
    integer :: temperature_unknown = 0             !! ... and its multiplier's place in y
    integer :: temperature_part = 1
    real(real64) :: temperature = 0.0_real64
    type(step_point) :: kept                       !! the last residual's pass (evaluate_residual)
    real(real64) :: kept_y(11) = 0.0_real64
    real(real64) :: kept_h = 0.0_real64
    logical :: kept_valid = .false.
  contains
    procedure :: unknowns
    procedure :: evaluate
    procedure :: evaluate_residual
    procedure :: evaluate_jacobian
    procedure :: check_root
    procedure :: set_continuation
    procedure :: set_old_state
    procedure :: rounding_scales
    procedure :: step_length
    procedure :: expand
    procedure :: condense
    procedure :: scheme_temperatures
  end type pendulum_step

  interface
    !> The values pass at y (positions, momenta, each spring's partials and what the Jacobian
    !> reuses) (src/model/pendulum/pendulum_step_residual).
    module pure subroutine values_pass(self, y, point, stat)
      class(pendulum_step), intent(in) :: self
      real(real64), intent(in) :: y(:)
      type(step_point), intent(inout) :: point
      integer, intent(out) :: stat
    end subroutine values_pass
    !> The condensed residual at y in the internal rows, after its values pass
    !> (src/model/pendulum/pendulum_step_residual).
    module pure subroutine residual_pass(self, y, point, residual, stat)
      class(pendulum_step), intent(in) :: self
      real(real64), intent(in) :: y(:)
      type(step_point), intent(inout) :: point
      real(real64), intent(out) :: residual(:)
      integer, intent(out) :: stat
    end subroutine residual_pass
    !> The derivative pass and dR/dy at a point whose residual pass is done
    !> (src/model/pendulum/pendulum_step_jacobian).
    module pure subroutine jacobian_pass(self, point, jacobian, stat)
      class(pendulum_step), intent(in) :: self
      type(step_point), intent(inout) :: point
      real(real64), intent(out) :: jacobian(:, :)
      integer, intent(out) :: stat
    end subroutine jacobian_pass
  end interface

contains

  !> The kernel for `problem` if its model is the double pendulum with thermal springs (any
  !> dimension, with or without gamma) and it knows every active constraint; `built` = .false.
  !> otherwise (the generic residual then serves; the elastic rung has no thermal unknowns, and
  !> the kernel's rows are written around them).
  subroutine build_pendulum_step(problem, kernel, built)
    type(step_problem), intent(in) :: problem
    type(pendulum_step), intent(out) :: kernel
    logical, intent(out) :: built
    type(pendulum_parameters) :: params
    integer :: k, a, d, n, base

    ! The generated rungs (pendulum_rungs) are served by the generated element of the paper's spring
    ! (paper_spring_potential) with the same data and thermodynamic variable.
    call rung_parameters(problem%model, params, built)
    if (.not. built) return
    built = .false.
    if (.not. params%thermal()) return
    kernel%params = params
    kernel%layout = make_layout(params%dimension, params%viscous(), params%thermal())
    ! Spring 2 with its invariants (C, gamma, tau) in every layout: a thermoelastic one's gamma
    ! (always 0, moving by 0) weighs nothing in the metric, so its scale is 1 (the element's).
    do a = 1, 2
      n = a + 1
      kernel%spring(a) = make_paper_spring_potentials(spring_data(params, a), n, problem%model%thermo_variable)
      kernel%scale(:, a) = 1.0_real64
      if (problem%metric /= metric_euclidean) kernel%scale(1:n, a) = kernel%spring(a)%metric_scale(1:n)
    end do
    d = kernel%layout%dimension
    kernel%full = kernel%layout%is_full()
    kernel%viscous = kernel%layout%viscous
    kernel%partials_rule = problem%partials_rule
    kernel%gradient = problem%gradient
    kernel%dt = problem%dt
    kernel%eliminated = 2*d
    kernel%fraction = problem%fraction
    associate (m1 => kernel%params%mass(1), m2 => kernel%params%mass(2))
      kernel%inverse_mass = reshape([1.0_real64, -1.0_real64, -1.0_real64, (m1 + m2)/m2], [2, 2])/m1
    end associate
    kernel%force = 0.0_real64
    kernel%force(1:d, :) = kernel%layout%gravity_force(kernel%params)
    ! y = (p1 (d), p2 (d), [gamma,] tau1, tau2, multipliers) in the internal numbering's rows
    ! (p_a's components at 3(a - 1) + i, gamma 7, tau 8 and 9, the multipliers from 10).
    kernel%internal_of = 0
    kernel%internal_of(1:d) = [(k, k=1, d)]
    kernel%internal_of(d + 1:2*d) = [(3 + k, k=1, d)]
    base = 2*d
    if (kernel%viscous) then
      base = base + 1
      kernel%internal_of(base) = row_gamma
    end if
    kernel%internal_of(base + 1:base + 2) = row_tau
    base = base + 2
    kernel%constraint_count = size(problem%constraints)
    kernel%internal_count = row_tau(2) + kernel%constraint_count
    do k = 1, size(problem%constraints)
      kernel%internal_of(base + k) = row_tau(2) + k
      select type (item => problem%constraints(k)%item)
      type is (fixed_length)
        kernel%length_row = row_tau(2) + k
        kernel%length_unknown = base + k
        kernel%length = item%length
      type is (fixed_temperature)
        kernel%temperature_row = row_tau(2) + k
        kernel%temperature_unknown = base + k
        kernel%temperature_part = item%part
        kernel%temperature = item%temperature
      class default
        return
      end select
    end do
    call kernel%set_old_state(problem%z_old)
    built = .true.
  end subroutine build_pendulum_step

  !> The fused step for `problem` as the model registry offers it (build_pendulum_step's).
  subroutine pendulum_fused_step(problem, kernel, built)
    type(step_problem), intent(in) :: problem
    class(condensed_step_problem), allocatable, intent(out) :: kernel
    logical, intent(out) :: built
    type(pendulum_step) :: made

    call build_pendulum_step(problem, made, built)
    if (built) allocate (kernel, source=made)
  end subroutine pendulum_fused_step

  !> y's size: the layout's momenta, [gamma,] tau1, tau2 and the multipliers.
  pure integer function unknowns(self)
    class(pendulum_step), intent(in) :: self

    unknowns = self%layout%state_size - self%eliminated + self%constraint_count
  end function unknowns

  !> The step of s dt from the same old state.
  pure subroutine set_continuation(self, s)
    class(pendulum_step), intent(inout) :: self
    real(real64), intent(in) :: s

    self%fraction = s
  end subroutine set_continuation

  !> The step's old state z; what the step needs of it is computed here, once.
  pure subroutine set_old_state(self, z)
    class(pendulum_step), intent(inout) :: self
    real(real64), intent(in) :: z(:)
    integer :: a, n, d

    ! A planar scene's third components and a thermoelastic scene's gamma stay 0 (module header).
    d = self%layout%dimension
    self%q_old = 0.0_real64
    self%p_old = 0.0_real64
    self%q_old(1:d, 1) = z(self%layout%q(1:d, 1))
    self%q_old(1:d, 2) = z(self%layout%q(1:d, 2))
    self%p_old(1:d, 1) = z(self%layout%p(1:d, 1))
    self%p_old(1:d, 2) = z(self%layout%p(1:d, 2))
    self%gamma_old = 0.0_real64
    if (self%viscous) self%gamma_old = z(self%layout%gamma)
    self%tau_old = z(self%layout%tau)
    self%kept_valid = .false.
    self%old_stat = failure_none
    do a = 1, 2
      n = a + 1
      associate (old => self%old(a))
        old%x(1) = dot_product(self%q_old(:, a), self%q_old(:, a))
        if (a == 2) old%x(2) = self%gamma_old
        old%x(n) = self%tau_old(a)
        if (.not. (old%x(1) > 0.0_real64)) then
          self%old_stat = domain_nonpositive_length
          return
        end if
        call self%spring(a)%temperature(old%x(1:n), old%theta, self%old_stat)
        if (self%old_stat /= failure_none) return
      end associate
    end do
  end subroutine set_old_state

  !> The residual (y' - y)/h - f rounds at ~eps |z|/h, the root at ~eps |z|: z the old state.
  pure subroutine rounding_scales(self, state_scale, residual_scale)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(out) :: state_scale, residual_scale

    state_scale = sqrt(sum(self%q_old**2) + sum(self%p_old**2) + self%gamma_old**2 + sum(self%tau_old**2))
    residual_scale = state_scale/(self%fraction*self%dt)
  end subroutine rounding_scales

  !> The step's length, s dt under continuation (its Jacobian's factors serve only steps of it).
  pure real(real64) function step_length(self)
    class(pendulum_step), intent(in) :: self

    step_length = self%fraction*self%dt
  end function step_length

  !> The generic unknowns x = (q', y) of the condensed unknowns y.
  pure function expand(self, y) result(x)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: y(:)
    real(real64) :: x(size(y) + self%eliminated)
    real(real64) :: v(3, 2), q_new(3, 2)
    integer :: d

    v = velocity(self, new_momenta(self, y))
    q_new = self%q_old + (self%fraction*self%dt)*v
    if (self%full) then
      x(1:3) = q_new(:, 1)
      x(4:6) = q_new(:, 2)
    else
      d = self%layout%dimension
      x(1:d) = q_new(1:d, 1)
      x(d + 1:2*d) = q_new(1:d, 2)
    end if
    x(self%eliminated + 1:) = y
  end function expand

  !> The condensed unknowns y whose q'(y) is the positions of x: the momenta p' = 2 m (q' - q)/h - p
  !> (the position rows solved for p'), the rest of y from x.
  pure function condense(self, x) result(y)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64) :: y(size(x) - self%eliminated)
    real(real64) :: q_new(3, 2), v(3, 2), p_mid(3, 2), p_new(3, 2), m1, m2
    integer :: d

    d = self%layout%dimension
    if (self%full) then
      q_new(:, 1) = x(1:3)
      q_new(:, 2) = x(4:6)
    else
      q_new = 0.0_real64
      q_new(1:d, 1) = x(1:d)
      q_new(1:d, 2) = x(d + 1:2*d)
    end if
    m1 = self%params%mass(1)
    m2 = self%params%mass(2)
    v = (q_new - self%q_old)/(self%fraction*self%dt)
    ! m = [[m1 + m2, m2], [m2, m2]] (q2 relative to m1), the inverse of m^-1.
    p_mid(:, 1) = (m1 + m2)*v(:, 1) + m2*v(:, 2)
    p_mid(:, 2) = m2*(v(:, 1) + v(:, 2))
    p_new = 2.0_real64*p_mid - self%p_old
    y = x(self%eliminated + 1:)
    if (self%full) then
      y(1:3) = p_new(:, 1)
      y(4:6) = p_new(:, 2)
    else
      y(1:d) = p_new(1:d, 1)
      y(d + 1:2*d) = p_new(1:d, 2)
    end if
  end function condense

  ! The new momenta p_a' of y as columns, a planar scene's third components 0.
  pure function new_momenta(self, y) result(p_new)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: y(:)
    real(real64) :: p_new(3, 2)
    integer :: d

    if (self%full) then
      p_new(:, 1) = y(1:3)
      p_new(:, 2) = y(4:6)
    else
      d = self%layout%dimension
      p_new = 0.0_real64
      p_new(1:d, 1) = y(1:d)
      p_new(1:d, 2) = y(d + 1:2*d)
    end if
  end function new_momenta

  ! v = m^-1 p_mid for the new momenta p_new.
  pure function velocity(self, p_new) result(v)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: p_new(3, 2)
    real(real64) :: v(3, 2), p_mid(3, 2)

    p_mid(:, 1) = 0.5_real64*(self%p_old(:, 1) + p_new(:, 1))
    p_mid(:, 2) = 0.5_real64*(self%p_old(:, 2) + p_new(:, 2))
    v(:, 1) = self%inverse_mass(1, 1)*p_mid(:, 1) + self%inverse_mass(1, 2)*p_mid(:, 2)
    v(:, 2) = self%inverse_mass(2, 1)*p_mid(:, 1) + self%inverse_mass(2, 2)*p_mid(:, 2)
  end function velocity

  ! The element's data of spring a: spring 1 has no Maxwell element, nor has a thermoelastic
  ! scene's spring 2 (beta_v = mu_neq = 0: its potentials do not depend on gamma).
  pure function spring_data(params, a) result(data)
    type(pendulum_parameters), intent(in) :: params
    integer, intent(in) :: a
    type(paper_spring_parameters) :: data

    data%natural_length = params%natural_length(a)
    data%mu_eq_const = params%mu_eq_const(a)
    data%mu_eq_slope = params%mu_eq_slope(a)
    data%heat_capacity = params%heat_capacity(a)
    data%viscosity_const = params%viscosity_const
    data%viscosity_activation = params%viscosity_activation
    data%theta_ref = params%theta_ref
    data%beta = params%beta
    data%mu_neq_const = 0.0_real64
    data%mu_neq_slope = 0.0_real64
    data%beta_v = 0.0_real64
    if (a == 2 .and. params%viscous()) then
      data%mu_neq_const = params%mu_neq_const
      data%mu_neq_slope = params%mu_neq_slope
      data%beta_v = params%beta_v
    end if
  end function spring_data

  !> The temperature of spring a at the new state and, optionally, its gradient in the spring's
  !> invariants: the element's closed form, and eq. (2)'s Theta = U_tau/S_tau differentiated,
  !> dTheta/dx_l = (d2U/dtau dx_l - Theta d2S/dtau dx_l)/S_tau.
  pure subroutine new_temperature(self, a, point, theta, dtheta_dx, stat)
    class(pendulum_step), intent(in) :: self
    integer, intent(in) :: a
    type(step_point), intent(in) :: point
    real(real64), intent(out) :: theta
    real(real64), intent(out), optional :: dtheta_dx(:)
    integer, intent(out) :: stat
    real(real64) :: x(3), f(2), grad(3, 2), hess(3, 3, 2)
    integer :: n

    n = a + 1
    theta = 0.0_real64
    x(1) = dot_product(point%q_new(:, a), point%q_new(:, a))
    if (.not. (x(1) > 0.0_real64)) then
      stat = domain_nonpositive_length
      return
    end if
    if (a == 2) x(2) = point%gamma_new
    x(n) = point%tau_new(a)
    call self%spring(a)%temperature(x(1:n), theta, stat)
    if (stat /= failure_none .or. .not. present(dtheta_dx)) return
    call self%spring(a)%evaluate(x(1:n), f, grad(1:n, :), hess(1:n, 1:n, :), stat)
    if (stat /= failure_none) return
    dtheta_dx = (hess(n, 1:n, potential_u) - theta*hess(n, 1:n, potential_s))/grad(n, potential_s)
  end subroutine new_temperature

  !> R(y) and optionally dR/dy (module header) in one pass. stat /= 0: y (or a point the scheme
  !> needs) is outside the model's domain; R is then undefined.
  pure subroutine evaluate(self, x, residual, jacobian, stat)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    real(real64), intent(out), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    type(step_point) :: point

    call layout_residual(self, x, point, residual, stat)
    if (stat /= failure_none .or. .not. present(jacobian)) return
    call jacobian_pass(self, point, jacobian, stat)
  end subroutine evaluate

  ! The residual pass at y with R in y's rows: the internal rows themselves in the full layout, else
  ! the layout's rows picked from them (a planar scene's third components and gamma dropped: the
  ! rows dropped are 0, so the overflow check of the internal rows is the layout's).
  pure subroutine layout_residual(self, y, point, residual, stat)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: y(:)
    type(step_point), intent(inout) :: point
    real(real64), intent(out) :: residual(:)
    integer, intent(out) :: stat
    real(real64) :: internal(max_rows)

    if (self%full) then
      call residual_pass(self, y, point, residual, stat)
    else
      internal = 0.0_real64
      call residual_pass(self, y, point, internal(1:self%internal_count), stat)
      residual = internal(self%internal_of(1:size(residual)))
    end if
  end subroutine layout_residual

  !> R(y), keeping the pass for a Jacobian at the same y (evaluate_jacobian).
  subroutine evaluate_residual(self, x, residual, stat)
    class(pendulum_step), intent(inout) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    integer, intent(out) :: stat

    call layout_residual(self, x, self%kept, residual, stat)
    self%kept_valid = stat == failure_none
    self%kept_y(1:size(x)) = x
    self%kept_h = self%fraction*self%dt
  end subroutine evaluate_residual

  !> dR/dy at y, from the kept residual pass if it was at this y (and step), else in one pass.
  subroutine evaluate_jacobian(self, x, jacobian, stat)
    class(pendulum_step), intent(inout) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: jacobian(:, :)
    integer, intent(out) :: stat
    real(real64) :: residual(size(x))

    if (.not. kept_for(self, x)) then
      call layout_residual(self, x, self%kept, residual, stat)
      self%kept_valid = stat == failure_none
      self%kept_y(1:size(x)) = x
      self%kept_h = self%fraction*self%dt
      if (stat /= failure_none) return
    end if
    call jacobian_pass(self, self%kept, jacobian, stat)
  end subroutine evaluate_jacobian

  !> The temperatures the scheme's K0 uses at y: discrete (EME) or midpoint temperatures.
  pure subroutine scheme_temperatures(self, y, theta, stat)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: y(:)
    real(real64), intent(out) :: theta(:)
    integer, intent(out) :: stat

    ! The kept pass if it was at this y of this step (the root a solve ended on), read in place: a
    ! copy of a point, or a new one's default initialization, costs more than the rest of this.
    theta = 0.0_real64
    if (kept_for(self, y)) then
      theta(1:2) = point_temperatures(self%kept)
      stat = failure_none
    else
      call new_point_temperatures(self, y, theta, stat)
    end if
  end subroutine scheme_temperatures

  ! scheme_temperatures at a point y that was not kept.
  pure subroutine new_point_temperatures(self, y, theta, stat)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: y(:)
    real(real64), intent(inout) :: theta(:)
    integer, intent(out) :: stat
    type(step_point) :: point

    call values_pass(self, y, point, stat)
    if (stat == failure_none) theta(1:2) = point_temperatures(point)
  end subroutine new_point_temperatures

  ! The scheme temperatures U_tau/S_tau of a point's partials.
  pure function point_temperatures(point) result(theta)
    type(step_point), intent(in) :: point
    real(real64) :: theta(2)
    integer :: a

    do a = 1, 2
      theta(a) = point%partials(a + 1, potential_u, a)/point%partials(a + 1, potential_s, a)
    end do
  end function point_temperatures

  ! Whether the kept pass is at y (bit for bit) of this very step.
  pure logical function kept_for(self, y)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: y(:)

    kept_for = self%kept_valid .and. abs(self%kept_h - self%fraction*self%dt) <= 0.0_real64
    if (kept_for) kept_for = all(abs(self%kept_y(1:size(y)) - y) <= 0.0_real64)
  end function kept_for

  !> Why y is not a physical root ('' if it is): as the generic step's check_root.
  pure subroutine check_root(self, x, problem_text)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: x(:)
    character(len=:), allocatable, intent(out) :: problem_text

    ! The values pass at x: the kept one, read in place, if it was at this x of this step (the root
    ! a solve ended on), else a new one (scheme_temperatures' note).
    if (kept_for(self, x)) then
      call root_text(self, self%kept, failure_none, problem_text)
    else
      call new_point_root_text(self, x, problem_text)
    end if
  end subroutine check_root

  ! check_root at a point x that was not kept.
  pure subroutine new_point_root_text(self, x, problem_text)
    class(pendulum_step), intent(in) :: self
    real(real64), intent(in) :: x(:)
    character(len=:), allocatable, intent(out) :: problem_text
    type(step_point) :: point
    integer :: scheme_stat

    call values_pass(self, x, point, scheme_stat)
    call root_text(self, point, scheme_stat, problem_text)
  end subroutine new_point_root_text

  ! check_root's text from the values pass `point` at the root and its status.
  pure subroutine root_text(self, point, scheme_stat, problem_text)
    class(pendulum_step), intent(in) :: self
    type(step_point), intent(in) :: point
    integer, intent(in) :: scheme_stat
    character(len=:), allocatable, intent(out) :: problem_text
    real(real64) :: theta_new(2), theta_scheme(2)
    integer :: stat, a, which

    theta_new = 0.0_real64
    theta_scheme = 0.0_real64
    which = 1
    do a = 1, 2
      call new_temperature(self, a, point, theta_new(a), stat=stat)
      if (stat /= failure_none) then
        which = a
        exit
      end if
    end do
    if (scheme_stat == failure_none) theta_scheme = [(point%partials(a + 1, potential_u, a) &
                                                   /point%partials(a + 1, potential_s, a), a=1, 2)]
    call root_problem_text(self%partials_rule, stat, which, theta_new, 'spring '//achar(iachar('0') + which), &
                           scheme_stat, theta_scheme, problem_text)
  end subroutine root_text

end module pendulum_step_kernel
