/* The files PETSc's options would write (-log_view :FILE, -snes_view binary:FILE, -info FILE,
 * -history FILE, ...), for the drivers (src/io/command_line.f90): none may be one of the run's or
 * the study's own files (its input, its output and their companions, a study's folder: given by
 * the caller, src/io/output_path.f90), checked on the command line, PETSC_OPTIONS and the options
 * files before PETSc starts (it opens the files of -history, -info and -log_trace as it starts)
 * and in PETSc's options database after; each must be writable, which PETSc would find out only
 * at the end of the run; and a run refused before it ran has them forgotten, since PETSc writes
 * -log_view's file as it finalizes. */
#define _POSIX_C_SOURCE 200809L
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <petscsys.h>

int eme_same_target(const char *first, const char *second);   /* path_identity.c */
int eme_inside_folder(const char *path, const char *folder);  /* path_identity.c */
int eme_in_study_folder(const char *path);                    /* path_identity.c */

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

/* An option (its name without the '-') and its value ("" if none). */
typedef struct {
    char *name, *value;
} option_pair;

typedef struct {
    option_pair *pairs;
    int count, room;
} option_list;

static void add_option(option_list *list, const char *name, const char *value)
{
    if (list->count == list->room) {
        int room = list->room > 0 ? 2 * list->room : 64;
        option_pair *larger = realloc(list->pairs, (size_t)room * sizeof *larger);
        if (larger == NULL) return;
        list->pairs = larger;
        list->room = room;
    }
    char *name_copy = strdup(name), *value_copy = strdup(value);
    if (name_copy == NULL || value_copy == NULL) {
        free(name_copy);
        free(value_copy);
        return;
    }
    list->pairs[list->count++] = (option_pair){name_copy, value_copy};
}

static void free_options(option_list *list)
{
    for (int i = 0; i < list->count; ++i) {
        free(list->pairs[i].name);
        free(list->pairs[i].value);
    }
    free(list->pairs);
}

/* '-name' and not a number ('-1', '-.5' are values), as PETSc tells an option from a value. */
static int option_name(const char *token)
{
    return token[0] == '-' && token[1] != '\0' && !isdigit((unsigned char)token[1]) && token[1] != '.';
}

static void add_options_file(option_list *list, const char *path, int depth);

/* The options among `count` tokens: a name, and the next token as its value unless that is a
 * name; -options_file's file is read in turn. */
static void add_tokens(option_list *list, char **tokens, int count, int depth)
{
    for (int i = 0; i < count; ++i) {
        if (!option_name(tokens[i])) continue;
        const char *value = i + 1 < count && !option_name(tokens[i + 1]) ? tokens[i + 1] : "";
        add_option(list, tokens[i] + 1, value);
        if (strcmp(tokens[i] + 1, "options_file") == 0 && value[0] != '\0') add_options_file(list, value, depth + 1);
    }
}

/* The options of `text`, split at white space. */
static void add_words(option_list *list, const char *text, int depth)
{
    char *copy = strdup(text), *saveptr = NULL;
    char **tokens = NULL;
    int count = 0;
    if (copy == NULL) return;
    for (char *word = strtok_r(copy, " \t\r\n", &saveptr); word != NULL; word = strtok_r(NULL, " \t\r\n", &saveptr)) {
        char **larger = realloc(tokens, (size_t)(count + 1) * sizeof *tokens);
        if (larger == NULL) break;
        tokens = larger;
        tokens[count++] = word;
    }
    add_tokens(list, tokens, count, depth);
    free(tokens);
    free(copy);
}

/* An options file as PETSc reads one: per line an option and, after white space, its value;
 * '#' starts a comment. A missing file adds nothing (PETSc reports it). */
static void add_options_file(option_list *list, const char *path, int depth)
{
    char line[4096];
    FILE *file = depth > 8 ? NULL : fopen(path, "r");
    if (file == NULL) return;
    while (fgets(line, sizeof line, file) != NULL) {
        char *comment = strchr(line, '#');
        if (comment != NULL) *comment = '\0';
        char *name = line + strspn(line, " \t");
        size_t length = strcspn(name, " \t\r\n");
        if (length == 0 || !option_name(name)) continue;
        char *value = name + length;
        if (*value != '\0') *value++ = '\0';
        value += strspn(value, " \t");
        size_t end = strlen(value);
        while (end > 0 && isspace((unsigned char)value[end - 1])) value[--end] = '\0';
        add_option(list, name + 1, value);
        if (strcmp(name + 1, "options_file") == 0 && value[0] != '\0') add_options_file(list, value, depth + 1);
    }
    fclose(file);
}

/* Whether option `name` was given (in `list`). */
static int has_option(const option_list *list, const char *name)
{
    for (int i = 0; i < list->count; ++i)
        if (strcmp(list->pairs[i].name, name) == 0) return 1;
    return 0;
}

/* The options PETSc will read as it starts: the `count` arguments (each NUL-terminated, one
 * after another), PETSC_OPTIONS, the files of -options_file, and ~/.petscrc, .petscrc and
 * petscrc unless -skip_petscrc. */
