!> Final assembly of a Jacobian that a callback wrote straight into a dense matrix's array, and
!> of the operator too when PETSc passes a different one: what PETSc requires after
!> MatDenseRestoreArray in the SNES and TS Jacobian callbacks.
module dense_assembly
#include <petsc/finclude/petscmat.h>
  use petscmat
  implicit none
  private
  public :: assemble_jacobian

contains

  !> MAT_FINAL_ASSEMBLY of `preconditioner`, and of `jacobian` if it is another matrix.
  subroutine assemble_jacobian(jacobian, preconditioner, ierr)
    Mat, intent(in) :: jacobian, preconditioner
    PetscErrorCode, intent(out) :: ierr

    PetscCall(MatAssemblyBegin(preconditioner, MAT_FINAL_ASSEMBLY, ierr))
    PetscCall(MatAssemblyEnd(preconditioner, MAT_FINAL_ASSEMBLY, ierr))
    if (jacobian /= preconditioner) then
      PetscCall(MatAssemblyBegin(jacobian, MAT_FINAL_ASSEMBLY, ierr))
      PetscCall(MatAssemblyEnd(jacobian, MAT_FINAL_ASSEMBLY, ierr))
    end if
  end subroutine assemble_jacobian

end module dense_assembly
