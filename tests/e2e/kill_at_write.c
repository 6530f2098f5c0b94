/* A SIGKILL at a chosen file operation, for the crash-consistency test
 * (tests/e2e/test_kill_points.py): loaded with LD_PRELOAD, it counts the operations that change
 * files under the directory $EME_KILL_DIR (write, pwrite, ftruncate, truncate, posix_fallocate,
 * rename, renameat2, link, unlink) and, at the operation numbered $EME_KILL_AT (from 1), kills
 * the process with SIGKILL before that operation reaches the file system. So the files are left
 * exactly as operations 1 .. K-1 made them, which is what a kill at any instant between two
 * system calls leaves. $EME_KILL_LOG names a file that gets a line "K operation" for each
 * operation (without $EME_KILL_AT: the whole run's list). $EME_KILL_SIGNAL names another signal
 * by number (19, SIGSTOP: the process stops there, holding what it holds, until SIGCONT lets it
 * perform the operation and go on). To stand for file systems that lack
 * them, $EME_KILL_NO_EXCHANGE makes renameat2(RENAME_EXCHANGE) fail with EINVAL (as on NFS) and
 * $EME_KILL_NO_LINK makes link fail with EPERM (as on FAT). Everything else passes through. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static long operations;   /* counted so far */

#define NEXT(name) ((__typeof__(&name))dlsym(RTLD_NEXT, #name))

/* 1 if the absolute path `path` lies under $EME_KILL_DIR. */
static int watched_path(const char *path)
{
    const char *directory = getenv("EME_KILL_DIR");
    if (directory == NULL || path == NULL) return 0;
    char resolved[PATH_MAX];
    if (path[0] != '/') {
        if (getcwd(resolved, sizeof resolved) == NULL) return 0;
        size_t used = strlen(resolved);
        snprintf(resolved + used, sizeof resolved - used, "/%s", path);
        path = resolved;
    }
    size_t prefix = strlen(directory);
    return strncmp(path, directory, prefix) == 0 && path[prefix] == '/';
}

static int watched_fd(int fd)
{
    char link[64], path[PATH_MAX];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t length = readlink(link, path, sizeof path - 1);
    if (length <= 0) return 0;
    path[length] = '\0';
    return watched_path(path);
}

/* Counts one operation on a watched file, logs it, and kills the process if it is the chosen one. */
static void operation(int watched, const char *name)
{
    if (!watched) return;
    operations++;
    const char *log = getenv("EME_KILL_LOG");
    if (log != NULL) {
        int fd = open(log, O_WRONLY | O_CREAT | O_APPEND, 0666);
        if (fd >= 0) {
            char line[64];
            int length = snprintf(line, sizeof line, "%ld %s\n", operations, name);
            (void)!NEXT(write)(fd, line, (size_t)length);
            close(fd);
        }
    }
    const char *at = getenv("EME_KILL_AT");
    if (at != NULL && operations == atol(at)) {
        const char *number = getenv("EME_KILL_SIGNAL");
        raise(number != NULL ? atoi(number) : SIGKILL);
    }
}

ssize_t write(int fd, const void *data, size_t size)
{
    operation(watched_fd(fd), "write");
    return NEXT(write)(fd, data, size);
}

ssize_t pwrite(int fd, const void *data, size_t size, off_t offset)
{
    operation(watched_fd(fd), "pwrite");
    return NEXT(pwrite)(fd, data, size, offset);
}

ssize_t pwrite64(int fd, const void *data, size_t size, off_t offset)
{
    return pwrite(fd, data, size, offset);
}

int ftruncate(int fd, off_t length)
{
    operation(watched_fd(fd), "ftruncate");
    return NEXT(ftruncate)(fd, length);
}

int ftruncate64(int fd, off_t length)
{
    return ftruncate(fd, length);
}

int truncate(const char *path, off_t length)
{
    operation(watched_path(path), "truncate");
    return NEXT(truncate)(path, length);
}

int posix_fallocate(int fd, off_t offset, off_t length)
{
    operation(watched_fd(fd), "posix_fallocate");
    return NEXT(posix_fallocate)(fd, offset, length);
}

int posix_fallocate64(int fd, off_t offset, off_t length)
{
    return posix_fallocate(fd, offset, length);
}

int rename(const char *from, const char *to)
{
    operation(watched_path(from) || watched_path(to), "rename");
    return NEXT(rename)(from, to);
}

int renameat2(int from_directory, const char *from, int to_directory, const char *to, unsigned int flags)
{
    if ((flags & RENAME_EXCHANGE) && getenv("EME_KILL_NO_EXCHANGE") != NULL) {
        errno = EINVAL;
        return -1;
    }
    operation(watched_path(from) || watched_path(to), "renameat2");
    return NEXT(renameat2)(from_directory, from, to_directory, to, flags);
}

int link(const char *from, const char *to)
{
    if (getenv("EME_KILL_NO_LINK") != NULL) {
        errno = EPERM;
        return -1;
    }
    operation(watched_path(from) || watched_path(to), "link");
    return NEXT(link)(from, to);
}

int unlink(const char *path)
{
    operation(watched_path(path), "unlink");
    return NEXT(unlink)(path);
}
