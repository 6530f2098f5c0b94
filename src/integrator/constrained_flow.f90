!> The continuous constrained flow that the relaxed Runge-Kutta family integrates (docs/integrators.md,
!> Constraints), built from each active constraint's continuous-time form
!> (src/structure/model_constraint):
!>  - the field F(z) = f(sigma(z)) + N lambda: the continuous GENERIC field at the state whose
!>    slaved entries (g2: tau_a with Theta_a = thetabar) are set from the others, plus the
!>    constraint forces with their index-1 multipliers (g1);
!>  - the projection after a step: positions back onto g = 0, then the momenta onto every
!>    conserved momentum component and every hidden constraint dg/dt = 0 at once (the least
!>    change of p: p <- p - G (G^T G)^-1 r for the conditions' gradients G, one a column, and
!>    residuals r), then the slaved entries again. Only positions and momenta move (and slaved
!>    entries), so in entropy variables the entropy of the free subsystems is untouched.
module constrained_flow
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use model_interface, only: generic_model
  use model_constraint, only: constraint_slot
  use number_text, only: scientific_text
  implicit none (type, external)
  private
  public :: constrained_field, project_state, bath_temperature_of, initial_inconsistency, slaved_entries

contains

  !> F(z) = f(sigma(z)) + N lambda and optionally dF/dz; multipliers(k): constraint k's lambda.
  !> stat /= failure_none outside the model's domain.
  pure subroutine constrained_field(model, constraints, z, f, stat, jacobian, multipliers)
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z(:)
    real(real64), intent(out) :: f(:)
    integer, intent(out) :: stat
    real(real64), intent(out), optional :: jacobian(:, :), multipliers(:)
    ! The n x n work arrays are allocated (1000 unknowns: 8 MB each, beyond a default stack) and
    ! only where constraints need them.
    real(real64), allocatable :: chain(:, :), df(:, :)
    real(real64) :: w(size(z)), lambda
    integer :: k

    if (size(constraints) == 0) then
      call model%continuous_field(z, f, stat, jacobian)
      return
    end if
    w = z
    if (present(jacobian)) then
      chain = identity(size(z))
      allocate (df(size(z), size(z)))
    end if
    do k = 1, size(constraints)
      if (present(jacobian)) then
        call constraints(k)%item%slave_state(model, w, stat, chain)
      else
        call constraints(k)%item%slave_state(model, w, stat)
      end if
      if (stat /= failure_none) return
    end do
    if (present(jacobian)) then
      call model%continuous_field(w, f, stat, df)
    else
      call model%continuous_field(w, f, stat)
    end if
    if (stat /= failure_none) return
    do k = 1, size(constraints)
      if (present(jacobian)) then
        call constraints(k)%item%add_force(model, w, f, lambda, df)
      else
        call constraints(k)%item%add_force(model, w, f, lambda)
      end if
      if (present(multipliers)) multipliers(k) = lambda
    end do
    if (present(jacobian)) jacobian = matmul(df, chain)
  end subroutine constrained_field

  !> The entries of z that the constraints' continuous forms slave to the others (g2: tau_a, set
  !> from Theta_a = thetabar): their rate is not the field's but follows from the others'.
  pure function slaved_entries(model, constraints, z) result(slaved)
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z(:)
    logical :: slaved(size(z))
    real(real64), allocatable :: chain(:, :)
    real(real64) :: w(size(z))
    integer :: k, i, stat

    slaved = .false.
    if (size(constraints) == 0) return
    w = z
    chain = identity(size(z))
    ! A slaved entry's row of the chain rule no longer depends on the entry itself.
    do k = 1, size(constraints)
      call constraints(k)%item%slave_state(model, w, stat, chain)
    end do
    do i = 1, size(z)
      slaved(i) = abs(chain(i, i)) < 0.5_real64
    end do
  end function slaved_entries

  ! The n x n identity.
  pure function identity(n) result(unit)
    integer, intent(in) :: n
    real(real64), allocatable :: unit(:, :)
    integer :: i

    allocate (unit(n, n), source=0.0_real64)
    do i = 1, n
      unit(i, i) = 1.0_real64
    end do
  end function identity

  !> z back onto the constraints and the conserved momentum components' values `momenta` (the
  !> model's conserved_momenta; see above); stat: a domain code if a slaved entry has no value.
  !> The least change solves G^T dp = -r by Gram-Schmidt on G's columns: a condition whose
  !> gradient depends on the others' (to sqrt(eps) of its length) is implied by them and left
  !> out, as J along the line of a straight pendulum, zero whatever p (its gradient is then 0).
  subroutine project_state(model, constraints, momenta, z, stat)
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: momenta(:)
    real(real64), intent(inout) :: z(:)
    integer, intent(out) :: stat
    real(real64) :: gradients(size(z), size(momenta) + size(constraints)), residuals(size(momenta) + size(constraints))
    real(real64) :: basis(size(z), size(momenta) + size(constraints)), coefficients(size(momenta) + size(constraints))
    real(real64) :: w(size(z)), r, overlap, length
    integer :: k, j, i, m, kept
    logical :: has

    stat = failure_none
    do k = 1, size(constraints)
      call constraints(k)%item%project_positions(model, z)
    end do
    ! The conditions linear in the momenta at the new positions: each conserved component's value
    ! (J.a = momenta(k)), c_k = 0.
    m = size(momenta)
    if (m > 0) then
      gradients(:, 1:m) = model%conserved_momenta_gradient(z)
      residuals(1:m) = model%conserved_momenta(z) - momenta
    end if
    do k = 1, size(constraints)
      call constraints(k)%item%momentum_condition(model, z, has, residuals(m + 1), gradients(:, m + 1))
      if (has) m = m + 1
    end do
    ! G = Q R column by column, and R^T y = r by forward substitution as it goes: dz = -Q y.
    kept = 0
    do j = 1, m
      w = gradients(:, j)
      r = residuals(j)
      do i = 1, kept
        overlap = dot_product(basis(:, i), w)
        w = w - overlap*basis(:, i)
        r = r - overlap*coefficients(i)
      end do
      length = norm2(w)
      if (.not. (length > sqrt(epsilon(1.0_real64))*norm2(gradients(:, j)))) cycle
      kept = kept + 1
      basis(:, kept) = w/length
      coefficients(kept) = r/length
    end do
    if (kept > 0) z = z - matmul(basis(:, 1:kept), coefficients(1:kept))
    do k = 1, size(constraints)
      call constraints(k)%item%slave_state(model, z, stat)
      if (stat /= failure_none) return
    end do
  end subroutine project_state

  !> The temperature of the heat bath of the constraints [K], 0 for a closed system.
  pure real(real64) function bath_temperature_of(constraints)
    type(constraint_slot), intent(in) :: constraints(:)
    integer :: k

    bath_temperature_of = 0.0_real64
    do k = 1, size(constraints)
      bath_temperature_of = max(bath_temperature_of, constraints(k)%item%bath_temperature())
    end do
  end function bath_temperature_of

  !> Why z0 cannot start the constrained continuous flow ('' if it can), with the nearest state
  !> that can (the projection above, which keeps the conserved momenta), column by column.
  function initial_inconsistency(model, constraints, z0) result(text)
    class(generic_model), intent(in) :: model
    type(constraint_slot), intent(in) :: constraints(:)
    real(real64), intent(in) :: z0(:)
    character(len=:), allocatable :: text
    real(real64) :: z(size(z0))
    integer :: k, stat
    character(len=:), allocatable :: changes

    text = ''
    do k = 1, size(constraints)
      text = text//constraints(k)%item%inconsistency(model, z0)
    end do
    if (len(text) == 0) return
    z = z0
    call project_state(model, constraints, model%conserved_momenta(z0), z, stat)
    if (stat /= failure_none) return
    changes = ''
    do k = 1, size(z)
      if (abs(z(k) - z0(k)) > 0.0_real64) changes = changes//', '//trim(model%column_names(k))//' = '//scientific_text(z(k))
    end do
    if (model%conserved_count() > 0) then
      text = text//'; the nearest state that satisfies it with the same conserved momenta has '//changes(3:)
    else
      text = text//'; the nearest state that satisfies it has '//changes(3:)
    end if
  end function initial_inconsistency

end module constrained_flow
