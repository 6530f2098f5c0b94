!> Constraints g(z) = 0 of eq. (13) with Lagrange multipliers, as a model offers them: each
!> active constraint adds its multiplier lambda to the unknowns of a step, its generalized force
!> (the paper's N lambda) to the state rows of the step residual, and its equation g(z') = 0 as
!> the multiplier's row (docs/formulation.md section 7).
!>
!> Integrators of the continuous flow (the relaxed Runge-Kutta family) use a constraint's
!> continuous-time form instead, when it has one (`continuous_form`): a map that slaves state
!> entries to the others (g2: Theta_a = thetabar fixes tau_a), a force with the index-1 multiplier
!> (g1: the multiplier that keeps d^2 g/dt^2 = 0), the projection of positions back onto g = 0
!> after a step, a condition linear in the momenta (g1: dg/dt = 0), and the temperature of the
!> heat bath the constraint couples to (g2), which turns the conserved energy into the Lyapunov
!> function V = E - thetabar S. The defaults do nothing.
module model_constraint
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
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
    logical :: continuous_form = .false.         !! it offers the continuous-time form below
  contains
    procedure(add_terms_interface), deferred :: add_terms
    procedure(value_interface), deferred :: value
    procedure :: heat_supply
    procedure :: slave_state
    procedure :: add_force
    procedure :: project_positions
    procedure :: momentum_condition
    procedure :: bath_temperature
    procedure :: inconsistency
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

  !> z <- sigma(z), the state with the entries the constraint fixes set from the others; with
  !> `chain`, chain <- (d sigma/dz) chain. The default fixes nothing.
  pure subroutine slave_state(self, model, z, stat, chain)
    class(constraint), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(inout) :: z(:)
    integer, intent(out) :: stat
    real(real64), intent(inout), optional :: chain(:, :)

    stat = failure_none
  end subroutine slave_state

  !> f <- f + N lambda, the constraint force with its index-1 multiplier lambda(z, f) for the
  !> field f at z; with `jacobian` (df/dz on entry), its derivative. The default adds nothing.
  pure subroutine add_force(self, model, z, f, multiplier, jacobian)
    class(constraint), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    real(real64), intent(inout) :: f(:)
    real(real64), intent(out) :: multiplier
    real(real64), intent(inout), optional :: jacobian(:, :)

    multiplier = 0.0_real64
  end subroutine add_force

  !> Moves the positions of z back onto g = 0. The default moves nothing.
  pure subroutine project_positions(self, model, z)
    class(constraint), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(inout) :: z(:)
  end subroutine project_positions

  !> A condition c(z) = gradient . z = 0 that is linear in the momenta at fixed positions (the
  !> hidden constraint dg/dt = 0), with gradient zero outside the momenta; has = .false. if the
  !> constraint has none (the default).
  pure subroutine momentum_condition(self, model, z, has, value, gradient)
    class(constraint), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    logical, intent(out) :: has
    real(real64), intent(out) :: value, gradient(:)

    has = .false.
    value = 0.0_real64
    gradient = 0.0_real64
  end subroutine momentum_condition

  !> The temperature of the heat bath the constraint holds a subsystem at [K], 0 for none.
  pure real(real64) function bath_temperature(self)
    class(constraint), intent(in) :: self

    bath_temperature = 0.0_real64
  end function bath_temperature

  !> Why z cannot start a continuous-time integration under the constraint ('' if it can): the
  !> hidden constraints (dg/dt = 0) must hold at t = 0.
  function inconsistency(self, model, z) result(text)
    class(constraint), intent(in) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    character(len=:), allocatable :: text

    text = ''
  end function inconsistency

end module model_constraint
