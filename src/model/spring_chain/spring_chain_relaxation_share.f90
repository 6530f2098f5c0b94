!> A rank's share of what a relaxed Runge-Kutta step of the split chain sums over the ranks
!> (spring_chain_relaxed_run; docs/integrators.md, "The relaxed family on the split chain"), each
!> from the rank's points of the state, the caller adding the ranks' shares:
!>  - the rounding floor of the relaxation's r(gamma): 8 eps sum_j |z_j| |dE/dz_j| over the
!>    unknowns of the share's points (src/solver/relaxation_root);
!>  - the conserved components of J about the scene's axes a_k (spring_chain_balance's
!>    conserved_axes): J.a_k = sum_i p_i.(a_k x x_i), so their gradients in the momenta are the
!>    columns G_k(i) = a_k x x_i, and the least change of p onto given values is
!>    p <- p - G (G^T G)^-1 r, which needs the Gram matrix G^T G and the residuals r, sums of the
!>    masses' terms; and each spring's tau converted between two thermodynamic variables at the
!>    same temperature (the split relaxed steps run in entropy variables, the run's file holds its
!>    own variable).
module spring_chain_relaxation_share
  use, intrinsic :: iso_fortran_env, only: real64
  use failures, only: failure_none
  use invariant_function, only: potential_u
  use spring_chain_spring, only: chain_spring, spring_invariants
  use spring_chain_partials, only: spring_partials
  use spring_chain_layout, only: chain_layout, slots_of
  use spring_chain_step, only: chain_step_problem
  implicit none (type, external)
  private
  public :: rounding_floor_share, momentum_share, projection_coefficients, project_momenta, converted_taus

