/* A dense PETSc matrix's values read through the read-only accessor, for the LU shell
 * preconditioner (src/solver/snes_solver). Restoring the array that MatDenseGetArrayF90 lends
 * bumps the matrix's state, so PCSetUp would see a new operator and factor it a second time in the
 * same Newton iteration; MatDenseGetArrayRead leaves the state alone. PETSc 3.18 has no Fortran
 * MatDenseGetArrayReadF90. */
#include <petscmat.h>
#include <string.h>

/* Copies the n x n matrix *A (column-major, n = its rows) into values(n, n). The matrix comes
 * from Fortran by reference, as PETSc's own Fortran interfaces pass it. */
PetscErrorCode eme_dense_read(Mat *A, PetscScalar *values)
{
    const PetscScalar *array;
    PetscInt n, columns, lda, j;

    PetscFunctionBeginUser;
    PetscCall(MatGetSize(*A, &n, &columns));
    PetscCall(MatDenseGetLDA(*A, &lda));
    PetscCall(MatDenseGetArrayRead(*A, &array));
    for (j = 0; j < columns; j++) memcpy(values + j * n, array + j * lda, (size_t)n * sizeof(PetscScalar));
    PetscCall(MatDenseRestoreArrayRead(*A, &array));
    PetscFunctionReturn(0);
}
