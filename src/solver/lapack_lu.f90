!> Interfaces to LAPACK's LU factorization and solve, for the step's small dense Jacobian
!> (the solver's shell preconditioner and the benchmark's floor share them).
module lapack_lu
  use, intrinsic :: iso_fortran_env, only: real64
  implicit none (type, external)
  private
  public :: dgetf2, dgetrs

  interface
    !> LU factorization with partial pivoting, unblocked: A = P L U.
    subroutine dgetf2(m, n, a, lda, ipiv, info)
      import :: real64
      integer, intent(in) :: m, n, lda
      real(real64), intent(inout) :: a(lda, *)
      integer, intent(out) :: ipiv(*), info
    end subroutine dgetf2
    !> Solves A X = B (trans = 'N') with the factors of dgetf2.
    subroutine dgetrs(trans, n, nrhs, a, lda, ipiv, b, ldb, info)
      import :: real64
      character, intent(in) :: trans
      integer, intent(in) :: n, nrhs, lda, ldb, ipiv(*)
      real(real64), intent(in) :: a(lda, *)
      real(real64), intent(inout) :: b(ldb, *)
      integer, intent(out) :: info
    end subroutine dgetrs
  end interface

end module lapack_lu
