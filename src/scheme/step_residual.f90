!> Residual and analytic Jacobian of one time step of any model (src/structure/model_interface):
!>   R(z') = (z' - z)/dt - f(z_mid, partials),   z_mid = (z + z')/2,
!> where f is the model's GENERIC vector field and `partials` are
!>  - discrete gradients (EME, eq. (15), docs/formulation.md section 5): of U_a and S_a between the
!>    invariants of z and z', per subsystem; K0 then sees the discrete temperatures
!>    Theta_a = D_tau U_a / D_tau S_a;
!>  - midpoint partials (docs/formulation.md section 6): the exact partials at z_mid.
!> Active constraints (docs/formulation.md section 7) append their multipliers to the unknowns and their
!> equations g(z') = 0 to the residual. For the solver it is a nonlinear_system whose
!> continuation parameter s solves the step of s dt from the same old state.
module step_residual
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none, domain_nonpositive_temperature, domain_overflow, failure_code_name
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use discrete_gradient, only: gradient_gonzalez, metric_nondimensional, metric_euclidean, discrete_gradient_of
  use nonlinear_problem, only: nonlinear_system
  implicit none (type, external)
  private
  public :: step_problem, partials_discrete_gradient, partials_midpoint, root_problem_text

  integer, parameter :: partials_discrete_gradient = 1  !! EME
  integer, parameter :: partials_midpoint = 2           !! the implicit midpoint rule

  !> One step z -> z' of a scheme: the model, the scheme's choices, dt and the old state.
  type, extends(nonlinear_system) :: step_problem
    class(generic_model), allocatable :: model
    type(constraint_slot), allocatable :: constraints(:)   !! the active ones, in the unknowns' order
    integer :: partials_rule = partials_discrete_gradient
    integer :: gradient = gradient_gonzalez
    integer :: metric = metric_nondimensional
    real(real64) :: dt = 0.0_real64
    real(real64) :: fraction = 1.0_real64       !! continuation: the step of fraction*dt
    real(real64), allocatable :: z_old(:)
  contains
    procedure :: unknowns
    procedure :: evaluate
    procedure :: check_root
    procedure :: set_continuation
    procedure :: rounding_scales
    procedure :: step_length
    procedure :: scheme_partials
    procedure :: scheme_temperatures
  end type step_problem

contains

  !> The state and one multiplier per active constraint (the system grows only with what the
  !> scene switches on).
  pure integer function unknowns(self)
    class(step_problem), intent(in) :: self

    unknowns = self%model%state_size + size(self%constraints)
  end function unknowns

  !> The step of s dt from the same old state.
  pure subroutine set_continuation(self, s)
    class(step_problem), intent(inout) :: self
    real(real64), intent(in) :: s

    self%fraction = s
  end subroutine set_continuation

  !> The residual (z' - z)/h - f rounds at ~eps |z|/h, the root at ~eps |z|: z the old state.
  pure subroutine rounding_scales(self, state_scale, residual_scale)
    class(step_problem), intent(in) :: self
    real(real64), intent(out) :: state_scale, residual_scale

    state_scale = norm2(self%z_old)
    residual_scale = state_scale/(self%fraction*self%dt)
  end subroutine rounding_scales

  !> The step's length, s dt under continuation (its Jacobian's factors serve only steps of it).
  pure real(real64) function step_length(self)
    class(step_problem), intent(in) :: self

    step_length = self%fraction*self%dt
  end function step_length

  !> R(x') and optionally dR/dx' for x' = (z', multipliers of the active constraints).
  !> stat /= 0: z' (or a point the scheme needs) is outside the model's domain, e.g. a
  !> non-positive temperature; R is then undefined.
  pure subroutine evaluate(self, x, residual, jacobian, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    real(real64), intent(out), optional :: jacobian(:, :)
    integer, intent(out) :: stat
    integer :: n, k, i
    real(real64) :: step

    n = self%model%state_size
    step = self%fraction*self%dt
    block
      ! The arrays of size n^2 and more live on the heap: on the stack (-fstack-arrays) a chain of
      ! about 500 unknowns already overflowed its 8 MB.
      real(real64) :: z_mid(n), f(n)
      real(real64) :: partials(self%model%max_invariants, 2, self%model%subsystem_count())
      real(real64), allocatable :: df_dz(:, :), dpartials_dz(:, :, :, :), df_dpartials(:, :, :, :)

      allocate (df_dz(n, n), dpartials_dz(self%model%max_invariants, 2, self%model%subsystem_count(), n), &
                df_dpartials(n, self%model%max_invariants, 2, self%model%subsystem_count()))
      z_mid = 0.5_real64*(self%z_old + x(1:n))
      if (present(jacobian)) then
        call self%scheme_partials(x, partials, dpartials_dz, stat)
        if (stat /= failure_none) return
        call self%model%vector_field(z_mid, partials, f, df_dz, df_dpartials)
        jacobian = 0.0_real64
        jacobian(1:n, 1:n) = -0.5_real64*df_dz
        call self%model%add_partials_chain(df_dpartials, dpartials_dz, -1.0_real64, jacobian)
        do i = 1, n
          jacobian(i, i) = jacobian(i, i) + 1.0_real64/step
        end do
      else
        call self%scheme_partials(x, partials, stat=stat)
        if (stat /= failure_none) return
        call self%model%vector_field(z_mid, partials, f)
      end if
      residual(1:n) = (x(1:n) - self%z_old)/step - f
      do k = 1, size(self%constraints)
        call self%constraints(k)%item%add_terms(self%model, x(1:n), z_mid, partials, dpartials_dz, x(n + k), n + k, &
                                                residual, jacobian, stat)
        if (stat /= failure_none) return
      end do
    end block
    if (.not. all(abs(residual) <= huge(1.0_real64))) stat = domain_overflow
  end subroutine evaluate

  !> The scheme's partials of U_a, S_a (discrete gradients or midpoint derivatives) for the
  !> step to z', and optionally their derivatives with respect to z'.
  pure subroutine scheme_partials(self, z_new, partials, dpartials_dz, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: z_new(:)
    real(real64), intent(out) :: partials(:, :, :)
    real(real64), intent(out), optional :: dpartials_dz(:, :, :, :)
    integer, intent(out) :: stat
    integer :: a, n, m, mx
    real(real64) :: g(self%model%max_invariants, 2), dg(self%model%max_invariants, self%model%max_invariants, 2)
    real(real64) :: x_old(self%model%max_invariants), x_new(self%model%max_invariants), scale(self%model%max_invariants)
    real(real64) :: dx(self%model%max_invariants, self%model%state_size)

    mx = self%model%state_size
    if (self%partials_rule == partials_midpoint) then
      ! Exact partials at z_mid = (z + z')/2, so d/dz' is half of d/dz_mid.
      call self%model%exact_partials(0.5_real64*(self%z_old + z_new(1:mx)), partials, dpartials_dz, stat)
      if (present(dpartials_dz)) dpartials_dz = 0.5_real64*dpartials_dz
      return
    end if
    partials = 0.0_real64
    stat = failure_none
    if (present(dpartials_dz)) dpartials_dz = 0.0_real64
    do a = 1, self%model%subsystem_count()
      associate (part => self%model%subsystems(a))
        n = part%invariant_count
        m = size(part%columns)
        if (self%metric == metric_euclidean) then
          scale(1:n) = 1.0_real64
        else
          scale(1:n) = part%metric_scale
        end if
        call self%model%invariants(self%z_old, a, x_old(1:n))
        if (present(dpartials_dz)) then
          call self%model%invariants(z_new, a, x_new(1:n), dx(1:n, 1:m))
          call discrete_gradient_of(self%gradient, part%potentials, x_old(1:n), x_new(1:n), scale(1:n), g(1:n, :), &
                                    dg(1:n, 1:n, :), stat=stat)
        else
          call self%model%invariants(z_new, a, x_new(1:n))
          call discrete_gradient_of(self%gradient, part%potentials, x_old(1:n), x_new(1:n), scale(1:n), g(1:n, :), &
                                    stat=stat)
        end if
        if (stat /= failure_none) return
        partials(1:n, :, a) = g(1:n, :)
        ! Chain rule through x' = x(z'), e.g. (q'.q', [gamma'], tau').
        if (present(dpartials_dz)) call self%model%chain_to_state(a, dg(1:n, 1:n, :), dx(1:n, 1:m), dpartials_dz)
      end associate
    end do
  end subroutine scheme_partials

  !> The temperatures the scheme's K0 uses for the step to z': the discrete temperatures
  !> D_tau U_a / D_tau S_a for EME, the midpoint temperatures for the midpoint rule.
  pure subroutine scheme_temperatures(self, z_new, theta, stat)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: z_new(:)
    real(real64), intent(out) :: theta(:)
    integer, intent(out) :: stat
    real(real64) :: partials(self%model%max_invariants, 2, self%model%subsystem_count())

    theta = 0.0_real64
    call self%scheme_partials(z_new, partials, stat=stat)
    if (stat /= failure_none) return
    theta = self%model%partials_temperatures(partials)
  end subroutine scheme_temperatures

  !> Why x' is not a physical root of the step ('' if it is): the temperatures at z' and the
  !> temperatures the scheme's K0 used must be positive (docs/formulation.md section 5).
  pure subroutine check_root(self, x, problem_text)
    class(step_problem), intent(in) :: self
    real(real64), intent(in) :: x(:)
    character(len=:), allocatable, intent(out) :: problem_text
    real(real64) :: theta(self%model%temperature_count()), theta_scheme(self%model%temperature_count())
    integer :: stat, scheme_stat, which

    call self%model%temperatures(x(1:self%model%state_size), theta, stat, which)
    scheme_stat = failure_none
    theta_scheme = 0.0_real64
    if (stat == failure_none) call self%scheme_temperatures(x, theta_scheme, scheme_stat)
    which = max(which, 1)
    call root_problem_text(self%partials_rule, stat, which, theta, self%model%subsystems(which)%name, &
                           scheme_stat, theta_scheme, problem_text)
  end subroutine check_root

  !> The reason a root is not physical ('' if it is) from the temperatures at the new state
  !> (`new_stat` and the subsystem `which` that failed first, named `name`) and the scheme's
  !> temperatures (`scheme_stat`, not looked at unless new_stat is failure_none).
  pure subroutine root_problem_text(partials_rule, new_stat, which, theta_new, name, scheme_stat, theta_scheme, &
                                    problem_text)
    integer, intent(in) :: partials_rule, new_stat, which, scheme_stat
    real(real64), intent(in) :: theta_new(:), theta_scheme(:)
    character(len=*), intent(in) :: name
    character(len=:), allocatable, intent(out) :: problem_text
    character(len=120) :: text
    integer :: a

    problem_text = ''
    if (new_stat == domain_nonpositive_temperature) then
      write (text, '(a, i0, a, es10.3, a)') 'non-positive temperature at the new state (theta_', which, ' = ', &
        theta_new(which), ' K)'
      problem_text = trim(text)
    else if (new_stat /= failure_none) then
      problem_text = trim(name)//' at the new state is outside the model''s domain ('//failure_code_name(new_stat)//')'
    else if (scheme_stat /= failure_none .and. scheme_stat /= domain_nonpositive_temperature) then
      problem_text = 'the scheme''s temperatures are undefined between the states ('//failure_code_name(scheme_stat)//')'
    else if (scheme_stat /= failure_none .or. .not. all(theta_scheme > 0.0_real64 .and. theta_scheme < huge(1.0_real64))) then
      if (partials_rule == partials_discrete_gradient) then
        problem_text = 'non-positive discrete temperature (D_tau U/D_tau S ='
      else
        problem_text = 'non-positive midpoint temperature (theta ='
      end if
      do a = 1, size(theta_scheme)
        write (text, '(1x, es10.3)') theta_scheme(a)
        problem_text = problem_text//trim(text)
      end do
      problem_text = problem_text//' K)'
    end if
  end subroutine root_problem_text

end module step_residual
