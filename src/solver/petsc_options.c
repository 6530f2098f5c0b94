/* The step solver's own options, registered with PETSc's options database so that `-help` lists
 * them with their descriptions (PETSc 3.18 has no Fortran PetscOptionsBegin/PetscOptionsBool),
 * and a scan of the options a user gave, by part of their name (PETSc's options database has no
 * prefix query). For src/solver/solver_options.f90. */
#include <petscsys.h>
#include <string.h>

/* One logical option: *flag (0 or 1) is its default on entry and its value on return. */
static PetscErrorCode bool_option(PetscOptionItems *PetscOptionsObject, const char *name, const char *help, int *flag)
{
    PetscBool value = *flag ? PETSC_TRUE : PETSC_FALSE;

    PetscFunctionBeginUser;
    PetscCall(PetscOptionsBool(name, help, "README: Solver", value, &value, NULL));
    *flag = value == PETSC_TRUE;
    PetscFunctionReturn(0);
}

/* Reads -eme_chord_predictor, -eme_fused_kernel, -eme_lean_snes and -eme_final_chord into the
 * four flags (0 or 1) and -eme_max_halvings into max_halvings (0 to 30); their values on entry are
 * the defaults. Returns a PETSc error code (PETSC_ERR_ARG_OUTOFRANGE for a depth outside 0..30). */
PetscErrorCode eme_read_solver_options(int *chord_predictor, int *fused_kernel, int *lean_snes, int *final_chord,
                                       int *max_halvings)
{
    PetscInt depth = *max_halvings;

    PetscFunctionBeginUser;
    PetscOptionsBegin(PETSC_COMM_SELF, NULL, "EME step solver (eme_run, eme_ensemble, eme_bench)", "SNES");
    PetscCall(bool_option(PetscOptionsObject, "-eme_chord_predictor",
                          "Refine each step's predictor by one chord step with the last step's LU factors",
                          chord_predictor));
    PetscCall(bool_option(PetscOptionsObject, "-eme_fused_kernel",
                          "Solve the double pendulum's step by its fused kernel on the condensed unknowns "
                          "(9 plus multipliers); false: the generic residual on 15 plus multipliers", fused_kernel));
    PetscCall(bool_option(PetscOptionsObject, "-eme_lean_snes",
                          "Build the Jacobian and its LU inside the shell preconditioner (lag -1) with a "
                          "full-step shell line search, unless options need SNES's own Jacobian", lean_snes));
    PetscCall(bool_option(PetscOptionsObject, "-eme_final_chord",
                          "Confirm a root whose residual is below tolerance after a small update with the "
                          "existing LU factors instead of a new Jacobian (lean SNES only)", final_chord));
    PetscCall(PetscOptionsInt("-eme_max_halvings",
                              "A step whose root no retry strategy finds is replaced by two half steps, "
                              "recursively up to this depth (0: the run stops at such a step)", "README: Solver",
                              depth, &depth, NULL));
    PetscCheck(depth >= 0 && depth <= 30, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-eme_max_halvings takes 0 to 30, not %" PetscInt_FMT, depth);
    *max_halvings = (int)depth;
    PetscOptionsEnd();
    PetscFunctionReturn(0);
}

/* *given = 1 if the name of an option in the database contains `text` (a NUL-terminated string),
 * else 0. Returns a PETSc error code. */
PetscErrorCode eme_option_given(const char *text, int *given)
{
    char *all, *token, *end;
    size_t length = strlen(text);

    PetscFunctionBeginUser;
    *given = 0;
    PetscCall(PetscOptionsGetAll(NULL, &all));
    /* "-name value -name ..." : each token that starts with '-' is a name (or a negative value). */
    for (token = all; *token && !*given; token = end) {
        while (*token == ' ') token++;
        for (end = token; *end && *end != ' '; end++) continue;
        if (*token == '-') {
            const char *at;
            for (at = token; at + length <= end && !*given; at++) *given = strncmp(at, text, length) == 0;
        }
    }
    PetscCall(PetscFree(all));
    PetscFunctionReturn(0);
}
