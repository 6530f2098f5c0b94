/* A SIGKILL at a chosen file operation, for the crash-consistency test
 * (tests/e2e/test_kill_points.py): loaded with LD_PRELOAD, it counts the operations that change
 * files under the directory $EME_KILL_DIR (write, pwrite, ftruncate, truncate, posix_fallocate,
 * rename, renameat2, link, unlink) and, at the operation numbered $EME_KILL_AT (from 1), kills
 * the process with SIGKILL before that operation reaches the file system. So the files are left
 * exactly as operations 1 .. K-1 made them, which is what a kill at any instant between two
 * system calls leaves. $EME_KILL_LOG names a file that gets a line "K operation path" for each
 * operation (two paths for a rename or a link; without $EME_KILL_AT: the whole run's list).
 * $EME_KILL_MATCH counts only the operations on a path that contains its text towards
 * $EME_KILL_AT (e.g. "case_00002.h5.part.spare" and 1: the first window of a study's second
 * case), so that a test can name the event it needs instead of counting every operation before
 * it. $EME_KILL_SIGNAL names another signal by number (19, SIGSTOP: the process stops there,
 * holding what it holds, until SIGCONT lets it perform the operation and go on; 15, SIGTERM: the
 * process asks itself to stop, as a batch scheduler would). $EME_KILL_HOLD names a file instead:
 * the process holds there, sleeping, until that file exists, having written its process id to
 * $EME_KILL_HOLD.held; signals reach it meanwhile (unlike a stopped process, which mpirun would
 * wake with SIGCONT), so a test can send SIGTERM to a batch script, see the held process catch it
 * (/proc/PID/status), and then let it go on. To stand for file systems that lack
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
#include <time.h>
#include <unistd.h>

static long operations;   /* counted so far */
static long matches;      /* of them, those on a path containing $EME_KILL_MATCH */

#define NEXT(name) ((__typeof__(&name))dlsym(RTLD_NEXT, #name))

/* The absolute form of `path` in `resolved` if it lies under $EME_KILL_DIR, else NULL. */
static const char *watched_path(const char *path, char resolved[PATH_MAX])
{
    const char *directory = getenv("EME_KILL_DIR");
    if (directory == NULL || path == NULL) return NULL;
    if (path[0] != '/') {
        if (getcwd(resolved, PATH_MAX) == NULL) return NULL;
        size_t used = strlen(resolved);
        snprintf(resolved + used, PATH_MAX - used, "/%s", path);
    } else {
        snprintf(resolved, PATH_MAX, "%s", path);
    }
    size_t prefix = strlen(directory);
    return strncmp(resolved, directory, prefix) == 0 && resolved[prefix] == '/' ? resolved : NULL;
}

/* The path of open file `fd` in `resolved` if it lies under $EME_KILL_DIR, else NULL. */
static const char *watched_fd(int fd, char resolved[PATH_MAX])
{
    char link[64], path[PATH_MAX];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t length = readlink(link, path, sizeof path - 1);
    if (length <= 0) return NULL;
    path[length] = '\0';
    return watched_path(path, resolved);
}

/* Writes the process id to RELEASE.held (whole: through a temporary name) and sleeps until the
 * file RELEASE exists. */
