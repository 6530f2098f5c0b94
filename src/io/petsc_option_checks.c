/* The PETSc options database as the drivers' command line needs it (src/io/command_line.f90):
 * PETSc is initialized with the command line without the input file (so that no option takes
 * FILE.nml for its value: -help FILE.nml, -info FILE.nml), and the options that nothing used on
 * any rank are listed at the end, as -options_left would. Before MPI starts, a program started
 * without mpirun (an MPI singleton) is given the Open MPI settings it needs (docs/running.md). */
#define _XOPEN_SOURCE 700 /* nftw, mkdtemp */
#include <dirent.h>
#include <errno.h>
#include <ftw.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <petscsys.h>

/* Whether a launcher (mpirun, srun with PMI or PMIx) started this process: it then gives the
 * process its place in a job, and nothing here may change how it reaches the other ranks. */
static int launched_by_mpi(void)
{
    static const char *const markers[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE",
                                          "OMPI_MCA_orte_hnp_uri"};
    for (size_t i = 0; i < sizeof markers / sizeof markers[0]; ++i)
        if (getenv(markers[i]) != NULL) return 1;
    return 0;
}

/* Whether the user set the Open MPI parameter `name`: in the environment (OMPI_MCA_name) or in
 * their own parameter file, ~/.openmpi/mca-params.conf ("name = value" lines). The system's
 * file is the distribution's defaults, which the environment overrides as Open MPI intends. */
static int user_set(const char *name)
{
    char variable[256], file[4096], line[1024];
    snprintf(variable, sizeof variable, "OMPI_MCA_%s", name);
    if (getenv(variable) != NULL) return 1;
    const char *home = getenv("HOME");
    if (home == NULL) return 0;
    snprintf(file, sizeof file, "%s/.openmpi/mca-params.conf", home);
    FILE *params = fopen(file, "r");
    if (params == NULL) return 0;
    int found = 0;
    size_t length = strlen(name);
    while (!found && fgets(line, sizeof line, params) != NULL) {
        const char *text = line + strspn(line, " \t");
        found = strncmp(text, name, length) == 0 && strchr(" \t=", text[length]) != NULL;
    }
    fclose(params);
    return found;
}

static int set_unless_user_set(const char *name, const char *value)
{
    char variable[256];
    if (user_set(name)) return 0;
    snprintf(variable, sizeof variable, "OMPI_MCA_%s", name);
    return setenv(variable, value, 1);
}

/* This process's own base of Open MPI's session directory ("" if none was made), removed at exit. */
static char session_base[4096];

static int remove_entry(const char *path, const struct stat *info, int kind, struct FTW *walk)
{
    (void)info;
    (void)kind;
    (void)walk;
    (void)remove(path);
    return 0;
}

static void remove_session_base(void)
{
    if (session_base[0] != '\0') (void)nftw(session_base, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

/* Removes the session bases (named PREFIX PID .XXXXXX) that processes of this user on this host
 * left when they were killed: those whose process no longer exists. */
static void remove_abandoned_bases(const char *folder, const char *prefix)
{
    DIR *entries = opendir(folder);
    if (entries == NULL) return;
    size_t length = strlen(prefix);
    struct dirent *entry;
    while ((entry = readdir(entries)) != NULL) {
        if (strncmp(entry->d_name, prefix, length) != 0) continue;
        char *end;
        long pid = strtol(entry->d_name + length, &end, 10);
        if (end == entry->d_name + length || *end != '.' || pid <= 0) continue;
        if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue;
        char path[4096];
        struct stat info;
        snprintf(path, sizeof path, "%s/%s", folder, entry->d_name);
        if (lstat(path, &info) != 0 || !S_ISDIR(info.st_mode) || info.st_uid != getuid()) continue;
        (void)nftw(path, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
    }
    closedir(entries);
}

/* The Open MPI settings of a singleton, unless the user set them (docs/running.md):
 * - no daemon (ess_singleton_isolated): nothing here spawns processes, and the daemon costs 0.1 s
 *   of every start;
 * - only the transport to itself (pml ob1, btl self, no psm, psm2 or ofi mtl): the scan of the
 *   fast networks' components loads libpsm2 and libinfinipath, whose constructors sleep about
 *   0.1 s in all, even where no such network exists;
 * - a session directory of its own (orte_tmpdir_base): isolated singletons all take the same
 *   name in Open MPI 4.1 (job family 0, job 1, rank 0 under TMPDIR/ompi.HOST.UID), so two at
 *   once, or one after a killed one, can fail to start ("File exists"). The base,
 *   TMPDIR/eme-mpi.HOST.PID.XXXXXX, is removed at exit, and a killed process's at the next start.
 * Under mpirun nothing is set: the launcher and the user's -mca settings decide. Other MPIs
 * ignore the variables. Returns 0, or errno if the environment could not be set. */
static int prepare_singleton(void)
{
    if (launched_by_mpi()) return 0;
    if (set_unless_user_set("ess_singleton_isolated", "1") != 0) return errno;
    if (set_unless_user_set("pml", "ob1") != 0) return errno;
    if (set_unless_user_set("btl", "self") != 0) return errno;
    if (set_unless_user_set("mtl", "^psm,psm2,ofi") != 0) return errno;
    if (user_set("orte_tmpdir_base")) return 0;
    const char *folder = getenv("TMPDIR");
    if (folder == NULL || folder[0] == '\0') folder = "/tmp";
    char host[256], prefix[300];
    if (gethostname(host, sizeof host) != 0) snprintf(host, sizeof host, "unknown");
    host[sizeof host - 1] = '\0';
    snprintf(prefix, sizeof prefix, "eme-mpi.%s.", host);
    remove_abandoned_bases(folder, prefix);
    if (snprintf(session_base, sizeof session_base, "%s/%s%ld.XXXXXX", folder, prefix, (long)getpid()) >=
            (int)sizeof session_base ||
        mkdtemp(session_base) == NULL) {
        session_base[0] = '\0';   /* Open MPI's own default then */
        return 0;
    }
    if (atexit(remove_session_base) != 0 || setenv("OMPI_MCA_orte_tmpdir_base", session_base, 1) != 0) {
        remove_session_base();
        session_base[0] = '\0';
    }
    return 0;
}

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
    if (prepare_singleton() != 0) return PETSC_ERR_SYS;
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
