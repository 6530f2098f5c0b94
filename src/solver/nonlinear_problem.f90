!> What the nonlinear solvers need from a problem R(x) = 0 of any size: the residual with its
!> Jacobian, a physical check of a root, a continuation parameter s in (0, 1] that deforms
!> the problem into an easier one (s = 1 is the problem itself; as s -> 0 a known point, such
!> as a time step's old state, becomes a root), and optionally the scales of its rounding and the
!> step length its Jacobian belongs to.
module nonlinear_problem
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: nonlinear_system

  !> A square nonlinear system R(x) = 0.
  type, abstract :: nonlinear_system
  contains
    procedure(unknowns_interface), deferred :: unknowns
    procedure(evaluate_interface), deferred :: evaluate
    procedure(check_root_interface), deferred :: check_root
    procedure(continuation_interface), deferred :: set_continuation
    procedure :: rounding_scales
    procedure :: step_length
    procedure :: evaluate_residual
    procedure :: evaluate_jacobian
  end type nonlinear_system

  abstract interface
    !> Number of unknowns (and equations).
    pure integer function unknowns_interface(self)
      import :: nonlinear_system
      class(nonlinear_system), intent(in) :: self
    end function unknowns_interface

    !> R(x) and optionally dR/dx; stat /= 0 when x lies outside the problem's domain.
    pure subroutine evaluate_interface(self, x, residual, jacobian, stat)
      import :: nonlinear_system, real64
      class(nonlinear_system), intent(in) :: self
      real(real64), intent(in) :: x(:)
      real(real64), intent(out) :: residual(:)
      real(real64), intent(out), optional :: jacobian(:, :)
      integer, intent(out) :: stat
    end subroutine evaluate_interface

    !> Why x is not an acceptable root ('' if it is).
    pure subroutine check_root_interface(self, x, problem_text)
      import :: nonlinear_system, real64
      class(nonlinear_system), intent(in) :: self
      real(real64), intent(in) :: x(:)
      character(len=:), allocatable, intent(out) :: problem_text
    end subroutine check_root_interface

    !> Selects the deformed problem at s in (0, 1].
    pure subroutine continuation_interface(self, s)
      import :: nonlinear_system, real64
      class(nonlinear_system), intent(inout) :: self
      real(real64), intent(in) :: s
    end subroutine continuation_interface
  end interface

contains

  !> R(x) for a Newton iteration that may next ask for dR/dx at the same x (evaluate_jacobian): a
  !> problem may keep what the residual computed. This default evaluates.
  subroutine evaluate_residual(self, x, residual, stat)
    class(nonlinear_system), intent(inout) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: residual(:)
    integer, intent(out) :: stat

    call self%evaluate(x, residual, stat=stat)
  end subroutine evaluate_residual

  !> dR/dx; a problem that kept the residual's pass at this x reuses it. This default evaluates
  !> residual and Jacobian.
  subroutine evaluate_jacobian(self, x, jacobian, stat)
    class(nonlinear_system), intent(inout) :: self
    real(real64), intent(in) :: x(:)
    real(real64), intent(out) :: jacobian(:, :)
    integer, intent(out) :: stat
    real(real64) :: residual(size(x))

    call self%evaluate(x, residual, jacobian, stat)
  end subroutine evaluate_jacobian

  !> Sizes that say where rounding ends Newton's iteration (retry_strategies' newton_converged):
  !> an update below ~eps state_scale and a residual below ~eps residual_scale are at the rounding
  !> of a root. They must come from a point known to be sane (a time step's old state), not from
  !> the iterate. This default knows none (zeros): only the tolerance decides.
  pure subroutine rounding_scales(self, state_scale, residual_scale)
    class(nonlinear_system), intent(in) :: self
    real(real64), intent(out) :: state_scale, residual_scale

    state_scale = 0.0_real64
    residual_scale = 0.0_real64
  end subroutine rounding_scales

  !> The length of the time step whose equation this is (s dt under continuation): LU factors of
  !> the Jacobian serve the next step only if its length is the same (src/solver/modified_newton).
  !> This default is no time step (0): factors are not carried from one solve to the next.
  pure real(real64) function step_length(self)
    class(nonlinear_system), intent(in) :: self

    step_length = 0.0_real64
  end function step_length

end module nonlinear_problem
