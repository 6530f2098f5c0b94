/* The code's own options (-eme_*), in one table: registered with PETSc's options database when
 * they are read, so that PETSc's -help lists them with their descriptions (PETSc 3.18 has no
 * Fortran PetscOptionsBegin/PetscOptionsBool), and listed by the drivers' --help from the same
 * table (src/io/command_help.f90). Also a scan of the options a user gave, by part of their name
 * (PETSc's options database has no prefix query), and the database's text, for the provenance a
 * run file records. For src/solver/solver_options.f90 and src/run/run_options.F90. */
#include <petscsys.h>
#include <ctype.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* What values an option takes: a logical, an integer in [minimum, maximum], a real > minimum. */
typedef enum { LOGICAL, INTEGER, REAL } eme_option_kind;

typedef struct {
    const char *name, *value, *help;
    eme_option_kind kind;
    double minimum, maximum;
} eme_option;

/* The step solver's options (docs/integrators.md), then the run's (docs/running.md). */
enum {
    CHORD_PREDICTOR, FUSED_KERNEL, LEAN_SNES, DIRECT_NEWTON, FINAL_CHORD, MODIFIED_NEWTON, CHORD_ITERATIONS, MAX_HALVINGS,
    ERROR_ESTIMATE, ERROR_SCALE, PROGRESS, OVERWRITE, CONTINUE, SPLIT, DENSE, OPTION_COUNT
};
static const eme_option options[OPTION_COUNT] = {
    {"-eme_chord_predictor", "<true>", "Refine each step's predictor by one chord step with the last step's LU factors",
     LOGICAL, 0, 0},
    {"-eme_fused_kernel", "<true>",
     "Solve EME's and the midpoint rule's steps by the model's fused step on its condensed unknowns, where the "
     "model offers one (the double pendulum: 9 plus multipliers); false: the generic residual on all unknowns "
     "(the pendulum: 15 plus multipliers)",
     LOGICAL, 0, 0},
    {"-eme_lean_snes", "<true>",
     "Build the Jacobian and its LU inside the shell preconditioner (lag -1) with a full-step shell line search, "
     "unless options need SNES's own Jacobian",
     LOGICAL, 0, 0},
    {"-eme_direct_newton", "<false>",
     "Run the lean SNES's Newton iteration (the same iterates, tests and LU factors) without SNESSolve, unless an "
     "-snes_, -ksp_, -pc_, -info or -log_ option is given; a solve that does not converge is solved again by SNES",
     LOGICAL, 0, 0},
    {"-eme_final_chord", "<true>",
     "Confirm a root whose residual is below tolerance after a small update with the existing LU factors instead "
     "of a new Jacobian (lean SNES with -eme_modified_newton false only)",
     LOGICAL, 0, 0},
    {"-eme_modified_newton", "<true>",
     "Keep the LU factors across the Newton iterations of a step while they contract, and accept a chord iterate "
     "only at rounding (lean SNES only); false: a new Jacobian every Newton iteration",
     LOGICAL, 0, 0},
    {"-eme_chord_iterations", "<2>",
     "The modified Newton keeps the LU factors while their observed contraction brings the error to its acceptance "
     "level within this many chord iterations, else it makes new ones (1 to 10)",
     INTEGER, 1, 10},
    {"-eme_max_halvings", "<6>",
     "A step whose root no retry strategy finds is replaced by two half steps, recursively up to this depth "
     "(0 to 30; 0: the run stops at such a step)",
     INTEGER, 0, 30},
    {"-eme_error_estimate", "<false>",
     "Compute and record the local error estimate of every step of EME and the midpoint rule also at fixed steps "
     "(with &integrator tolerance it is always on: it chooses the steps)",
     LOGICAL, 0, 0},
    {"-eme_error_scale", "<1>",
     "Multiply the local error estimate by this factor (> 0) before the step-size controller sees it: above 1 is "
     "more cautious (the tests use it to plant a wrong estimate)",
     REAL, 0, 0},
    {"-eme_progress", "<terminal>",
     "Print a progress line on stderr at most every 2 s (simulated time, steps, rate, time left); default: when "
     "stderr is a terminal",
     LOGICAL, 0, 0},
    {"-eme_overwrite", "<false>",
     "Replace an existing complete output file, as &output overwrite = .true. does (a run that does not complete "
     "never replaces one)",
     LOGICAL, 0, 0},
    {"-eme_continue", "<false>",
     "Continue the run that FILE (or FILE.part) holds from its last written state, appending to it "
     "(docs/faults.md: Continuing a run)",
     LOGICAL, 0, 0},
    {"-eme_split", "<false>",
     "Run a model that can be split over ranks (the spring chain) on the sparse split path on one process at any "
     "size of at least 2 masses a rank (by default an integrator that solves equations takes it beyond 64 unknowns, the others beyond 1000; "
     "docs/performance.md: Two paths)",
     LOGICAL, 0, 0},
    {"-eme_dense", "<false>",
     "Run a spring chain of at most 1000 unknowns on the dense path on one process, as eme_run did before 64 "
     "unknowns took implicit steps to the split path (its state in /state rows; docs/performance.md: Two paths)",
     LOGICAL, 0, 0},
};

