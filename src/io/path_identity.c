/* What stands at a path, where a path leads, and whether two paths name one file
 * (src/io/output_path.f90, src/io/petsc_option_files.c): the checks that keep a run from replacing
 * its own input, a directory, a stranger's file or a study's files, and PETSc's own output from
 * landing on any of them. */
#define _DEFAULT_SOURCE /* realpath, readlink, lstat */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int eme_h5_file_kind(const char *path);   /* hdf5_run_file_check.c: 1 a run file, 2 another HDF5 file */

/* 0: nothing, 1: a regular file, 2: a directory, 3: something else (FIFO, device, socket);
 * -errno if the path cannot be examined. Follows symbolic links, as opening the path would. */
int eme_path_kind(const char *path)
{
    struct stat info;

    if (stat(path, &info) != 0) return errno == ENOENT ? 0 : -errno;
    if (S_ISREG(info.st_mode)) return 1;
    if (S_ISDIR(info.st_mode)) return 2;
    return 3;
}

/* 1 if both paths exist and name the same file (device and inode), else 0. */
int eme_same_file(const char *first, const char *second)
{
    struct stat a, b;

    if (stat(first, &a) != 0 || stat(second, &b) != 0) return 0;
    return a.st_dev == b.st_dev && a.st_ino == b.st_ino;
}

/* Where opening `path` for writing would create or write the file, as an absolute path without
 * symbolic links, '.' or '..' (`resolved`, PATH_MAX bytes): realpath of an existing file; a
 * dangling symbolic link followed to where it points; else the folder resolved (itself by these
 * rules) and the last name appended. 0, or -1 (too long, a loop of links, a folder on the way
 * that does not exist: nothing could be written there). */
static int resolve(const char *path, char *resolved, int depth)
{
    char current[PATH_MAX], target[PATH_MAX];
    struct stat info;

    if (depth > 40 || snprintf(current, sizeof current, "%s", path) >= (int)sizeof current) return -1;
    if (realpath(current, resolved) != NULL) return 0;
    if (lstat(current, &info) == 0 && S_ISLNK(info.st_mode)) {
        ssize_t length = readlink(current, target, sizeof target - 1);
        if (length < 0) return -1;
        target[length] = '\0';
        if (target[0] != '/') {                     /* relative to the link's folder */
            char *slash = strrchr(current, '/');
            char joined[PATH_MAX];
            if (slash == NULL) snprintf(joined, sizeof joined, "%s", target);
            else if (snprintf(joined, sizeof joined, "%.*s/%s", (int)(slash - current), current, target) >=
                     (int)sizeof joined)
                return -1;
            snprintf(target, sizeof target, "%s", joined);
        }
        return resolve(target, resolved, depth + 1);
    }
    /* Nothing there: the folder, resolved, and the last name. */
    size_t length = strlen(current);
    while (length > 1 && current[length - 1] == '/') current[--length] = '\0';
    char *slash = strrchr(current, '/');
    const char *name = slash ? slash + 1 : current;
    char folder[PATH_MAX];
    if (slash == NULL) snprintf(folder, sizeof folder, ".");
    else if (slash == current) snprintf(folder, sizeof folder, "/");
    else snprintf(folder, sizeof folder, "%.*s", (int)(slash - current), current);
    /* FOLDER/. and FOLDER/.. exist if FOLDER does: here it does not, and nothing can be written. */
    if (strcmp(name, ".") == 0 || strcmp(name, "..") == 0 || name[0] == '\0') return -1;
    if (resolve(folder, resolved, depth + 1) != 0) return -1;
    size_t used = strlen(resolved);
    if (snprintf(resolved + used, PATH_MAX - used, "%s%s", strcmp(resolved, "/") == 0 ? "" : "/", name) >=
        (int)(PATH_MAX - used))
        return -1;
    return 0;
}

/* `path` resolved as opening it would (resolve); `path` itself if it cannot be. */
void eme_resolve_path(const char *path, char *resolved)
{
    if (resolve(path, resolved, 0) != 0) snprintf(resolved, PATH_MAX, "%s", path);
}

/* 1 if writing `first` would write the file `second` names: the same place once both are
 * resolved, or the same file (device and inode: a hard link). */
int eme_same_target(const char *first, const char *second)
{
    char a[PATH_MAX], b[PATH_MAX];

    eme_resolve_path(first, a);
    eme_resolve_path(second, b);
    return strcmp(a, b) == 0 || eme_same_file(first, second);
}

/* 1 if `path`, once resolved, lies inside the folder `folder` (resolved too), at any depth. */
int eme_inside_folder(const char *path, const char *folder)
{
    char a[PATH_MAX], b[PATH_MAX];

    eme_resolve_path(path, a);
    eme_resolve_path(folder, b);
    size_t length = strlen(b);
    if (strcmp(b, "/") == 0) return 1;
    return strncmp(a, b, length) == 0 && a[length] == '/';
}

/* 1 if the file `path` would be written (resolved) into a study's output folder: one that
 * holds study.lock or index.journal (a study runs, or stopped early), or an index.h5 that is
 * not a run file (eme_ensemble's index). Every file of such a folder is the study's. */
int eme_in_study_folder(const char *path)
{
    char resolved[PATH_MAX], file[PATH_MAX + 32];
    struct stat info;

    eme_resolve_path(path, resolved);
    char *slash = strrchr(resolved, '/');
    if (slash == NULL) return 0;
    *slash = '\0';
    const char *folder = slash == resolved ? "/" : resolved;
    snprintf(file, sizeof file, "%s/study.lock", folder);
    if (stat(file, &info) == 0) return 1;
    snprintf(file, sizeof file, "%s/index.journal", folder);
    if (stat(file, &info) == 0) return 1;
    snprintf(file, sizeof file, "%s/index.h5", folder);
    return stat(file, &info) == 0 && S_ISREG(info.st_mode) && eme_h5_file_kind(file) == 2;
}
