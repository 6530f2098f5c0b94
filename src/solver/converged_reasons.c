/* The legends of the converged reasons the run files record per step (docs/output.md):
 * PETSc's own names for SNESConvergedReason and TSConvergedReason, from PETSc's string tables,
 * over the range of each enumeration in petscsnes.h and petscts.h. For src/solver/snes_solver.F90
 * and src/integrator/ts_stepper.F90. */
#include <petscsnes.h>
#include <petscts.h>
#include <string.h>

enum { FAMILY_SNES = 1, FAMILY_TS = 2 };

/* Fills codes[] and `names` (each name followed by '\n', at most names_size bytes with the NUL)
 * with the reasons of `family` (1 SNES, 2 TS), at most `capacity` of them; returns how many,
 * or -1 for an unknown family or too small a buffer. CONVERGED_ITERATING (0) is left out: a
 * finished solve never reports it. */
int eme_converged_reasons(int family, int capacity, int *codes, char *names, int names_size)
{
    const char *const *table;
    int first, last, count = 0;
    size_t used = 0;

    if (family == FAMILY_SNES) {
        table = SNESConvergedReasons;
        first = SNES_DIVERGED_TR_DELTA;
        last = SNES_CONVERGED_ITS;
    } else if (family == FAMILY_TS) {
        table = TSConvergedReasons;
        first = TSADJOINT_DIVERGED_LINEAR_SOLVE;
        last = TS_CONVERGED_PSEUDO_FRTOL;
    } else {
        return -1;
    }
    names[0] = '\0';
    for (int code = first; code <= last; ++code) {
        const char *name = table[code];
        size_t length = strlen(name);
        if (code == 0 || length == 0 || name[0] == ' ') continue;
        if (count == capacity || used + length + 2 > (size_t)names_size) return -1;
        codes[count++] = code;
        memcpy(names + used, name, length);
        names[used + length] = '\n';
        used += length + 1;
        names[used] = '\0';
    }
    return count;
}