static void options_before_start(option_list *list, const char *arguments, int count)
{
    char **tokens = calloc((size_t)(count > 0 ? count : 1), sizeof *tokens);
    if (tokens == NULL) return;
    for (int i = 0; i < count; ++i) {
        tokens[i] = (char *)arguments;
        arguments += strlen(arguments) + 1;
    }
    add_tokens(list, tokens, count, 0);
    free(tokens);
    const char *environment = getenv("PETSC_OPTIONS");
    if (environment != NULL) add_words(list, environment, 0);
    if (has_option(list, "skip_petscrc")) return;
    const char *home = getenv("HOME");
    char path[PATH_MAX];
    if (home != NULL && snprintf(path, sizeof path, "%s/.petscrc", home) < (int)sizeof path)
        add_options_file(list, path, 1);
    add_options_file(list, ".petscrc", 1);
    add_options_file(list, "petscrc", 1);
}

/* The options in PETSc's database (after PetscInitialize). 0, or -1 if it cannot be listed. */
static int options_in_database(option_list *list)
{
    char *all = NULL;
    if (PetscOptionsGetAll(NULL, &all) != 0) return -1;
    add_words(list, all, 9);           /* (the files were read: no -options_file again) */
    PetscFree(all);
    return 0;
}

/* This process's rank: MPI's after PetscInitialize, the launcher's before (0 without one). */
static int process_rank(int started)
{
    PetscMPIInt rank = 0;
    if (started) {
        if (MPI_Comm_rank(PETSC_COMM_WORLD, &rank) != MPI_SUCCESS) rank = 0;
        return (int)rank;
    }
    static const char *const variables[] = {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"};
    for (size_t i = 0; i < sizeof variables / sizeof variables[0]; ++i)
        if (getenv(variables[i]) != NULL) return atoi(getenv(variables[i]));
    return 0;
}

/* The rank the launcher gave this process, or 0 (before MPI starts: who prints a refusal). */
int eme_launcher_rank(void)
{
    return process_rank(0);
}

/* The files option `name` = `value` has PETSc write, into targets[0..1] (PETSc 3.18): -history
 * FILE (appended to); -info FILE[:classes] and -log_trace FILE (FILE.rank); -viewer_binary_filename
 * FILE (and FILE.info); a viewer, [type]:FILE[:format[:mode]] (-log_view, -*_view*, -*_monitor*,
 * -*_converged_reason, ...: any value with a ':'), FILE, and FILE.info for a binary viewer.
 * `viewer` tells the last kind. Their number. */
static int option_targets(const option_pair *option, int rank, char targets[2][PATH_MAX], int *viewer)
{
    const char *name = option->name, *value = option->value;
    *viewer = 0;
    if (value[0] == '\0') return 0;
    if (strcmp(name, "history") == 0) {
        snprintf(targets[0], PATH_MAX, "%s", value);
        return 1;
    }
    if (strcmp(name, "info") == 0 || strcmp(name, "log_trace") == 0) {
        size_t length = strcmp(name, "info") == 0 ? strcspn(value, ":") : strlen(value);
        if (length == 0) return 0;
        snprintf(targets[0], PATH_MAX, "%.*s.%d", (int)length, value, rank);
        return 1;
    }
    if (strcmp(name, "viewer_binary_filename") == 0) {
        snprintf(targets[0], PATH_MAX, "%s", value);
        snprintf(targets[1], PATH_MAX, "%s.info", value);
        return 2;
    }
    if (strncmp(name, "options_file", 12) == 0) return 0;        /* read, not written */
    const char *colon = strchr(value, ':');
    if (colon == NULL) return 0;
    const char *end = strchr(colon + 1, ':');
    size_t length = end ? (size_t)(end - colon - 1) : strlen(colon + 1);
    if (length == 0 || length >= PATH_MAX - 8) return 0;
    snprintf(targets[0], PATH_MAX, "%.*s", (int)length, colon + 1);
    /* Viewer types that write no file of that name (draw windows, sockets, a stream). */
    if (strncmp(value, "draw", 4) == 0 || strncmp(value, "socket", 6) == 0 || strncmp(value, "saws", 4) == 0 ||
        strncmp(value, "glvis", 5) == 0 || strcmp(targets[0], "stdout") == 0 || strcmp(targets[0], "stderr") == 0)
        return 0;
    *viewer = 1;
    if (strncmp(value, "binary:", 7) != 0) return 1;
    snprintf(targets[1], PATH_MAX, "%.*s.info", (int)length, colon + 1);
    return 2;
}

/* What a protected entry list holds: "path\nlabel\n" after one another. The label of the entry
 * that `target` would write (a file, or anything inside a folder with `folders`), or NULL. */
static const char *protected_label(const char *entries, const char *target, int folders, char *path, char *label)
{
    while (entries != NULL && *entries != '\0') {
        const char *end_path = strchr(entries, '\n');
        if (end_path == NULL) break;
        const char *end_label = strchr(end_path + 1, '\n');
        if (end_label == NULL) break;
        snprintf(path, PATH_MAX, "%.*s", (int)(end_path - entries), entries);
        snprintf(label, 512, "%.*s", (int)(end_label - end_path - 1), end_path + 1);
        if (folders ? eme_inside_folder(target, path) : eme_same_target(target, path)) return label;
        entries = end_label + 1;
    }
    return NULL;
}

/* Checks the files the options would have PETSc write: none may be one of `files` or lie in one
 * of `folders` (each "path\nlabel\n" after one another), nor, with `study_folders`, in a study's
 * output folder; after PetscInitialize (`started`), each viewer file must be writable too.
 * Before, the options are the `count` arguments (NUL-terminated, one after another) and what
 * PETSc adds as it starts; after, PETSc's database, and the answer is every rank's (collective).
 * 0, or 1 with "option -NAME VALUE: ..." in `message`; 2 if the database cannot be listed. */
int eme_petsc_check_option_files(int started, const char *arguments, int count, const char *files,
                                 const char *folders, int study_folders, char *message, int size)
{
    option_list list = {NULL, 0, 0};
    int status = 0, rank = process_rank(started);
    char path[PATH_MAX], label[512], targets[2][PATH_MAX], refused[256] = "";

    message[0] = '\0';
    if (started) {
        if (options_in_database(&list) != 0) status = 2;
    } else {
        options_before_start(&list, arguments, count);
    }
    for (int i = 0; i < list.count && status == 0; ++i) {
        int viewer, n = option_targets(&list.pairs[i], rank, targets, &viewer);
        snprintf(refused, sizeof refused, "%s", list.pairs[i].name);
        for (int k = 0; k < n && status == 0; ++k) {
            const char *what = protected_label(files, targets[k], 0, path, label);
            if (what == NULL) what = protected_label(folders, targets[k], 1, path, label);
            if (what != NULL) {
                snprintf(message, (size_t)size, "option -%s %s would have PETSc write '%s', which is %s ('%s'); "
                         "refused before anything ran; allowed: a file that is none of the run's or study's own "
                         "(input, output and its .part, .spare or .lock, a study's folder)", list.pairs[i].name,
                         list.pairs[i].value, targets[k], what, path);
                status = 1;
            } else if (study_folders && eme_in_study_folder(targets[k])) {
                snprintf(message, (size_t)size, "option -%s %s would have PETSc write '%s', which lies in the output "
                         "folder of a study (it holds study.lock, index.journal or a study's index.h5), whose files "
                         "are the study's; refused before anything ran; allowed: a file in another folder",
                         list.pairs[i].name, list.pairs[i].value, targets[k]);
                status = 1;
            } else if (started && viewer) {
                int error = writable(targets[k]);
                if (error != 0) {
                    snprintf(message, (size_t)size, "option -%s %s: PETSc could not write the file '%s': %s; allowed: "
                             "a file in an existing, writable folder", list.pairs[i].name, list.pairs[i].value,
                             targets[k], strerror(error));
                    status = 1;
                }
            }
        }
    }
    /* A refused option is taken out of the database: PETSc would still write -log_view's or
     * -options_view's file as it finalizes. */
    if (started && status == 1) {
        char option[300];
        snprintf(option, sizeof option, "-%s", refused);
        (void)PetscOptionsClearValue(NULL, option);
    }
    free_options(&list);
    if (!started) return status;
    /* Every rank takes the first refusing rank's answer, so that all go on or all stop. */
    PetscMPIInt first = status != 0 ? (PetscMPIInt)rank : INT_MAX;
    if (MPI_Allreduce(MPI_IN_PLACE, &first, 1, MPI_INT, MPI_MIN, PETSC_COMM_WORLD) != MPI_SUCCESS) return status;
    if (first == INT_MAX) return 0;
    int shared = status;
    if (MPI_Bcast(&shared, 1, MPI_INT, first, PETSC_COMM_WORLD) != MPI_SUCCESS ||
        MPI_Bcast(message, size, MPI_CHAR, first, PETSC_COMM_WORLD) != MPI_SUCCESS)
        return status;
    return shared;
}

/* Takes every option that has PETSc write a file (option_targets) out of the database: a run
 * refused before it ran writes nothing, and PETSc would still write -log_view's file as it
 * finalizes. 0, or -1 if the database cannot be listed. */
int eme_petsc_forget_file_options(void)
{
    option_list list = {NULL, 0, 0};
    char targets[2][PATH_MAX], option[300];
    int viewer, status = options_in_database(&list);
    for (int i = 0; i < list.count; ++i) {
        if (option_targets(&list.pairs[i], process_rank(1), targets, &viewer) == 0) continue;
        snprintf(option, sizeof option, "-%s", list.pairs[i].name);
        (void)PetscOptionsClearValue(NULL, option);
    }
    free_options(&list);
    return status;
}
