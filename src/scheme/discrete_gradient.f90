!> Discrete gradients D f(a, b) of functions of a spring's invariants (docs/formulation.md section 5).
!> Both satisfy the directionality condition D f . (b - a) = f(b) - f(a) and tend to grad f
!> as b -> a. Each also returns its exact Jacobian d(D f)/db for Newton's method.
!>  - Gonzalez [1]: D f = grad f(m) + (f(b) - f(a) - grad f(m).d) / (d.W d) W d, with
!>    m = (a + b)/2, d = b - a, and W = diag(1/scale^2), the nondimensional metric.
!>  - partitioned: the symmetrized coordinate increment. D_i f averages the one-variable
!>    difference quotients in x_i over all orderings of the variables; for n variables the
!>    quotient with the set P of other variables already at b has weight |P|! (n-1-|P|)! / n!.
!> The quotient's numerator f(b) - f(a) - grad f(m).d is O(|d|^3); the invariant functions give
!> f(b) - f(a) free of cancellation (to eps |f(b) - f(a)|), so the quotient keeps a rounding error
!> of about eps |grad f| at any |d|. Only below `quotient_threshold` (nondimensional, eps^(2/3):
!> there the fallback's directionality error |d|^3 f''' is below eps^2 |f'''|) does the exact
!> derivative at the midpoint replace it; the Jacobian follows the branch taken. (At eps^(1/3)
!> the fallback's error was not round-off where f''' is large: a spring compressed to 7 % of its
!> length lost 2e-11 J a step at dt = 3e-4 s.)
module discrete_gradient
  use, intrinsic :: iso_fortran_env, only: real64
  use invariant_function, only: invariant_functions
  implicit none (type, external)
  private
  public :: gradient_gonzalez, gradient_partitioned, discrete_gradient_names
  public :: metric_nondimensional, metric_euclidean, metric_names
  public :: quotient_threshold, discrete_gradient_of, gonzalez_from_parts

  integer, parameter :: gradient_gonzalez = 1
  integer, parameter :: gradient_partitioned = 2
  character(len=*), parameter :: discrete_gradient_names(2) = [character(len=11) :: 'gonzalez', 'partitioned']

  !> The metric of Gonzalez's quotient: scaled by typical sizes (the default), or raw units.
  integer, parameter :: metric_nondimensional = 1
  integer, parameter :: metric_euclidean = 2
  character(len=*), parameter :: metric_names(2) = [character(len=14) :: 'nondimensional', 'euclidean']

  real(real64), parameter :: quotient_threshold = epsilon(1.0_real64)**(2.0_real64/3.0_real64)