/* Whether `text` is a value PETSc reads as a logical (an empty value is a flag: true). */
static int is_logical(const char *text)
{
    static const char *const words[] = {"", "true", "false", "yes", "no", "on", "off", "1", "0"};

    for (size_t i = 0; i < sizeof words / sizeof words[0]; ++i)
        if (strcasecmp(text, words[i]) == 0) return 1;
    return 0;
}

/* 0 if `value` is allowed for option o, else 1 with "-name value: allowed: ..." in `message`. */
static int check_value(const eme_option *o, const char *value, char *message, int size)
{
    char *end = NULL;
    int allowed;

    if (o->kind == LOGICAL) {
        allowed = is_logical(value);
    } else if (o->kind == INTEGER) {
        long number = strtol(value, &end, 10);
        allowed = end != value && *end == '\0' && number >= o->minimum && number <= o->maximum;
    } else {
        double number = strtod(value, &end);
        allowed = end != value && *end == '\0' && number > o->minimum && number < 1e300;
    }
    if (allowed) return 0;
    if (o->kind == LOGICAL)
        snprintf(message, (size_t)size, "%s %s: allowed: true or false (or nothing: true)", o->name, value);
    else if (o->kind == INTEGER)
        snprintf(message, (size_t)size, "%s %s: allowed: an integer from %g to %g", o->name, value, o->minimum,
                 o->maximum);
    else
        snprintf(message, (size_t)size, "%s %s: allowed: a number > %g", o->name, value, o->minimum);
    return 1;
}

/* Checks the value of every -eme_* option given before anything reads it: 0 if all are allowed,
 * else 1 with "-name value: allowed: ..." in `message` (`size` bytes). A bad value is bad input
 * (the drivers exit with status 2 and write nothing), not a PETSc error. Returns 2 for a PETSc
 * error. */
int eme_check_own_options(char *message, int size)
{
    char *all, *token, *next;
    int status = 0;

    message[0] = '\0';
    /* The database as text ("-name value -flag ..."): reading it marks no option as used, so an
     * option the run does not read is still named as unused at the end. */
    if (PetscOptionsGetAll(NULL, &all) != 0) return 2;
    for (token = strtok(all, " "); token != NULL && status == 0; token = next) {
        next = strtok(NULL, " ");
        for (int i = 0; i < OPTION_COUNT; ++i) {
            if (strcmp(token, options[i].name) != 0) continue;
            /* The next token is the value unless it is another option (a negative number is a value). */
            int has_value = next != NULL && !(next[0] == '-' && !isdigit((unsigned char)next[1]) && next[1] != '.');
            status = check_value(&options[i], has_value ? next : "", message, size);
            if (has_value) next = strtok(NULL, " ");
        }
    }
    PetscFree(all);
    return status;
}

/* The name, default and description of option i (0-based), for --help; 1 past the last. */
int eme_option_help(int i, char *name, char *value, char *help, int size)
{
    if (i < 0 || i >= OPTION_COUNT) return 1;
    snprintf(name, (size_t)size, "%s", options[i].name);
    snprintf(value, (size_t)size, "%s", options[i].value);
    snprintf(help, (size_t)size, "%s", options[i].help);
    return 0;
}

/* One logical option: *flag (0 or 1) is its default on entry and its value on return; *given
 * (if not NULL) says whether the database set it. */
static PetscErrorCode bool_option(PetscOptionItems *PetscOptionsObject, int which, const char *section, int *flag,
                                  int *given)
{
    PetscBool value = *flag ? PETSC_TRUE : PETSC_FALSE, set = PETSC_FALSE;

    PetscFunctionBeginUser;
    PetscCall(PetscOptionsBool(options[which].name, options[which].help, section, value, &value, &set));
    *flag = value == PETSC_TRUE;
    if (given) *given = set == PETSC_TRUE;
    PetscFunctionReturn(0);
}

/* Reads -eme_chord_predictor, -eme_fused_kernel, -eme_lean_snes, -eme_direct_newton, -eme_final_chord
 * and -eme_modified_newton into the six flags (0 or 1), -eme_chord_iterations into *chord_iterations
 * (1 to 10) and -eme_max_halvings into *max_halvings (0 to 30); their values on entry are the
 * defaults. Returns a PETSc error code (PETSC_ERR_ARG_OUTOFRANGE for a number out of its range). */
