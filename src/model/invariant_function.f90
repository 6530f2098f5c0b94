!> Abstract vector of scalar functions f: R^n -> R^k of a spring's invariant variables
!> x = (C, [gamma,] tau). Discrete gradients (src/scheme) work on any extension of it.
module invariant_function
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: invariant_functions

  !> k functions of n invariants, evaluated with gradient and (optionally) Hessian.
  type, abstract :: invariant_functions
  contains
    procedure(evaluate_interface), deferred :: evaluate
    procedure :: difference
  end type invariant_functions

  abstract interface
    !> f(j) = f_j(x), grad(:, j) = grad f_j, hess(:, :, j) = Hessian of f_j.
    !> stat /= 0 means x lies outside the functions' domain; outputs are then undefined.
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
    if (stat /= 0) return
    call self%evaluate(b, f_b, g, stat=stat)
    delta = f_b - f_a
  end subroutine difference

end module invariant_function
