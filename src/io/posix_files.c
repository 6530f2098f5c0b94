/* Directory creation and atomic rename for the Fortran drivers (no standard Fortran way).
 * Each returns 0 on success and -1 on failure (errno is left set). */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

/* mkdir -p: create `path` and any missing parents. */
int eme_make_directories(const char *path)
{
    char partial[4096];
    size_t length = strlen(path);
    if (length == 0 || length >= sizeof partial) return -1;
    memcpy(partial, path, length + 1);
    for (char *cursor = partial + 1; *cursor != '\0'; ++cursor) {
        if (*cursor != '/') continue;
        *cursor = '\0';
        if (mkdir(partial, 0777) != 0 && errno != EEXIST) return -1;
        *cursor = '/';
    }
    if (mkdir(partial, 0777) != 0 && errno != EEXIST) return -1;
    return 0;
}

/* rename(2): atomic within one file system. */
int eme_rename_file(const char *from, const char *to)
{
    return rename(from, to) == 0 ? 0 : -1;
}
