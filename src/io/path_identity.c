/* What stands at a path, and whether two paths name one file (src/io/output_path.f90): the
 * checks that keep a run from replacing its own input, a directory or a stranger's file. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <sys/stat.h>

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
