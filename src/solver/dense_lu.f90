!> LU factors of a small dense matrix by LAPACK: dgetf2 (unblocked; for 9 to 17 unknowns it
!> costs half of the blocked dgetrf that PETSc's dense LU calls, docs/performance.md), and the
!> solves of dgetrs by its parts (dlaswp, two dtrsv).
!> The step solver's shell preconditioner keeps them, and its chord predictor reuses them.
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
  end type lu_factors

  interface
    !> LU factorization with partial pivoting, unblocked: A = P L U.
    subroutine dgetf2(m, n, a, lda, ipiv, info)
      import :: real64
      integer, intent(in) :: m, n, lda
      real(real64), intent(inout) :: a(lda, *)
      integer, intent(out) :: ipiv(*), info
    end subroutine dgetf2
    !> The row interchanges of the factorization applied to x (LAPACK).
    subroutine dlaswp(n, a, lda, k1, k2, ipiv, incx)
      import :: real64
      integer, intent(in) :: n, lda, k1, k2, ipiv(*), incx
      real(real64), intent(inout) :: a(lda, *)
    end subroutine dlaswp
    !> x := A^-1 x for a triangular A (BLAS level 2).
    subroutine dtrsv(uplo, trans, diag, n, a, lda, x, incx)
      import :: real64
      character, intent(in) :: uplo, trans, diag
      integer, intent(in) :: n, lda, incx
      real(real64), intent(in) :: a(lda, *)
      real(real64), intent(inout) :: x(*)
    end subroutine dtrsv
  end interface

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
  subroutine factor_in_place(self, info)
    class(lu_factors), intent(inout) :: self
    integer, intent(out) :: info
    integer :: n

    n = size(self%pivots)
    call dgetf2(n, n, self%factors, n, self%pivots, info)
    self%ready = info == 0
  end subroutine factor_in_place

  !> b := A^-1 b with the factors: what dgetrs does for one right-hand side, by the level-2 BLAS
  !> triangular solves (dgetrs calls the level-3 dtrsm, whose overhead dominates at this size).
  subroutine solve(self, b, info)
    class(lu_factors), intent(in) :: self
    real(real64), intent(inout) :: b(:)
    integer, intent(out) :: info
    integer :: n

    n = size(self%pivots)
    call dlaswp(1, b, n, 1, n, self%pivots, 1)
    call dtrsv('L', 'N', 'U', n, self%factors, n, b, 1)
    call dtrsv('U', 'N', 'N', n, self%factors, n, b, 1)
    info = 0
  end subroutine solve

end module dense_lu