contains

  !> sum_j |z_j| |dE/dz_j| over the unknowns of points first..last (`points`) at z, which holds
  !> the unknowns base + 1 .. base + size(z) (the points and two on either side); problem's rule
  !> must give the exact partials (partials_exact). dE/dx_i = -m_i g + 2 r_i dU_i/dC -
  !> 2 r_(i+1) dU_(i+1)/dC (r_a = x_a - x_(a-1)), dE/dp_i = p_i/m_i, and dU_a/dgamma_a, dU_a/dtau_a.
  pure subroutine rounding_floor_share(problem, z, base, points, share, stat)
    type(chain_step_problem), intent(in) :: problem
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: base, points(2)
    real(real64), intent(out) :: share
    integer, intent(out) :: stat
    type(spring_partials), allocatable :: parts(:)
    real(real64) :: force(problem%layout%dimension)
    integer :: i, a, d, n, last_spring

    share = 0.0_real64
    associate (layout => problem%layout)
      d = layout%dimension
      n = layout%invariant_count
      last_spring = min(layout%springs, points(2) + 1)
      allocate (parts(points(1):last_spring))
      call problem%partials_of(z, z, parts, stat, base, points(1))
      if (stat /= failure_none) return
      do i = points(1), min(layout%masses, points(2))
        associate (x => layout%mass_indices(i) - base)
          force = -problem%masses(i)*problem%gravity + 2.0_real64*parts(i)%r(1:d)*parts(i)%partials(1, potential_u)
          if (i + 1 <= last_spring) force = force - 2.0_real64*parts(i + 1)%r(1:d)*parts(i + 1)%partials(1, potential_u)
          share = share + sum(abs(z(x(1:d))*force)) + sum(z(x(d + 1:))**2)/problem%masses(i)
        end associate
      end do
      do a = points(1), min(layout%springs, points(2))
        if (n == 3) share = share + abs(z(layout%gamma_index(a) - base)*parts(a)%partials(2, potential_u))
        if (n >= 2) share = share + abs(z(layout%tau_index(a) - base)*parts(a)%partials(n, potential_u))
      end do
    end associate
  end subroutine rounding_floor_share

  !> The share of masses first..last (`masses`) of the Gram matrix gram(k, l) = G_k.G_l and of
  !> the conserved components values(k) = J.a_k, `axes` (3 x m) the conserved axes; z holds the
  !> unknowns base + 1 .. base + size(z).
  pure subroutine momentum_share(layout, axes, z, base, masses, gram, values)
    type(chain_layout), intent(in) :: layout
    real(real64), intent(in) :: axes(:, :), z(:)
    integer, intent(in) :: base, masses(2)
    real(real64), intent(out) :: gram(size(axes, 2), size(axes, 2)), values(size(axes, 2))
    real(real64) :: columns(layout%dimension, size(axes, 2))
    integer :: i, k, l, d

    d = layout%dimension
    gram = 0.0_real64
    values = 0.0_real64
    do i = masses(1), masses(2)
      associate (x => layout%mass_indices(i) - base)
        columns = gradient_columns(axes, z(x(1:d)))
        do k = 1, size(axes, 2)
          values(k) = values(k) + dot_product(z(x(d + 1:)), columns(:, k))
          do l = 1, size(axes, 2)
            gram(k, l) = gram(k, l) + dot_product(columns(:, k), columns(:, l))
          end do
        end do
      end associate
    end do
  end subroutine momentum_share

  !> y with p <- p - G y the least change of p that makes the conserved components' residuals
  !> r = J.a - J_0 zero: Gram-Schmidt on G's columns through their Gram matrix, as
  !> src/integrator/constrained_flow's project_state does on the columns themselves (a column
  !> whose remainder is below sqrt(eps) of its length is implied by the others and left out).
  pure function projection_coefficients(gram, residuals) result(y)
    real(real64), intent(in) :: gram(:, :), residuals(:)
    real(real64) :: y(size(residuals))
    real(real64) :: basis(size(residuals), size(residuals)), coefficients(size(residuals))
    real(real64) :: w(size(residuals)), r, overlap, length
    integer :: i, j, kept

    kept = 0
    do j = 1, size(residuals)
      ! w in the columns' coordinates: the remainder of column j.
      w = 0.0_real64
      w(j) = 1.0_real64
      r = residuals(j)
      do i = 1, kept
        overlap = dot_product(basis(:, i), matmul(gram, w))
        w = w - overlap*basis(:, i)
        r = r - overlap*coefficients(i)
      end do
      length = sqrt(max(0.0_real64, dot_product(w, matmul(gram, w))))
      if (.not. (length > sqrt(epsilon(1.0_real64))*sqrt(gram(j, j)))) cycle
      kept = kept + 1
      basis(:, kept) = w/length
      coefficients(kept) = r/length
    end do
    y = matmul(basis(:, 1:kept), coefficients(1:kept))
  end function projection_coefficients

  !> p_i <- p_i - sum_k y_k (a_k x x_i) for masses first..last (`masses`); `owned` holds the
  !> unknowns base + 1 .. base + size(owned).
  pure subroutine project_momenta(layout, axes, y, base, masses, owned)
    type(chain_layout), intent(in) :: layout
    real(real64), intent(in) :: axes(:, :), y(:)
    integer, intent(in) :: base, masses(2)
    real(real64), intent(inout) :: owned(:)
    integer :: i, d

    d = layout%dimension
    do i = masses(1), masses(2)
      associate (x => layout%mass_indices(i) - base)
        owned(x(d + 1:)) = owned(x(d + 1:)) - matmul(gradient_columns(axes, owned(x(1:d))), y)
      end associate
    end do
  end subroutine project_momenta

  !> Each spring's tau of springs first..last (`springs`) at z (holding the unknowns base + 1 ..
  !> base + size(z), in the thermodynamic variable of `from`) in the variable of `to`, at the same
  !> temperature and mechanical invariants (docs/formulation.md section 3's closed forms).
  pure subroutine converted_taus(layout, from, to, z, base, springs, taus, stat)
    type(chain_layout), intent(in) :: layout
    type(chain_spring), intent(in) :: from(:), to(:)
    real(real64), intent(in) :: z(:)
    integer, intent(in) :: base, springs(2)
    real(real64), intent(out) :: taus(:)
    integer, intent(out) :: stat
    real(real64) :: x(3), values(2), theta, r(layout%dimension), gamma
    integer :: a, n, d

    n = layout%invariant_count
    d = layout%dimension
    stat = failure_none
    taus = 0.0_real64
    do a = springs(1), springs(2)
      associate (values_at => layout%gather_spring(z, a, base), s => slots_of(d, n))
        r = values_at(s%x_right(1:d)) - values_at(s%x_left(1:d))
        gamma = 0.0_real64
        if (n == 3) gamma = values_at(s%gamma)
        call spring_invariants(r, gamma, values_at(s%tau), n, x(1:n))
      end associate
      call from(a)%values_and_temperature(x(1:n), values, theta, stat)
      if (stat /= failure_none) return
      call to(a)%tau_from_temperature(x(1:n - 1), theta, taus(a - springs(1) + 1), stat)
      if (stat /= failure_none) return
    end do
  end subroutine converted_taus

  ! The columns a_k x x of the gradients of J.a_k in p_i at the position x (`dimension`
  ! components), as many as the axes.
  pure function gradient_columns(axes, x) result(columns)
    real(real64), intent(in) :: axes(:, :), x(:)
    real(real64) :: columns(size(x), size(axes, 2))
    real(real64) :: x3(3), column(3)
    integer :: k

    x3 = 0.0_real64
    x3(1:size(x)) = x
    do k = 1, size(axes, 2)
      associate (a => axes(:, k))
        column = [a(2)*x3(3) - a(3)*x3(2), a(3)*x3(1) - a(1)*x3(3), a(1)*x3(2) - a(2)*x3(1)]
      end associate
      columns(:, k) = column(1:size(x))
    end do
  end function gradient_columns

end module spring_chain_relaxation_share
