!> LU factors with partial pivoting of the small dense matrices of one step (9 to 17 unknowns), and
!> their solves. The arithmetic is LAPACK's unblocked dgetf2 and BLAS dtrsv, column by column in
!> the same order, written out as loops the compiler inlines: at this size the reference BLAS
!> calls (idamax, dswap, dscal, dger per column) cost several times the arithmetic
!> (docs/performance.md, "Issue 22's four ratios"). The step solver's shell preconditioner keeps
!> the factors, and its chord predictor reuses them; tests/unit/test_dense_lu.pf checks them
!> against LAPACK's dgesv.
module dense_lu
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: lu_factors

  !> The factors of the last matrix factored, if `ready`.
  type :: lu_factors
    real(real64), allocatable :: factors(:, :)
    integer, allocatable :: pivots(:)
    logical :: ready = .false.
  contains
    procedure :: reset
    procedure :: factor
    procedure :: factor_in_place
    procedure :: solve
    procedure :: as_values
    procedure :: value_count
    procedure :: put_values
    procedure :: from_values
  end type lu_factors

contains

  !> Room for n x n factors, none ready.
  pure subroutine reset(self, n)
    class(lu_factors), intent(inout) :: self
    integer, intent(in) :: n

    if (allocated(self%factors)) deallocate (self%factors, self%pivots)
    allocate (self%factors(n, n), self%pivots(n))
    self%ready = .false.
  end subroutine reset

  !> Factors `matrix`; info /= 0 for a zero pivot (then no factors are ready).
  subroutine factor(self, matrix, info)
    class(lu_factors), intent(inout) :: self
    real(real64), intent(in) :: matrix(:, :)
    integer, intent(out) :: info

    self%factors = matrix
    call self%factor_in_place(info)
  end subroutine factor

  !> Factors the matrix a caller wrote into `factors` (saves a copy); info as `factor`.
  pure subroutine factor_in_place(self, info)
    class(lu_factors), intent(inout) :: self
    integer, intent(out) :: info

    call factor_pivoted(size(self%pivots), self%factors, self%pivots, info)
    self%ready = info == 0
  end subroutine factor_in_place

  !> A = P L U in place (L unit lower, U upper), as LAPACK's dgetf2: column k's pivot is its
  !> largest entry in magnitude at or below the diagonal, whose row is swapped into row k; the
  !> column below the pivot is scaled by the pivot's reciprocal and the rank-1 update applied
  !> column by column. info = k > 0 if the k-th pivot is zero (the factors are then incomplete).
  pure subroutine factor_pivoted(n, a, pivots, info)
    integer, intent(in) :: n
    real(real64), intent(inout) :: a(n, n)
    integer, intent(out) :: pivots(n)
    integer, intent(out) :: info
    real(real64) :: swapped, reciprocal, largest, multiplier
    integer :: k, i, j, p

    info = 0
    do k = 1, n
      p = k
      largest = abs(a(k, k))
      do i = k + 1, n
        if (abs(a(i, k)) > largest) then
          p = i
          largest = abs(a(i, k))
        end if
      end do
      pivots(k) = p
      if (.not. (largest > 0.0_real64)) then
        if (info == 0) info = k
        cycle
      end if
      if (p /= k) then
        do j = 1, n
          swapped = a(k, j)
          a(k, j) = a(p, j)
          a(p, j) = swapped
        end do
      end if
      reciprocal = 1.0_real64/a(k, k)
      do i = k + 1, n
        a(i, k) = a(i, k)*reciprocal
      end do
      do j = k + 1, n
        multiplier = a(k, j)
        do i = k + 1, n
          a(i, j) = a(i, j) - a(i, k)*multiplier
        end do
      end do
    end do
  end subroutine factor_pivoted

  !> The factors as numbers, for a continued run (from_values takes them back, bit for bit):
  !> whether they are ready (1 or 0), their order m, the m*m factors by columns and the m pivots;
  !> [0, 0] when none are ready.
  pure function as_values(self) result(values)
    class(lu_factors), intent(in) :: self
    real(real64), allocatable :: values(:)

    allocate (values(self%value_count()))
    call self%put_values(values)
  end function as_values

  !> The number of as_values' numbers.
  pure integer function value_count(self)
    class(lu_factors), intent(in) :: self

    value_count = 2
    if (self%ready) value_count = 2 + size(self%pivots)*(size(self%pivots) + 1)
  end function value_count

  !> as_values into `values` (of value_count numbers): a caller that keeps its array allocates nothing.
  pure subroutine put_values(self, values)
    class(lu_factors), intent(in) :: self
    real(real64), intent(out) :: values(:)
    integer :: m, j

    values(1:2) = 0.0_real64
    if (.not. self%ready) return
    m = size(self%pivots)
    values(1:2) = [1.0_real64, real(m, real64)]
    do j = 1, m
      values(3 + (j - 1)*m:2 + j*m) = self%factors(:, j)
    end do
    values(3 + m*m:) = real(self%pivots, real64)
  end subroutine put_values

  !> Takes back what as_values gave. Factors of another order than n (another system) are not
  !> taken: then none are ready. ok = .false. if `values` are not as_values' layout.
  pure subroutine from_values(self, values, n, ok)
    class(lu_factors), intent(inout) :: self
    real(real64), intent(in) :: values(:)
    integer, intent(in) :: n
    logical, intent(out) :: ok
    integer :: m

    self%ready = .false.
    ok = .false.
    if (size(values) < 2) return
    m = nint(values(2))
    if (nint(values(1)) == 0) then
      ok = size(values) == 2
      return
    end if
    if (m < 1 .or. size(values) /= 2 + m*m + m) return
    ok = .true.
    if (m /= n) return
    call self%reset(n)
    self%factors = reshape(values(3:2 + m*m), [m, m])
    self%pivots = nint(values(3 + m*m:))
    self%ready = .true.
  end subroutine from_values

  !> b := A^-1 b with the factors, as LAPACK's dgetrs for one right-hand side.
  pure subroutine solve(self, b, info)
    class(lu_factors), intent(in) :: self
    real(real64), intent(inout) :: b(:)
    integer, intent(out) :: info

    call solve_pivoted(size(self%pivots), self%factors, self%pivots, b)
    info = 0
  end subroutine solve

  !> The row interchanges of the factorization applied to b, then L y = P b forward and U x = y
  !> backward, column by column (BLAS dtrsv's order).
  pure subroutine solve_pivoted(n, a, pivots, b)
    integer, intent(in) :: n
    real(real64), intent(in) :: a(n, n)
    integer, intent(in) :: pivots(n)
    real(real64), intent(inout) :: b(n)
    real(real64) :: swapped
    integer :: k, i, p

    do k = 1, n
      p = pivots(k)
      if (p /= k) then
        swapped = b(k)
        b(k) = b(p)
        b(p) = swapped
      end if
    end do
    do k = 1, n - 1
      do i = k + 1, n
        b(i) = b(i) - b(k)*a(i, k)
      end do
    end do
    do k = n, 1, -1
      b(k) = b(k)/a(k, k)
      do i = 1, k - 1
        b(i) = b(i) - b(k)*a(i, k)
      end do
    end do
  end subroutine solve_pivoted

end module dense_lu