static void hold(const char *release)
{
    char held[PATH_MAX + 8], temporary[PATH_MAX + 16], line[32];
    snprintf(held, sizeof held, "%s.held", release);
    snprintf(temporary, sizeof temporary, "%s.tmp", held);
    int fd = open(temporary, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    if (fd >= 0) {
        int length = snprintf(line, sizeof line, "%ld\n", (long)getpid());
        (void)!NEXT(write)(fd, line, (size_t)length);
        close(fd);
        NEXT(rename)(temporary, held);
    }
    const struct timespec pause = {0, 10000000};
    while (access(release, F_OK) != 0) nanosleep(&pause, NULL);
}

/* Counts one operation on the watched path(s) (NULL: not watched), logs it, and signals the
 * process if it is the chosen one. */
static void operation(const char *path, const char *other, const char *name)
{
    if (path == NULL && other == NULL) return;
    operations++;
    const char *log = getenv("EME_KILL_LOG");
    if (log != NULL) {
        int fd = open(log, O_WRONLY | O_CREAT | O_APPEND, 0666);
        if (fd >= 0) {
            char line[64 + 2 * PATH_MAX];
            int length = snprintf(line, sizeof line, "%ld %s %s%s%s\n", operations, name, path ? path : "-",
                                  other ? " " : "", other ? other : "");
            (void)!NEXT(write)(fd, line, (size_t)length < sizeof line ? (size_t)length : sizeof line - 1);
            close(fd);
        }
    }
    const char *match = getenv("EME_KILL_MATCH");
    if (match != NULL && !(path && strstr(path, match)) && !(other && strstr(other, match))) return;
    matches++;
    const char *at = getenv("EME_KILL_AT");
    if (at == NULL || matches != atol(at)) return;
    const char *release = getenv("EME_KILL_HOLD");
    if (release != NULL) {
        hold(release);
        return;
    }
    const char *number = getenv("EME_KILL_SIGNAL");
    raise(number != NULL ? atoi(number) : SIGKILL);
}

ssize_t write(int fd, const void *data, size_t size)
{
    char resolved[PATH_MAX];
    operation(watched_fd(fd, resolved), NULL, "write");
    return NEXT(write)(fd, data, size);
}

ssize_t pwrite(int fd, const void *data, size_t size, off_t offset)
{
    char resolved[PATH_MAX];
    operation(watched_fd(fd, resolved), NULL, "pwrite");
    return NEXT(pwrite)(fd, data, size, offset);
}

ssize_t pwrite64(int fd, const void *data, size_t size, off_t offset)
{
    return pwrite(fd, data, size, offset);
}

int ftruncate(int fd, off_t length)
{
    char resolved[PATH_MAX];
    operation(watched_fd(fd, resolved), NULL, "ftruncate");
    return NEXT(ftruncate)(fd, length);
}

int ftruncate64(int fd, off_t length)
{
    return ftruncate(fd, length);
}

int truncate(const char *path, off_t length)
{
    char resolved[PATH_MAX];
    operation(watched_path(path, resolved), NULL, "truncate");
    return NEXT(truncate)(path, length);
}

int posix_fallocate(int fd, off_t offset, off_t length)
{
    char resolved[PATH_MAX];
    operation(watched_fd(fd, resolved), NULL, "posix_fallocate");
    return NEXT(posix_fallocate)(fd, offset, length);
}

int posix_fallocate64(int fd, off_t offset, off_t length)
{
    return posix_fallocate(fd, offset, length);
}

int rename(const char *from, const char *to)
{
    char from_resolved[PATH_MAX], to_resolved[PATH_MAX];
    operation(watched_path(from, from_resolved), watched_path(to, to_resolved), "rename");
    return NEXT(rename)(from, to);
}

int renameat2(int from_directory, const char *from, int to_directory, const char *to, unsigned int flags)
{
    if ((flags & RENAME_EXCHANGE) && getenv("EME_KILL_NO_EXCHANGE") != NULL) {
        errno = EINVAL;
        return -1;
    }
    char from_resolved[PATH_MAX], to_resolved[PATH_MAX];
    operation(watched_path(from, from_resolved), watched_path(to, to_resolved), "renameat2");
    return NEXT(renameat2)(from_directory, from, to_directory, to, flags);
}

int link(const char *from, const char *to)
{
    if (getenv("EME_KILL_NO_LINK") != NULL) {
        errno = EPERM;
        return -1;
    }
    char from_resolved[PATH_MAX], to_resolved[PATH_MAX];
    operation(watched_path(from, from_resolved), watched_path(to, to_resolved), "link");
    return NEXT(link)(from, to);
}

int unlink(const char *path)
{
    char resolved[PATH_MAX];
    operation(watched_path(path, resolved), NULL, "unlink");
    return NEXT(unlink)(path);
}
