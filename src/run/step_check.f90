!> The check of every accepted step (docs/faults.md, "Every accepted step checked"): which of the
!> balances of src/structure/step_balances a run guarantees (its integrator's registry entry,
!> less what its model and constraints do not have), and whether a step's figures keep them.
!> The time loop (src/run/simulation) measures the figures after each step; a step that breaks a
!> guaranteed balance is solved again with the model's default solver settings
!> (time_stepper%resolve), and a run whose step still breaks one stops (failure kind 'balance').
module step_check
  use, intrinsic :: iso_fortran_env, only: real64
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use integrator_registry, only: integrator_entry
  use step_balances, only: balance_count, balance_entropy, balance_lyapunov, balance_names, balance_bound_ulps, &
                           applicable_balances
  use number_text, only: scientific_text
  implicit none (type, external)
  private
  public :: checked_balances, broken_balance, balance_text

contains

  !> The balances a run checks on every step: those its integrator guarantees and its model has;
  !> with a constraint that supplies heat (g2), neither dS >= 0 nor dV <= 0 (heat leaving the
  !> system lowers S, and V keeps falling only for some variables: docs/constraints.md).
  pure function checked_balances(entry, model, constraints) result(checked)
    type(integrator_entry), intent(in) :: entry
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    logical :: checked(balance_count)
    integer :: k

    checked = entry%guarantees .and. applicable_balances(model)
    do k = 1, size(constraints)
      if (constraints(k)%item%supplies_heat) then
        checked(balance_entropy) = .false.
        checked(balance_lyapunov) = .false.
      end if
    end do
  end function checked_balances

  !> The first checked balance whose figure is beyond its bound for a step made of `substeps`
  !> steps of the scheme (each may add its own rounding), or a NaN figure; 0 if none.
  pure integer function broken_balance(figures, checked, substeps)
    real(real64), intent(in) :: figures(balance_count)
    logical, intent(in) :: checked(balance_count)
    integer, intent(in) :: substeps
    integer :: k

    broken_balance = 0
    do k = 1, balance_count
      if (.not. checked(k)) cycle
      if (figures(k) <= balance_bound_ulps(k)*max(1, substeps)) cycle
      broken_balance = k
      return
    end do
  end function broken_balance

  !> What the figure of balance k says, for a status line.
  function balance_text(k, figures) result(text)
    integer, intent(in) :: k
    real(real64), intent(in) :: figures(balance_count)
    character(len=:), allocatable :: text

    text = 'the '//trim(balance_names(k))//' balance is off by '//scientific_text(figures(k))// &
           ' ulps of its scale, above its bound of '//scientific_text(balance_bound_ulps(k))// &
           ' (docs/faults.md, Every accepted step checked)'
  end function balance_text

end module step_check
