/* A PETSc vector's entries lent as a C pointer, for vector_arrays (src/solver/vector_arrays.f90),
 * which maps it onto a Fortran array for the SNES callbacks. PETSc's Fortran accessors
 * (VecGetArrayF90, VecGetArrayReadF90 and their restores) build and free a Fortran array
 * descriptor on every call: on these 9-unknown systems that was about 4,800 instructions per
 * step, 7 % of the SNES step (docs/performance.md, "Issue 22's four ratios"). The vector comes
 * from Fortran by reference, as PETSc's own Fortran interfaces pass it. */
#include <petscvec.h>

PetscErrorCode eme_vec_get_array(Vec *v, PetscScalar **values)
{
    return VecGetArray(*v, values);
}

PetscErrorCode eme_vec_restore_array(Vec *v, PetscScalar **values)
{
    return VecRestoreArray(*v, values);
}

PetscErrorCode eme_vec_get_array_read(Vec *v, const PetscScalar **values)
{
    return VecGetArrayRead(*v, values);
}

PetscErrorCode eme_vec_restore_array_read(Vec *v, const PetscScalar **values)
{
    return VecRestoreArrayRead(*v, values);
}
