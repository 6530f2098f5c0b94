/* The model's domain check for PETSc TS stages (TSSetFunctionDomainError), for ts_integrator.
 * PETSc 3.18 calls a domain check with C arguments (TS, PetscReal, Vec, PetscBool *), which a
 * Fortran procedure cannot receive as PETSc objects; this shim receives them and hands the
 * stage's values to a Fortran bind(C) function. A rejected stage makes the TS reject the step:
 * an adaptive method retries it with a smaller step, a fixed-step one (no rejections allowed)
 * stops with TS_DIVERGED_STEP_REJECTED. */
#include <petscts.h>

/* Returns 1 when the state (n values) lies in the model's domain, 0 otherwise. */
typedef int (*eme_state_check)(const double *state, int n, void *context);

typedef struct {
    eme_state_check inside;
    void *context;
} eme_domain_check;

static const char eme_domain_key[] = "eme_domain_check";

static PetscErrorCode stage_in_domain(TS ts, PetscReal time, Vec state, PetscBool *accept)
{
    PetscContainer container;
    eme_domain_check *check;
    const PetscScalar *values;
    PetscInt n;

    (void)time;
    PetscFunctionBeginUser;
    PetscCall(PetscObjectQuery((PetscObject)ts, eme_domain_key, (PetscObject *)&container));
    PetscCheck(container, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONGSTATE, "no domain check attached to the TS");
    PetscCall(PetscContainerGetPointer(container, (void **)&check));
    PetscCall(VecGetLocalSize(state, &n));
    PetscCall(VecGetArrayRead(state, &values));
    *accept = check->inside(values, (int)n, check->context) ? PETSC_TRUE : PETSC_FALSE;
    PetscCall(VecRestoreArrayRead(state, &values));
    PetscFunctionReturn(0);
}

/* Attaches `inside` with its `context` to the TS (from Fortran: the TS by reference, as
 * PETSc's own Fortran interfaces pass it). Returns a PETSc error code. */
PetscErrorCode eme_ts_set_domain_check(TS *ts, eme_state_check inside, void *context)
{
    PetscContainer container;
    eme_domain_check *check;

    PetscFunctionBeginUser;
    PetscCall(PetscNew(&check));
    check->inside = inside;
    check->context = context;
    PetscCall(PetscContainerCreate(PETSC_COMM_SELF, &container));
    PetscCall(PetscContainerSetPointer(container, check));
    PetscCall(PetscContainerSetUserDestroy(container, PetscContainerUserDestroyDefault));
    PetscCall(PetscObjectCompose((PetscObject)*ts, eme_domain_key, (PetscObject)container));
    PetscCall(PetscContainerDestroy(&container));
    PetscCall(TSSetFunctionDomainError(*ts, stage_in_domain));
    PetscFunctionReturn(0);
}