PetscErrorCode eme_read_solver_options(int *chord_predictor, int *fused_kernel, int *lean_snes, int *direct_newton,
                                       int *final_chord, int *modified_newton, int *chord_iterations,
                                       int *max_halvings)
{
    PetscInt depth = *max_halvings, chords = *chord_iterations;
    const char *section = "docs/integrators.md";

    PetscFunctionBeginUser;
    PetscOptionsBegin(PETSC_COMM_SELF, NULL, "EME step solver (eme_run, eme_ensemble, eme_bench)", "SNES");
    PetscCall(bool_option(PetscOptionsObject, CHORD_PREDICTOR, section, chord_predictor, NULL));
    PetscCall(bool_option(PetscOptionsObject, FUSED_KERNEL, section, fused_kernel, NULL));
    PetscCall(bool_option(PetscOptionsObject, LEAN_SNES, section, lean_snes, NULL));
    PetscCall(bool_option(PetscOptionsObject, DIRECT_NEWTON, section, direct_newton, NULL));
    PetscCall(bool_option(PetscOptionsObject, FINAL_CHORD, section, final_chord, NULL));
    PetscCall(bool_option(PetscOptionsObject, MODIFIED_NEWTON, section, modified_newton, NULL));
    PetscCall(PetscOptionsInt(options[CHORD_ITERATIONS].name, options[CHORD_ITERATIONS].help, section, chords, &chords,
                              NULL));
    PetscCheck(chords >= 1 && chords <= 10, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-eme_chord_iterations takes 1 to 10, not %" PetscInt_FMT, chords);
    *chord_iterations = (int)chords;
    PetscCall(PetscOptionsInt(options[MAX_HALVINGS].name, options[MAX_HALVINGS].help, section, depth, &depth, NULL));
    PetscCheck(depth >= 0 && depth <= 30, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE,
               "-eme_max_halvings takes 0 to 30, not %" PetscInt_FMT, depth);
    *max_halvings = (int)depth;
    PetscOptionsEnd();
    PetscFunctionReturn(0);
}

/* Reads -eme_error_estimate into *record (0 or 1) and -eme_error_scale into *scale (> 0); their
 * values on entry are the defaults. Returns a PETSc error code (PETSC_ERR_ARG_OUTOFRANGE for a
 * scale that is not positive). */
PetscErrorCode eme_read_step_control_options(int *record, double *scale)
{
    PetscReal factor = *scale;
    const char *section = "docs/integrators.md: Adaptive steps";

    PetscFunctionBeginUser;
    PetscOptionsBegin(PETSC_COMM_SELF, NULL, "EME step-size control (eme_run, eme_ensemble)", NULL);
    PetscCall(bool_option(PetscOptionsObject, ERROR_ESTIMATE, section, record, NULL));
    PetscCall(PetscOptionsReal(options[ERROR_SCALE].name, options[ERROR_SCALE].help, section, factor, &factor, NULL));
    PetscCheck(factor > 0, PETSC_COMM_SELF, PETSC_ERR_ARG_OUTOFRANGE, "-eme_error_scale takes a number > 0, not %g",
               (double)factor);
    *scale = (double)factor;
    PetscOptionsEnd();
    PetscFunctionReturn(0);
}

/* Reads -eme_progress (into *progress, and whether it was given into *progress_given),
 * -eme_overwrite (into *overwrite), -eme_continue (into *resume), -eme_split (into *split) and
 * -eme_dense (into *dense); the flags' values on entry are the defaults. Returns a PETSc error
 * code. */
PetscErrorCode eme_read_run_options(int *progress, int *progress_given, int *overwrite, int *resume, int *split,
                                    int *dense)
{
    const char *section = "docs/running.md";

    PetscFunctionBeginUser;
    PetscOptionsBegin(PETSC_COMM_SELF, NULL, "EME run (eme_run, eme_ensemble)", NULL);
    PetscCall(bool_option(PetscOptionsObject, PROGRESS, section, progress, progress_given));
    PetscCall(bool_option(PetscOptionsObject, OVERWRITE, section, overwrite, NULL));
    PetscCall(bool_option(PetscOptionsObject, CONTINUE, section, resume, NULL));
    PetscCall(bool_option(PetscOptionsObject, SPLIT, section, split, NULL));
    PetscCall(bool_option(PetscOptionsObject, DENSE, section, dense, NULL));
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

/* The options database as text ("-name value -name ..."; every option set, from the command
 * line, PETSC_OPTIONS or an options file) into `text` (`size` bytes, cut if longer). Returns a
 * PETSc error code. */
PetscErrorCode eme_options_in_force(char *text, int size)
{
    char *all;

    PetscFunctionBeginUser;
    PetscCall(PetscOptionsGetAll(NULL, &all));
    snprintf(text, (size_t)size, "%s", all);
    PetscCall(PetscFree(all));
    PetscFunctionReturn(0);
}

/* *set = 1 if the option `name` (NUL-terminated, exactly, e.g. "-snes_mf") is in the database,
 * with its value (or "") in `value` (`size` bytes, cut if longer). Returns a PETSc error code. */
PetscErrorCode eme_option_value(const char *name, char *value, int size, int *set)
{
    PetscBool found;

    PetscFunctionBeginUser;
    value[0] = '\0';
    PetscCall(PetscOptionsGetString(NULL, NULL, name, value, (size_t)size, &found));
    if (!found) PetscCall(PetscOptionsHasName(NULL, NULL, name, &found));
    *set = found ? 1 : 0;
    PetscFunctionReturn(0);
}
