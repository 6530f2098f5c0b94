!> What the dense run (src/run/simulation) sees of its state: the balances' quantities, the
!> temperatures and the momenta of the state it looked at last, and E, S and V of the state it
!> took last (the old state of the next step's check, src/run/step_check); and the figures of a
!> step from one to the other (src/structure/step_balances).
module dense_observation
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use step_balances, only: balance_count, balanced_state, observe_balances, balance_figures
  use run_outcome, only: run_summary
  use time_loop_steps, only: lower_min_temperature
  implicit none (type, external)
  private
  public :: state_observation

  !> The state the loop looked at last (`new`, `theta`, `momentum`) and the one it took last
  !> (`old`, `energy`, `entropy`, `lyapunov`: V = E - Theta_r S, docs/formulation.md).
  type :: state_observation
    type(balanced_state) :: old, new
    real(real64), allocatable :: theta(:)      !! the temperatures of the state looked at last
    real(real64), allocatable :: momentum(:)   !! its momenta (the model's momenta())
    real(real64) :: energy = 0.0_real64, entropy = 0.0_real64, lyapunov = 0.0_real64
  contains
    procedure :: look
    procedure :: take
    procedure :: measure
  end type state_observation

contains

  !> Looks at the state `z`: its balances' quantities, temperatures and momenta.
  subroutine look(self, model, z)
    class(state_observation), intent(inout) :: self
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    integer :: domain

    if (.not. allocated(self%theta)) allocate (self%theta(model%temperature_count()))
    self%momentum = model%momenta(z)
    call observe_balances(model, z, self%new, self%theta, domain, self%momentum)
  end subroutine look

  !> Takes the state looked at last: its E, S and V, the old state of the next step's check; the
  !> summary's lowest temperature goes with its temperatures.
  subroutine take(self, summary, theta_r)
    class(state_observation), intent(inout) :: self
    type(run_summary), intent(inout) :: summary
    real(real64), intent(in) :: theta_r     !! the reference temperature of V

    self%energy = self%new%energy
    self%entropy = self%new%entropy
    self%old = self%new
    self%lyapunov = self%energy - theta_r*self%entropy
    call lower_min_temperature(summary, self%theta)
  end subroutine take

  !> The step from the state taken last to `x_new` (state and multipliers) over `step_time`: its
  !> heat through the constraints (a multiplier is the step's mean rate, lambda_2 a heat power,
  !> so the heat is rate times the step) and its balance figures; x_new is looked at.
  subroutine measure(self, model, constraints, x_new, step_time, has_balance, theta_r, step_heat, figures)
    class(state_observation), intent(inout) :: self
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: x_new(:), step_time, theta_r
    logical, intent(in) :: has_balance(balance_count)
    real(real64), intent(out) :: step_heat, figures(balance_count)
    integer :: k

    step_heat = 0.0_real64
    do k = 1, size(constraints)
      step_heat = step_heat + step_time*constraints(k)%item%heat_supply(x_new(model%state_size + k))
    end do
    call self%look(model, x_new(1:model%state_size))
    figures = balance_figures(has_balance, self%old, self%new, step_heat, theta_r)
  end subroutine measure

end module dense_observation
