!> A PETSc shell preconditioner that solves exactly with the LU factors of the operator it is
!> given (src/solver/dense_lu): set-up factors the dense matrix, apply back-substitutes. A zero
!> pivot fails the preconditioner, which fails the linear solve and so the Newton solve.
module lu_preconditioner
#include <petsc/finclude/petscksp.h>
  use petscksp
  use, intrinsic :: iso_fortran_env, only: real64
  use dense_lu, only: lu_factors
  implicit none
  private
  public :: use_lu_shell

  ! PETSc needs these interfaces to pass a Fortran derived type as a shell's context.
  interface
    subroutine PCShellSetContext(pc, context, ierr)
      import :: tPC, lu_factors
      PC, intent(in) :: pc
      type(lu_factors), intent(in) :: context
      PetscErrorCode, intent(out) :: ierr
    end subroutine PCShellSetContext
    subroutine PCShellGetContext(pc, context, ierr)
      import :: tPC, lu_factors
      PC, intent(in) :: pc
      type(lu_factors), pointer, intent(out) :: context
      PetscErrorCode, intent(out) :: ierr
    end subroutine PCShellGetContext
  end interface

contains

  !> Makes `pc` a shell that factors into `lu` (which must stay at its address).
  subroutine use_lu_shell(pc, lu, ierr)
    PC, intent(in) :: pc
    type(lu_factors), intent(in), target :: lu
    PetscErrorCode, intent(out) :: ierr

    PetscCall(PCSetType(pc, PCSHELL, ierr))
    PetscCall(PCShellSetContext(pc, lu, ierr))
    PetscCall(PCShellSetSetUp(pc, factor_operator, ierr))
    PetscCall(PCShellSetApply(pc, solve_factored, ierr))
    PetscCall(PCShellSetName(pc, 'dense LU by LAPACK dgetf2 and dgetrs', ierr))
  end subroutine use_lu_shell

  ! Shell set-up: factor the new matrix. PETSc keeps a failure reason until told otherwise, so
  ! a good factorization clears it.
  subroutine factor_operator(pc, ierr)
    PC, intent(in) :: pc
    PetscErrorCode, intent(out) :: ierr
    type(lu_factors), pointer :: lu
    Mat :: operator, preconditioner
    PetscScalar, pointer :: entries(:, :)
    integer :: info

    PetscCall(PCShellGetContext(pc, lu, ierr))
    PetscCall(PCGetOperators(pc, operator, preconditioner, ierr))
    PetscCall(MatDenseGetArrayF90(preconditioner, entries, ierr))
    call lu%factor(entries, info)
    PetscCall(MatDenseRestoreArrayF90(preconditioner, entries, ierr))
    if (info /= 0) then
      PetscCall(PCSetFailedReason(pc, PC_FACTOR_NUMERIC_ZEROPIVOT, ierr))
    else
      PetscCall(PCSetFailedReason(pc, PC_NOERROR, ierr))
    end if
  end subroutine factor_operator

  ! Shell application: y = A^-1 x from the factors.
  subroutine solve_factored(pc, x, y, ierr)
    PC, intent(in) :: pc
    Vec, intent(in) :: x
    Vec, intent(in) :: y
    PetscErrorCode, intent(out) :: ierr
    type(lu_factors), pointer :: lu
    PetscScalar, pointer :: x_values(:), y_values(:)
    integer :: info

    PetscCall(PCShellGetContext(pc, lu, ierr))
    PetscCall(VecGetArrayReadF90(x, x_values, ierr))
    PetscCall(VecGetArrayF90(y, y_values, ierr))
    y_values = x_values
    call lu%solve(y_values, info)
    PetscCall(VecRestoreArrayF90(y, y_values, ierr))
    PetscCall(VecRestoreArrayReadF90(x, x_values, ierr))
    if (info /= 0) then
      PetscCall(PCSetFailedReason(pc, PC_SUBPC_ERROR, ierr))
    end if
  end subroutine solve_factored

end module lu_preconditioner
