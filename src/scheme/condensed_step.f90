!> A model's own form of the discrete-gradient step (the hook of docs/development.md, "A fused
!> step"): the same equations as the generic step residual (src/scheme/step_residual, its test
!> oracle) on fewer unknowns. Its leading `eliminated` unknowns of x follow from the others, y =
!> x(eliminated + 1:), which Newton solves for; the EME stepper uses it when the model offers
!> one (src/model/model_registry, fused_step_of) and -eme_fused_kernel is true.
module condensed_step
  use, intrinsic :: iso_fortran_env, only: real64
  use nonlinear_problem, only: nonlinear_system
  implicit none (type, external)
  private
  public :: condensed_step_problem

  !> The step of dt from an old state, on the condensed unknowns y.
  type, abstract, extends(nonlinear_system) :: condensed_step_problem
    integer :: eliminated = 0                  !! the leading unknowns of x that follow from y
    real(real64) :: dt = 0.0_real64
  contains
    procedure(old_state_interface), deferred :: set_old_state
    procedure(expand_interface), deferred :: expand
    procedure(condense_interface), deferred :: condense
    procedure(temperatures_interface), deferred :: scheme_temperatures
  end type condensed_step_problem

  abstract interface
    !> The step's old state z (what the step needs of it is computed once, here).
    pure subroutine old_state_interface(self, z)
      import :: condensed_step_problem, real64
      class(condensed_step_problem), intent(inout) :: self
      real(real64), intent(in) :: z(:)
    end subroutine old_state_interface

    !> The generic unknowns x of the condensed y.
    pure function expand_interface(self, y) result(x)
      import :: condensed_step_problem, real64
      class(condensed_step_problem), intent(in) :: self
      real(real64), intent(in) :: y(:)
      real(real64) :: x(size(y) + self%eliminated)
    end function expand_interface

    !> The condensed unknowns y of the generic x.
    pure function condense_interface(self, x) result(y)
      import :: condensed_step_problem, real64
      class(condensed_step_problem), intent(in) :: self
      real(real64), intent(in) :: x(:)
      real(real64) :: y(size(x) - self%eliminated)
    end function condense_interface

    !> The temperatures where the step evaluates K0, at the root y; stat as the model's domain codes.
    pure subroutine temperatures_interface(self, y, theta, stat)
      import :: condensed_step_problem, real64
      class(condensed_step_problem), intent(in) :: self
      real(real64), intent(in) :: y(:)
      real(real64), intent(out) :: theta(:)
      integer, intent(out) :: stat
    end subroutine temperatures_interface
  end interface

end module condensed_step
