/* The PETSc options database as the drivers' command line needs it (src/io/command_line.f90):
 * PETSc is initialized with the command line without the input file (so that no option takes
 * FILE.nml for its value: -help FILE.nml, -info FILE.nml), and the options that nothing used on
 * any rank are listed at the end, as -options_left would. */
#define _POSIX_C_SOURCE 200809L
#include <stdlib.h>
#include <string.h>
#include <petscsys.h>

/* PetscInitialize (and PetscInitializeFortran) with the `count` arguments in `arguments`, each
 * NUL-terminated, one after another, the program's name first. Returns a PETSc error code. */
int eme_petsc_initialize(const char *arguments, int count)
{
    /* PETSc keeps argc and argv for PetscGetArgs: they live as long as the program. */
    static int argc;
    static char **argv;
    PetscErrorCode ierr;

    argv = malloc(((size_t)count + 1) * sizeof *argv);
    if (argv == NULL) return PETSC_ERR_MEM;
    for (int i = 0; i < count; ++i) {
        size_t length = strlen(arguments) + 1;
        argv[i] = malloc(length);
        if (argv[i] == NULL) return PETSC_ERR_MEM;
        memcpy(argv[i], arguments, length);
        arguments += length;
    }
    argv[count] = NULL;
    argc = count;
    /* A program started without mpirun is an MPI singleton; Open MPI then starts a daemon for it
     * unless told not to, which costs 0.1 s of every start (measured: 0.37 s against 0.27 s for a
     * run refused at its input). Nothing here spawns processes, so the daemon is not needed. The
     * user's setting wins; other MPIs ignore the variable; under mpirun it does not apply. */
    if (setenv("OMPI_MCA_ess_singleton_isolated", "1", 0) != 0) return PETSC_ERR_SYS;
    ierr = PetscInitialize(&argc, &argv, NULL, NULL);
    if (ierr) return (int)ierr;
    return (int)PetscInitializeFortran();
}

/* Whether PETSc's -help was given (1) or not (0). */
int eme_petsc_help_requested(void)
{
    PetscBool set = PETSC_FALSE;

    if (PetscOptionsHasName(NULL, NULL, "-help", &set) != 0) return 0;
    return set == PETSC_TRUE;
}

/* The options (blank-separated, each with its '-') that were set but never used on any rank
 * of PETSC_COMM_WORLD, into `text` on rank 0 ('' elsewhere); collective; 0 on success. */
int eme_petsc_unused_options(char *text, int size)
{
    char candidates[8192] = "";
    PetscInt count = 0;
    char **names = NULL, **values = NULL;
    PetscMPIInt rank;
    int n = 0, used[256];
    char *tokens[256];
    static const char *const read_at_finalize[] = {"-options_left", "-options_view", "-citations"};

    text[0] = '\0';
    if (MPI_Comm_rank(PETSC_COMM_WORLD, &rank) != MPI_SUCCESS) return -1;
    /* PetscFinalize, still to come, reads these (PETSc 3.18): asking marks them used. */
    for (size_t i = 0; i < sizeof read_at_finalize / sizeof read_at_finalize[0]; ++i) {
        PetscBool set;
        if (PetscOptionsHasName(NULL, NULL, read_at_finalize[i], &set) != 0) return -1;
    }
    /* Rank 0's unused options are the candidates; an option used on another rank is used. */
    if (rank == 0) {
        if (PetscOptionsLeftGet(NULL, &count, &names, &values) != 0) return -1;
        for (PetscInt i = 0; i < count && i < 256; ++i) {
            if (strlen(candidates) + strlen(names[i]) + 3 >= sizeof candidates) break;
            strcat(candidates, " -");
            strcat(candidates, names[i]);
        }
        if (PetscOptionsLeftRestore(NULL, &count, &names, &values) != 0) return -1;
    }
    if (MPI_Bcast(candidates, (int)sizeof candidates, MPI_CHAR, 0, PETSC_COMM_WORLD) != MPI_SUCCESS) return -1;
    for (char *name = strtok(candidates, " "); name != NULL && n < 256; name = strtok(NULL, " ")) {
        PetscBool was_used = PETSC_FALSE;
        if (PetscOptionsUsed(NULL, name + 1, &was_used) != 0) return -1;
        tokens[n] = name;
        used[n++] = was_used ? 1 : 0;
    }
    if (n > 0 && MPI_Allreduce(MPI_IN_PLACE, used, n, MPI_INT, MPI_LOR, PETSC_COMM_WORLD) != MPI_SUCCESS) return -1;
    if (rank != 0) return 0;
    for (int i = 0; i < n; ++i) {
        if (used[i] || strlen(text) + strlen(tokens[i]) + 2 >= (size_t)size) continue;
        if (text[0] != '\0') strcat(text, " ");
        strcat(text, tokens[i]);
    }
    return 0;
}
