!> Abstract vector of scalar functions f: R^n -> R^k of a subsystem's invariant variables
!> x = (mechanical invariants, tau), e.g. a spring's (U_a, S_a) of (C, [gamma,] tau). Discrete
!> gradients (src/scheme) work on any extension of it. Evaluations outside the functions'
!> domain report one of failures' domain_* codes instead of stopping (a bare code, not a
!> failure_type: these run on every Newton iteration, docs/development.md "Errors").
module invariant_function
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none, domain_nonpositive_temperature, domain_overflow
  implicit none (type, external)
  private
  public :: invariant_functions, potential_u, potential_s

  integer, parameter :: potential_u = 1  !! index of the internal energy U_a in f(:)
  integer, parameter :: potential_s = 2  !! index of the entropy S_a in f(:)

  !> k functions of n invariants, evaluated with gradient and (optionally) Hessian.
  type, abstract :: invariant_functions
  contains
    procedure(evaluate_interface), deferred :: evaluate
    procedure :: difference
    procedure :: temperature
    procedure :: values_and_temperature
    procedure :: tau_from_temperature
  end type invariant_functions

  abstract interface
    !> f(j) = f_j(x), grad(:, j) = grad f_j, hess(:, :, j) = Hessian of f_j.
    !> stat /= failure_none means x lies outside the functions' domain; outputs are then undefined.
    pure subroutine evaluate_interface(self, x, f, grad, hess, stat)
      import :: invariant_functions, real64
      class(invariant_functions), intent(in) :: self
      real(real64), intent(in) :: x(:)
      real(real64), intent(out) :: f(:), grad(:, :)
      real(real64), intent(out), optional :: hess(:, :, :)
      integer, intent(out) :: stat
    end subroutine evaluate_interface
  end interface

contains

  !> f(b) - f(a). This default subtracts two evaluations; functions that can, override it with
  !> a form free of cancellation (the discrete gradients divide it by |b - a|).
  pure subroutine difference(self, a, b, delta, stat)
    class(invariant_functions), intent(in) :: self
    real(real64), intent(in) :: a(:), b(:)
    real(real64), intent(out) :: delta(:)
    integer, intent(out) :: stat
    real(real64) :: f_a(size(delta)), f_b(size(delta)), g(size(a), size(delta))

    call self%evaluate(a, f_a, g, stat=stat)
    if (stat /= failure_none) return
    call self%evaluate(b, f_b, g, stat=stat)
    delta = f_b - f_a
  end subroutine difference

  !> The temperature Theta = d_tau U / d_tau S of eq. (2) at x, tau being the last invariant.
  !> This default divides the derivatives; functions with a closed form override it.
  pure subroutine temperature(self, x, theta, stat)
    class(invariant_functions), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: theta
    integer, intent(out) :: stat
    real(real64) :: f(2), g(size(x), 2)

    theta = 0.0_real64
    call self%evaluate(x, f, g, stat=stat)
    if (stat /= failure_none) return
    theta = g(size(x), potential_u)/g(size(x), potential_s)
    if (.not. (theta > 0.0_real64)) stat = domain_nonpositive_temperature
  end subroutine temperature

  !> f(x) and the temperature at x, what a run observes of a state each step; optionally the
  !> rounding scales of f: the sums of the absolute values of the terms each f_j is computed from
  !> (src/structure/step_balances divides the step's balances by them). This default evaluates and
  !> then asks for the temperature, and takes |S| as S's scale and |U| + Theta |S| as U's (a U
  !> summed as F + Theta S); functions that share the work or sum other terms override it.
  pure subroutine values_and_temperature(self, x, f, theta, stat, scales)
    class(invariant_functions), intent(in) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: f(:), theta
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: scales(:)
    real(real64) :: g(size(x), size(f))

    theta = 0.0_real64
    call self%evaluate(x, f, g, stat=stat)
    if (present(scales)) scales = 0.0_real64
    if (stat /= failure_none) return
    call self%temperature(x, theta, stat)
    if (present(scales) .and. size(f) == 2) &
      scales = [abs(f(potential_u)) + theta*abs(f(potential_s)), abs(f(potential_s))]
  end subroutine values_and_temperature

  !> The value of tau (the last invariant) that gives temperature theta at the mechanical
  !> invariants (the others). This default cannot invert: stat = domain_overflow; functions with
  !> a closed form override it (a model that changes thermodynamic variables needs it).
  pure subroutine tau_from_temperature(self, mechanical, theta, tau, stat)
    class(invariant_functions), intent(in) :: self
    real(real64), intent(in) :: mechanical(:)
    real(real64), intent(in) :: theta
    real(real64), intent(out) :: tau
    integer, intent(out) :: stat

    tau = 0.0_real64
    stat = domain_overflow
  end subroutine tau_from_temperature

end module invariant_function
