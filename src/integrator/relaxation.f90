!> Relaxation of a Runge-Kutta step (Ketcheson 2019; Ranocha, Sayyari, Dalcin, Parsani,
!> Ketcheson 2020; HIGH_ORDER.md): the step z + d is replaced by z + Delta(gamma), where
!> Delta(gamma) = gamma d with the momenta corrected so that the conserved component of the
!> angular momentum keeps its value, and gamma is the root near 1 of
!>   r(gamma) = E(z + Delta(gamma)) - E(z) = 0,
!> evaluated with the model's cancellation-free energy difference. The momentum correction is
!> exact because J.a is linear in the momenta at fixed positions; it changes no entropy, so with
!> tau = s the entropy change stays gamma times the step's entropy estimate.
module relaxation
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: domain_ok
  use model_interface, only: generic_model
  implicit none (type, external)
  private
  public :: relax, relaxed_increment, gamma_min, gamma_max

  !> The gamma a step may take (HIGH_ORDER.md); outside, the step is rejected.
  real(real64), parameter :: gamma_min = 0.2_real64, gamma_max = 2.0_real64
  integer, parameter :: max_secant_steps = 30
  real(real64), parameter :: settled = 1.0e-13_real64   !! a secant step this small ends the iteration

contains

  !> gamma and z_new = z + Delta(gamma) with E(z_new) = E(z) to round-off and the conserved
  !> momentum unchanged; found = .false. when no root lies in [gamma_min, gamma_max] or an
  !> evaluation leaves the model's domain. `evaluations` counts the energy differences taken.
  subroutine relax(model, z, d, gamma, z_new, found, evaluations)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), d(:)
    real(real64), intent(out) :: gamma, z_new(:)
    logical, intent(out) :: found
    integer, intent(out) :: evaluations
    real(real64) :: momentum, g_a, g_b, q_a, q_b, g_next
    integer :: k, stat
    logical :: converged

    found = .false.
    evaluations = 0
    momentum = model%conserved_momentum(z)
    ! r(0) = 0 always: the secant runs on q(gamma) = r(gamma)/gamma, whose root is the
    ! nontrivial one, from gamma = 1 (an order-p step has r(1) = O(h^(p+1))) and 1 - 1e-3.
    g_a = 1.0_real64
    call scaled_residual(g_a, q_a, stat)
    if (stat /= domain_ok) return
    gamma = g_a
    if (.not. (abs(q_a) > 0.0_real64)) then
      found = .true.
      return
    end if
    g_b = 1.0_real64 - 1.0e-3_real64
    call scaled_residual(g_b, q_b, stat)
    if (stat /= domain_ok) return
    ! Secant steps (q is nearly linear near the root, so they converge fast) until a step moves
    ! gamma by less than `settled`: the secant's error is then far below that step, and gamma
    ! is the root to round-off. Stagnation elsewhere, or a step out of range, means no root.
    converged = .false.
    do k = 1, max_secant_steps
      if (.not. (abs(q_b - q_a) > 0.0_real64)) exit
      g_next = g_b - q_b*(g_b - g_a)/(q_b - q_a)
      if (.not. (g_next >= 0.5_real64*gamma_min .and. g_next <= 2.0_real64*gamma_max)) exit
      converged = abs(g_next - g_b) <= settled
      if (converged) then
        g_b = g_next
        exit
      end if
      g_a = g_b
      q_a = q_b
      g_b = g_next
      call scaled_residual(g_b, q_b, stat)
      if (stat /= domain_ok) return
      if (.not. (abs(q_b) > 0.0_real64)) converged = .true.
      if (converged) exit
    end do
    gamma = g_b
    found = converged .and. gamma >= gamma_min .and. gamma <= gamma_max
    if (found) z_new = relaxed_increment(model, z, d, gamma, momentum)

  contains

    subroutine scaled_residual(g, q, stat)
      real(real64), intent(in) :: g
      real(real64), intent(out) :: q
      integer, intent(out) :: stat
      real(real64) :: r

      z_new = relaxed_increment(model, z, d, g, momentum)
      call model%energy_difference(z, z_new, r, stat)
      evaluations = evaluations + 1
      q = r/g
      if (.not. (abs(q) <= huge(q))) stat = domain_ok + 1
    end subroutine scaled_residual
  end subroutine relax

  !> z + gamma d with the momenta corrected along the conserved momentum's gradient c (at the new
  !> positions) so that J.a keeps the value `momentum`: p <- p - ((J.a)(z + gamma d) - momentum) c/|c|^2.
  pure function relaxed_increment(model, z, d, gamma, momentum) result(z_new)
    class(generic_model), intent(in) :: model
    real(real64), intent(in) :: z(:), d(:), gamma, momentum
    real(real64) :: z_new(size(z))
    real(real64) :: c(size(z)), norm_squared

    z_new = z + gamma*d
    c = model%conserved_momentum_gradient(z_new)
    norm_squared = dot_product(c, c)
    if (norm_squared > 0.0_real64) z_new = z_new - (model%conserved_momentum(z_new) - momentum)/norm_squared*c
  end function relaxed_increment

end module relaxation
