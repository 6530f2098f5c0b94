!> The balances a structure-preserving step keeps, measured from the accepted states alone,
!> whatever the solver did (docs/faults.md, "Every accepted step checked"). Each balance is a
!> figure in ulps of the quantities it is computed from, and one bound per balance decides:
!>
!>   energy    |E_1 - E_0 - Q| / (eps (s_E(z_0) + s_E(z_1) + |Q|))          <= bound(energy)
!>   momentum  max_k |J_k(z_1) - J_k(z_0)| / (eps (s_J(z_0) + s_J(z_1)))   <= bound(momentum)
!>   entropy   (S_0 - S_1) / (eps (s_S(z_0) + s_S(z_1)))                     <= bound(entropy)
!>   lyapunov  (V_1 - V_0) / (eps (s_V(z_0) + s_V(z_1)))                     <= bound(lyapunov)
!>
!> with Q the heat supplied through constraints in the step, J_k the model's conserved momenta,
!> V = E - theta_r S (eq. (14)), and the rounding scales s of each quantity the sums of the
!> absolute values of the terms it is summed from (src/structure/model_interface: observe's
!> energy_scale and entropy_scale, momentum_scale; s_V = s_E + theta_r s_S). At an exact root
!> of a structure-preserving step each balance is exact; evaluated in floating point, each side
!> rounds at a few ulps of its scale, so a figure beyond its bound means the step's state is not
!> the scheme's root to round-off (an inexact, lagged or damped solve), not rounding.
!> The entropy and Lyapunov figures are signed (a negative one: S rose, V fell).
module step_balances
  use, intrinsic :: iso_fortran_env, only: real64
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan, ieee_positive_inf, ieee_is_nan
  use model_interface, only: generic_model
  implicit none (type, external)
  private
  public :: balance_count, balance_energy, balance_momentum, balance_entropy, balance_lyapunov
  public :: balance_names, balance_bound_ulps, balanced_state, observe_balances, balance_figures
  public :: applicable_balances

  integer, parameter :: balance_energy = 1, balance_momentum = 2, balance_entropy = 3, balance_lyapunov = 4
  integer, parameter :: balance_count = 4
  character(len=8), parameter :: balance_names(balance_count) = [character(len=8) :: 'energy', 'momentum', &
                                                                  'entropy', 'lyapunov']
  !> The bounds, in ulps of each balance's scale (measured margins: docs/faults.md).
  real(real64), parameter :: balance_bound_ulps(balance_count) = [32.0_real64, 32.0_real64, 32.0_real64, 32.0_real64]

  !> The most momenta a model conserves: the three components of an angular momentum
  !> (model_interface's `conserved` holds at most these; the conformance kit checks each model).
  integer, parameter :: max_conserved = 3

  !> What the balances need of one state (no allocatable part: the time loop keeps two and copies
  !> one into the other every step).
  type :: balanced_state
    real(real64) :: energy = 0.0_real64
    real(real64) :: energy_scale = 0.0_real64
    real(real64) :: entropy = 0.0_real64
    real(real64) :: entropy_scale = 0.0_real64
    integer :: conserved_count = 0                   !! the model's conserved momenta (observe_balances)
    real(real64) :: conserved(max_conserved) = 0.0_real64
    real(real64) :: momentum_scale = 0.0_real64
  end type balanced_state

contains

  !> The balances the model has: the energy always, the momentum with a conserved momentum, the
  !> entropy and V with temperatures.
  pure function applicable_balances(model) result(mask)
    class(generic_model), intent(in) :: model
    logical :: mask(balance_count)

    mask = .true.
    mask(balance_momentum) = model%conserved_count() > 0
    mask(balance_entropy) = model%temperature_count() > 0
    mask(balance_lyapunov) = mask(balance_entropy)
  end function applicable_balances

  !> The balances' quantities at z and the model's temperatures there; stat /= failure_none
  !> outside the model's domain. The conserved momenta are every conserved component (all three
  !> of J without gravity: the momentum figure is the largest over them), taken from `momenta`
  !> (the model's momenta at z) when the caller has them.
  pure subroutine observe_balances(model, z, state, temperature, stat, momenta)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:)
    type(balanced_state), intent(inout) :: state
    real(real64), intent(out) :: temperature(:)
    integer, intent(out) :: stat
    real(real64), intent(in), optional :: momenta(:)

    call model%observe(z, state%energy, state%entropy, temperature, stat, state%energy_scale, state%entropy_scale)
    state%conserved_count = model%conserved_count()
    if (state%conserved_count == 0) return
    if (present(momenta)) then
      state%conserved(1:state%conserved_count) = model%conserved_in_momenta(momenta)
    else
      state%conserved(1:state%conserved_count) = model%conserved_momenta(z)
    end if
    state%momentum_scale = model%momentum_scale(z)
  end subroutine observe_balances

  !> The four figures of the step from `old` to `new` (module header), in ulps of their scales;
  !> `heat` is Q and theta_r the Lyapunov function's reference temperature. A figure the model
  !> cannot have (not `applicable`: applicable_balances of the model) is NaN. The step's changes
  !> of E and S (`changes`) and of the conserved momenta (`conserved_changes`) are new minus old
  !> unless given: a model summed from 10^5 parts gives them as sums of the parts' differences,
  !> free of the cancellation of a difference of two large sums.
  pure function balance_figures(applicable, old, new, heat, theta_r, changes, conserved_changes) result(figures)
    logical, intent(in) :: applicable(balance_count)
    type(balanced_state), intent(in) :: old, new
    real(real64), intent(in) :: heat, theta_r
    real(real64), intent(in), optional :: changes(2), conserved_changes(max_conserved)
    real(real64) :: figures(balance_count)
    real(real64) :: delta_energy, delta_entropy, delta_conserved(max_conserved)
    integer :: k

    delta_energy = new%energy - old%energy
    delta_entropy = new%entropy - old%entropy
    if (present(changes)) then
      delta_energy = changes(1)
      delta_entropy = changes(2)
    end if
    delta_conserved = new%conserved - old%conserved
    if (present(conserved_changes)) delta_conserved = conserved_changes
    figures = ieee_value(1.0_real64, ieee_quiet_nan)
    figures(balance_energy) = in_ulps(abs(delta_energy - heat), old%energy_scale + new%energy_scale + abs(heat))
    if (applicable(balance_momentum)) then
      figures(balance_momentum) = 0.0_real64
      do k = 1, new%conserved_count
        figures(balance_momentum) = max(figures(balance_momentum), &
          in_ulps(abs(delta_conserved(k)), old%momentum_scale + new%momentum_scale))
      end do
    end if
    if (applicable(balance_entropy)) then
      figures(balance_entropy) = in_ulps(-delta_entropy, old%entropy_scale + new%entropy_scale)
      figures(balance_lyapunov) = in_ulps(delta_energy - theta_r*delta_entropy, &
                                          old%energy_scale + new%energy_scale + &
                                          theta_r*(old%entropy_scale + new%entropy_scale))
    end if
  end function balance_figures

  ! A difference in ulps of its scale: 0 for an exact balance at a scale of 0 (a state at rest),
  ! infinite for any other difference there; NaN stays NaN.
  pure real(real64) function in_ulps(difference, scale)
    real(real64), intent(in) :: difference, scale

    if (scale > 0.0_real64 .or. ieee_is_nan(difference)) then
      in_ulps = difference/(epsilon(1.0_real64)*scale)
    else if (.not. abs(difference) > 0.0_real64) then
      in_ulps = 0.0_real64
    else
      in_ulps = sign(ieee_value(1.0_real64, ieee_positive_inf), difference)
    end if
  end function in_ulps

end module step_balances
