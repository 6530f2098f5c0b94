!> One spring's partials for a step or for the field (docs/formulation.md section 10): the
!> derivatives of its (U_a, S_a) in its invariants x_a = (C_a, [gamma_a,] [tau_a]) and their
!> derivatives in the spring block's local slots (spring_chain_layout), computed once per spring
!> and shared by its spring block and its two links:
!>  - partials_discrete_gradient (EME): the local discrete gradient between x_a(old) and x_a(new),
!>    by src/scheme's discrete_gradient_of; derivatives in the new slots;
!>  - partials_midpoint (the midpoint rule): exact partials at x_a(z_mid); derivatives in the new slots;
!>  - partials_exact (the continuous field, for PETSc TS): exact partials at x_a(new); derivatives
!>    in those slots.
!> With them comes r_a at the point where the field is evaluated (r_mid, or r) and `weight`, the
!> derivative of such a midpoint quantity in a new slot (1/2 for the steps, 1 for the field).
module spring_chain_partials
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use invariant_function, only: potential_u, potential_s
  use step_residual, only: partials_discrete_gradient, partials_midpoint
  use spring_chain_spring, only: chain_spring, spring_invariants
  use spring_chain_layout, only: spring_slots, slots_of
  implicit none (type, external)
  private
  public :: spring_partials, evaluate_spring_partials, partials_exact, partials_discrete_gradient, partials_midpoint
  public :: max_slots

  !> The continuous field's exact partials, beside step_residual's two rules.
  integer, parameter :: partials_exact = 0
  !> The most local slots of a spring block: 4 d + 2 with d = 3.
  integer, parameter :: max_slots = 14

  !> One spring's partials, partials(i, k) = D_i of potential k (1: U, 2: S) in invariant i.
  type :: spring_partials
    integer :: invariants = 0
    type(spring_slots) :: slots
    real(real64) :: partials(3, 2) = 0.0_real64
    !> d partials(i, k)/d slot j of the spring block
    real(real64) :: dpartials(3, 2, max_slots) = 0.0_real64
    real(real64) :: r(3) = 0.0_real64          !! r_a,mid (steps) or r_a (field), `dimension` used
    real(real64) :: weight = 0.5_real64        !! d r/d x_right = weight I, likewise for v in p
    real(real64) :: theta = 0.0_real64         !! D_tau U/D_tau S: discrete, midpoint or exact temperature
  end type spring_partials

contains

  !> Spring `spring`'s partials by `rule` (partials_*) from its local slots' old and new values
  !> (spring_chain_layout's gather_spring), with `gradient` and `metric` for the discrete
  !> gradient; `dimension` components. stat: a domain code of the potentials. With
  !> with_derivatives false (default true) the partials' derivatives in the slots are skipped
  !> (dpartials stays 0): a residual needs the partials alone, and their second derivatives cost
  !> most of the evaluation.
  pure subroutine evaluate_spring_partials(spring, rule, gradient, metric, dimension, old, new, part, stat, with_derivatives)
    type(chain_spring), intent(in) :: spring
    integer, intent(in) :: rule, gradient, metric, dimension
    real(real64), intent(in) :: old(:), new(:)
    type(spring_partials), intent(out) :: part
    integer, intent(out) :: stat
    logical, intent(in), optional :: with_derivatives
    real(real64) :: r_old(dimension), r_new(dimension), x_old(3), x_new(3), f(2), second(3, 3, 2), dc_dr(dimension)
    real(real64) :: at(size(new)), w
    integer :: n, d, i, k, c
    logical :: derivatives

    derivatives = .true.
    if (present(with_derivatives)) derivatives = with_derivatives
    n = spring%invariant_count
    d = dimension
    part%invariants = n
    part%slots = slots_of(d, n)
    associate (s => part%slots)
      r_old = old(s%x_right(1:d)) - old(s%x_left(1:d))
      r_new = new(s%x_right(1:d)) - new(s%x_left(1:d))
      select case (rule)
      case (partials_discrete_gradient)
        part%weight = 0.5_real64
        part%r(1:d) = 0.5_real64*(r_old + r_new)
        call invariants_at(old, r_old, x_old)
        call invariants_at(new, r_new, x_new, dc_dr)
        if (derivatives) then
          call spring%discrete_gradient(gradient, metric, x_old(1:n), x_new(1:n), part%partials(1:n, :), &
                                        second(1:n, 1:n, :), stat)
        else
          call spring%discrete_gradient(gradient, metric, x_old(1:n), x_new(1:n), part%partials(1:n, :), stat=stat)
        end if
      case default
        ! The field at the new slots, or the midpoint rule's at the middle ones.
        part%weight = 1.0_real64
        at = new
        if (rule == partials_midpoint) then
          part%weight = 0.5_real64
          at = 0.5_real64*(old + new)
        end if
        part%r(1:d) = at(s%x_right(1:d)) - at(s%x_left(1:d))
        call invariants_at(at, part%r(1:d), x_new, dc_dr)
        if (derivatives) then
          call spring%evaluate(x_new(1:n), f, part%partials(1:n, :), second(1:n, 1:n, :), stat)
        else
          call spring%evaluate(x_new(1:n), f, part%partials(1:n, :), stat=stat)
        end if
        dc_dr = part%weight*dc_dr
      end select
      if (stat /= failure_none) return
      if (n >= 2) part%theta = part%partials(n, potential_u)/part%partials(n, potential_s)
      if (.not. derivatives) return

      ! Chain rule to the slots: C through x_left and x_right (dC/dslot = +-dc_dr), gamma and tau
      ! as they are (weight_of), written out (the matmul by a sparse dx/dslot it replaces cost
      ! chain_bench's loop 87e6 more instructions in 2 steps of 1e4 springs).
      w = weight_of(rule)
      do k = 1, 2
        do i = 1, n
          do c = 1, d
            part%dpartials(i, k, s%x_right(c)) = second(i, 1, k)*dc_dr(c)
            part%dpartials(i, k, s%x_left(c)) = -second(i, 1, k)*dc_dr(c)
          end do
          if (s%gamma > 0) part%dpartials(i, k, s%gamma) = second(i, 2, k)*w
          if (s%tau > 0) part%dpartials(i, k, s%tau) = second(i, n, k)*w
        end do
      end do
    end associate

  contains

    ! The invariants at local values `v` with r = v(x_right) - v(x_left) given.
    pure subroutine invariants_at(v, r, x, dc)
      real(real64), intent(in) :: v(:), r(:)
      real(real64), intent(out) :: x(3)
      real(real64), intent(out), optional :: dc(:)
      real(real64) :: gamma, tau

      gamma = 0.0_real64
      tau = 0.0_real64
      if (part%slots%gamma > 0) gamma = v(part%slots%gamma)
      if (part%slots%tau > 0) tau = v(part%slots%tau)
      x = 0.0_real64
      call spring_invariants(r, gamma, tau, n, x(1:n), dc)
    end subroutine invariants_at
  end subroutine evaluate_spring_partials

  ! The derivative of the point where the partials are taken in a new slot: 1 for a discrete
  ! gradient (its derivative in b) and the field, 1/2 for the midpoint rule.
  pure real(real64) function weight_of(rule)
    integer, intent(in) :: rule

    weight_of = 1.0_real64
    if (rule == partials_midpoint) weight_of = 0.5_real64
  end function weight_of

end module spring_chain_partials
