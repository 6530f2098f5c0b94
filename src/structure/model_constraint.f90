!> Constraints g(z) = 0 of eq. (13) with Lagrange multipliers, as a model offers them: each
!> active constraint adds its multiplier lambda to the unknowns of a step, its generalized force
!> (the paper's N lambda) to the state rows of the step residual, and its equation g(z') = 0 as
!> the multiplier's row (FORMULATION section 7).
module model_constraint
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  implicit none (type, external)
  private
  public :: constraint, constraint_slot

  !> One constraint. `name` is its namelist and output name (columns lambda_<name>, g_<name>).
  type, abstract :: constraint
    character(len=16) :: name = ''
    character(len=8) :: multiplier_units = ''    !! of lambda
    character(len=8) :: value_units = ''         !! of g
    character(len=80) :: meaning = ''            !! what g and lambda are, for the output's descriptions
    logical :: supplies_heat = .false.           !! lambda is a heat power from the surroundings [W]
  contains
    procedure(add_terms_interface), deferred :: add_terms
    procedure(value_interface), deferred :: value
    procedure :: heat_supply
  end type constraint

  !> A constraint in a list of the active ones.
  type :: constraint_slot
    class(constraint), allocatable :: item
  end type constraint_slot

  abstract interface
    !> Adds lambda's force to residual(1:state_size), writes g(z') into residual(row) and, with
    !> the Jacobian, the derivatives of both in the unknowns (z', multipliers). `partials` and
    !> `dpartials_dz` are the step's, z_mid = (z + z')/2. stat /= 0: z' is outside the domain.
    pure subroutine add_terms_interface(self, model, z_new, z_mid, partials, dpartials_dz, lambda, row, residual, &
                                        jacobian, stat)
      import :: constraint, generic_model, real64
      class(constraint), intent(in) :: self
      class(generic_model), intent(in) :: model
      real(real64), intent(in) :: z_new(:), z_mid(:), partials(:, :, :), dpartials_dz(:, :, :, :), lambda
      integer, intent(in) :: row
      real(real64), intent(inout) :: residual(:)
      real(real64), intent(inout), optional :: jacobian(:, :)
      integer, intent(out) :: stat
    end subroutine add_terms_interface

    !> g(z), as the output records it.
    pure subroutine value_interface(self, model, z, g, stat)
      import :: constraint, generic_model, real64
      class(constraint), intent(in) :: self
      class(generic_model), intent(in) :: model
      real(real64), intent(in) :: z(:)
      real(real64), intent(out) :: g
      integer, intent(out) :: stat
    end subroutine value_interface
  end interface

contains

  !> The heat the constraint supplies per unit time for multiplier lambda [W]: lambda itself for
  !> a constraint that exchanges heat with the surroundings, zero otherwise.
  pure real(real64) function heat_supply(self, lambda)
    class(constraint), intent(in) :: self
    real(real64), intent(in) :: lambda

    heat_supply = 0.0_real64
    if (self%supplies_heat) heat_supply = lambda
  end function heat_supply

end module model_constraint
