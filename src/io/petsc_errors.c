/* PETSc's errors as one line for the drivers (src/io/command_line.f90): an error handler that
 * keeps the first message of the latest error and prints nothing, so that a bad option (an
 * unknown -snes_type, a missing -options_file) ends with the project's one-line message and
 * exit status 2 instead of PETSc's traceback; and a check, before a run writes anything, that
 * every file an option asks PETSc to write (-log_view :FILE, -snes_view ascii:FILE, ...) can be
 * written, since PETSc would find out only at the end of the run. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <petscsys.h>

static char first_message[1024];

static PetscErrorCode keep_first_message(MPI_Comm comm, int line, const char *function, const char *file,
                                         PetscErrorCode code, PetscErrorType kind, const char *message, void *context)
{
    (void)comm; (void)line; (void)file; (void)context;
    if (kind == PETSC_ERROR_INITIAL) {
        const char *generic = NULL;
        if (PetscErrorMessage(code, &generic, NULL) != 0 || generic == NULL) generic = "PETSc error";
        if (message != NULL && message[0] != '\0')
            snprintf(first_message, sizeof first_message, "%s (%s)", message, function ? function : "?");
        else
            snprintf(first_message, sizeof first_message, "%s (%s)", generic, function ? function : "?");
        /* PETSc's messages may carry line ends; one line is wanted. */
        for (char *c = first_message; *c != '\0'; ++c)
            if (*c == '\n' || *c == '\r') *c = ' ';
    }
    return code;
}

/* From now on PETSc's errors are returned, not printed; callable before PetscInitialize (PETSc
 * allocates with malloc until then). 0 on success. */
int eme_petsc_capture_errors(void)
{
    first_message[0] = '\0';
    return (int)PetscPushErrorHandler(keep_first_message, NULL);
}

/* The first message of PETSc's latest error ('' if none), at most size - 1 characters. */
void eme_petsc_error_text(char *text, int size)
{
    snprintf(text, (size_t)size, "%s", first_message);
}

/* Whether `path` can be created or written: its folder exists and is writable, and the file, if
 * it exists, is a writable regular file. 0, or an errno. */
static int writable(const char *path)
{
    char folder[PATH_MAX];
    const char *slash = strrchr(path, '/');
    struct stat info;

    if (stat(path, &info) == 0) {
        if (!S_ISREG(info.st_mode)) return S_ISDIR(info.st_mode) ? EISDIR : EINVAL;
        return access(path, W_OK) == 0 ? 0 : errno;
    }
    if (slash == NULL) {
        strcpy(folder, ".");
    } else if (slash == path) {
        strcpy(folder, "/");
    } else {
        size_t length = (size_t)(slash - path);
        if (length >= sizeof folder) return ENAMETOOLONG;
        memcpy(folder, path, length);
        folder[length] = '\0';
    }
    if (stat(folder, &info) != 0) return errno;
    if (!S_ISDIR(info.st_mode)) return ENOTDIR;
    return access(folder, W_OK) == 0 ? 0 : errno;
}

/* Every option of the database whose value is a viewer with a file (type:FILE[:format[:mode]],
 * PETSc's syntax for -*_view, -*_monitor and -log_view) names a file that can be written.
 * 0, or 1 with "option -NAME: ..." in `message`; 2 if the database cannot be read. */
int eme_petsc_check_viewer_files(char *message, int size)
{
    char *all = NULL, *saveptr = NULL, *option = NULL;
    int status = 0;

    message[0] = '\0';
    if (PetscOptionsGetAll(NULL, &all) != 0) return 2;
    for (char *word = strtok_r(all, " ", &saveptr); word != NULL && status == 0; word = strtok_r(NULL, " ", &saveptr)) {
        if (word[0] == '-' && (word[1] < '0' || word[1] > '9') && word[1] != '.') {
            option = word;
            continue;
        }
        if (option == NULL || (strstr(option, "view") == NULL && strstr(option, "monitor") == NULL)) continue;
        const char *colon = strchr(word, ':');
        if (colon == NULL) continue;
        char file[PATH_MAX];
        const char *end = strchr(colon + 1, ':');
        size_t length = end ? (size_t)(end - colon - 1) : strlen(colon + 1);
        if (length == 0 || length >= sizeof file) continue;
        memcpy(file, colon + 1, length);
        file[length] = '\0';
        /* Viewer types that write no file of that name (draw windows, sockets, a stream). */
        if (strncmp(word, "draw", 4) == 0 || strncmp(word, "socket", 6) == 0 || strncmp(word, "saws", 4) == 0 ||
            strcmp(file, "stdout") == 0 || strcmp(file, "stderr") == 0)
            continue;
        int error = writable(file);
        if (error != 0) {
            snprintf(message, (size_t)size, "option %s %s: PETSc could not write the file '%s': %s; allowed: a file in "
                     "an existing, writable folder", option, word, file, strerror(error));
            status = 1;
        }
    }
    PetscFree(all);
    return status;
}