contains

  !> D f(a, b) by the discrete gradient `kind`; ddg_db(i, l, j) = d(dg(i, j))/d b(l).
  pure subroutine discrete_gradient_of(kind, fun, a, b, scale, dg, ddg_db, fallback, stat)
    integer, intent(in) :: kind
    class(invariant_functions), intent(in) :: fun
    real(real64), intent(in) :: a(:), b(:), scale(:)
    real(real64), intent(out) :: dg(:, :)
    real(real64), intent(out), optional :: ddg_db(:, :, :)
    logical, intent(out), optional :: fallback
    integer, intent(out) :: stat

    select case (kind)
    case (gradient_partitioned)
      call partitioned_gradient(fun, a, b, scale, dg, ddg_db, fallback, stat)
    case default
      call gonzalez_gradient(fun, a, b, scale, dg, ddg_db, fallback, stat)
    end select
  end subroutine discrete_gradient_of

  !> Gonzalez's discrete gradient in the metric W = diag(1/scale^2).
  pure subroutine gonzalez_gradient(fun, a, b, scale, dg, ddg_db, fallback, stat)
    class(invariant_functions), intent(in) :: fun
    real(real64), intent(in) :: a(:), b(:), scale(:)
    real(real64), intent(out) :: dg(:, :)
    real(real64), intent(out), optional :: ddg_db(:, :, :)
    logical, intent(out), optional :: fallback
    integer, intent(out) :: stat

    real(real64) :: d(size(a)), weight(size(a)), dwd
    real(real64) :: delta_f(size(dg, 2)), f_b(size(dg, 2)), f_m(size(dg, 2)), grad_b(size(a), size(dg, 2))
    real(real64) :: grad_m(size(a), size(dg, 2)), hess_m(size(a), size(a), size(dg, 2))
    logical :: small

    d = b - a
    weight = 1.0_real64/scale**2
    dwd = dot_product(d, weight*d)
    small = sqrt(dwd) < quotient_threshold
    if (present(fallback)) fallback = small

    if (present(ddg_db)) then
      call fun%evaluate(0.5_real64*(a + b), f_m, grad_m, hess_m, stat)
    else
      call fun%evaluate(0.5_real64*(a + b), f_m, grad_m, stat=stat)
    end if
    if (stat /= 0) return
    dg = grad_m
    if (present(ddg_db)) ddg_db = 0.5_real64*hess_m
    if (small) return

    call fun%difference(a, b, delta_f, stat)
    if (stat /= 0) return
    if (present(ddg_db)) then
      call fun%evaluate(b, f_b, grad_b, stat=stat)
      if (stat /= 0) return
      call gonzalez_from_parts(d, weight, dwd, grad_m, delta_f, dg, hess_m, grad_b, ddg_db)
    else
      call gonzalez_from_parts(d, weight, dwd, grad_m, delta_f, dg)
    end if
  end subroutine gonzalez_gradient

  !> Gonzalez's quotient above the threshold from its parts: d = b - a, the metric's weights W,
  !> dwd = d.W d, grad f at the midpoint and f(b) - f(a); for its Jacobian also the Hessian at the
  !> midpoint and grad f(b) (all three or none). The fused step kernel (src/scheme/
  !> pendulum_step_kernel) computes the parts itself and shares them. n = size(d) variables: the
  !> matrices' first n rows (and hess_m's and ddg_db's first n columns) are read and written, so a
  !> caller may pass whole arrays of a larger leading dimension (contiguous, never packed).
  pure subroutine gonzalez_from_parts(d, weight, dwd, grad_m, delta_f, dg, hess_m, grad_b, ddg_db)
    real(real64), intent(in), contiguous :: d(:), weight(:), grad_m(:, :), delta_f(:)
    real(real64), intent(in) :: dwd
    real(real64), intent(out), contiguous :: dg(:, :)
    real(real64), intent(in), optional, contiguous :: hess_m(:, :, :), grad_b(:, :)
    real(real64), intent(out), optional, contiguous :: ddg_db(:, :, :)
    real(real64) :: wd(size(d)), coefficient, dc_db(size(d)), inv_dwd, hess_d
    integer :: j, l, i, n

    n = size(d)
    inv_dwd = 1.0_real64/dwd
    wd = weight*d
    do j = 1, size(dg, 2)
      coefficient = delta_f(j)
      do i = 1, n
        coefficient = coefficient - grad_m(i, j)*d(i)
      end do
      coefficient = coefficient*inv_dwd
      do i = 1, n
        dg(i, j) = grad_m(i, j) + coefficient*wd(i)
      end do
      if (present(ddg_db)) then
        do l = 1, n
          hess_d = 0.0_real64
          do i = 1, n
            hess_d = hess_d + hess_m(l, i, j)*d(i)
          end do
          dc_db(l) = (grad_b(l, j) - grad_m(l, j) - 0.5_real64*hess_d - 2.0_real64*coefficient*wd(l))*inv_dwd
        end do
        do l = 1, n
          do i = 1, n
            ddg_db(i, l, j) = 0.5_real64*hess_m(i, l, j) + wd(i)*dc_db(l)
          end do
          ddg_db(l, l, j) = ddg_db(l, l, j) + coefficient*weight(l)
        end do
      end if
    end do
  end subroutine gonzalez_from_parts

  !> The symmetrized coordinate-increment (partitioned) discrete gradient, n <= 3 variables.
  pure subroutine partitioned_gradient(fun, a, b, scale, dg, ddg_db, fallback, stat)
    class(invariant_functions), intent(in) :: fun
    real(real64), intent(in) :: a(:), b(:), scale(:)
    real(real64), intent(out) :: dg(:, :)
    real(real64), intent(out), optional :: ddg_db(:, :, :)
    logical, intent(out), optional :: fallback
    integer, intent(out) :: stat

    integer, parameter :: max_corners = 8
    real(real64) :: f_corner(size(dg, 2), 0:max_corners - 1)
    real(real64) :: grad_corner(size(a), size(dg, 2), 0:max_corners - 1)
    real(real64) :: f_x(size(dg, 2)), grad_x(size(a), size(dg, 2)), hess_x(size(a), size(a), size(dg, 2))
    real(real64) :: x(size(a)), quotient(size(dg, 2)), increment, w
    integer :: n, corner, i, l, others, lo, hi
    logical :: any_fallback

    n = size(a)
    any_fallback = .false.
    dg = 0.0_real64
    if (present(ddg_db)) ddg_db = 0.0_real64

    ! f and grad f at every corner; bit i-1 of the corner's number set means x_i = b_i.
    do corner = 0, 2**n - 1
      call fun%evaluate(corner_point(corner), f_corner(:, corner), grad_corner(:, :, corner), stat=stat)
      if (stat /= 0) return
    end do

    do i = 1, n
      increment = b(i) - a(i)
      do others = 0, 2**n - 1
        if (btest(others, i - 1)) cycle
        lo = others
        hi = ibset(others, i - 1)
        w = ordering_weight(popcnt(others), n)
        if (abs(increment)/scale(i) >= quotient_threshold) then
          call fun%difference(corner_point(lo), corner_point(hi), quotient, stat)
          if (stat /= 0) return
          quotient = quotient/increment
          dg(i, :) = dg(i, :) + w*quotient
          if (present(ddg_db)) then
            ddg_db(i, i, :) = ddg_db(i, i, :) + w*(grad_corner(i, :, hi) - quotient)/increment
            do l = 1, n
              if (btest(others, l - 1)) ddg_db(i, l, :) = ddg_db(i, l, :) &
                + w*(grad_corner(l, :, hi) - grad_corner(l, :, lo))/increment
            end do
          end if
        else
          any_fallback = .true.
          x = corner_point(lo)
          x(i) = 0.5_real64*(a(i) + b(i))
          call fun%evaluate(x, f_x, grad_x, hess_x, stat)
          if (stat /= 0) return
          dg(i, :) = dg(i, :) + w*grad_x(i, :)
          if (present(ddg_db)) then
            ddg_db(i, i, :) = ddg_db(i, i, :) + 0.5_real64*w*hess_x(i, i, :)
            do l = 1, n
              if (btest(others, l - 1)) ddg_db(i, l, :) = ddg_db(i, l, :) + w*hess_x(i, l, :)
            end do
          end if
        end if
      end do
    end do
    if (present(fallback)) fallback = any_fallback

  contains

    pure function corner_point(bits) result(point)
      integer, intent(in) :: bits
      real(real64) :: point(size(a))
      integer :: m

      do m = 1, size(a)
        if (btest(bits, m - 1)) then
          point(m) = b(m)
        else
          point(m) = a(m)
        end if
      end do
    end function corner_point
  end subroutine partitioned_gradient

  ! Share of the orderings of n variables in which exactly `before` others precede a given one.
  pure function ordering_weight(before, n) result(w)
    integer, intent(in) :: before, n
    real(real64) :: w

    w = gamma(real(before + 1, real64))*gamma(real(n - before, real64))/gamma(real(n + 1, real64))
  end function ordering_weight

end module discrete_gradient
