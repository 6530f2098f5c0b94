/* File-system operations for the Fortran code that standard Fortran lacks or cannot check:
 * directories, atomic rename, exchange and copy, whole-file writes and line appends with their OS
 * error, disk space reserved ahead of a write, the lock that makes one process the only writer
 * of an output, and whether stderr is a terminal. Each returns 0 on success or the errno value
 * of the failure (eme_os_error_text turns it into the OS's words). */
#define _GNU_SOURCE /* renameat2 */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

/* The OS's text for error number `error` ("No space left on device"), NUL-terminated. */
void eme_os_error_text(int error, char *text, int capacity)
{
    if (capacity < 1) return;
    const char *words = strerror(error);
    snprintf(text, (size_t)capacity, "%s", words != NULL ? words : "unknown error");
}

/* mkdir -p: create `path` and any missing parents. */
int eme_make_directories(const char *path)
{
    char partial[4096];
    size_t length = strlen(path);
    if (length == 0) return EINVAL;
    if (length >= sizeof partial) return ENAMETOOLONG;
    memcpy(partial, path, length + 1);
    for (char *cursor = partial + 1; *cursor != '\0'; ++cursor) {
        if (*cursor != '/') continue;
        *cursor = '\0';
        if (mkdir(partial, 0777) != 0 && errno != EEXIST) return errno;
        *cursor = '/';
    }
    if (mkdir(partial, 0777) != 0 && errno != EEXIST) return errno;
    return 0;
}

/* Makes the directory entry of `path` durable (fsync of its directory; a no-op where the file
 * system refuses directories). */
static void sync_directory_of(const char *path)
{
    char directory[4096];
    const char *slash = strrchr(path, '/');
    if (slash == NULL) snprintf(directory, sizeof directory, ".");
    else if (slash == path) snprintf(directory, sizeof directory, "/");
    else snprintf(directory, sizeof directory, "%.*s", (int)(slash - path), path);
    int fd = open(directory, O_RDONLY);
    if (fd < 0) return;
    (void)fsync(fd);
    close(fd);
}

/* rename(2), atomic within one file system; with `sync`, the directory is synced after. */
int eme_rename_file(const char *from, const char *to, int sync)
{
    if (rename(from, to) != 0) return errno;
    if (sync) sync_directory_of(to);
    return 0;
}

static int write_all(int fd, const char *data, size_t size);

/* Copies the file `from` as the whole of `to`: written as `to`.tmp and renamed, so that `to` is
 * never a partial copy, and a process that has the old `to` open keeps it as it was. */
int eme_copy_file(const char *from, const char *to)
{
    char temporary[4096];
    if (snprintf(temporary, sizeof temporary, "%s.tmp", to) >= (int)sizeof temporary) return ENAMETOOLONG;
    int in = open(from, O_RDONLY);
    if (in < 0) return errno;
    int out = open(temporary, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    if (out < 0) {
        int error = errno;
        close(in);
        return error;
    }
    static char block[1 << 20];
    int error = 0;
    for (;;) {
        ssize_t got = read(in, block, sizeof block);
        if (got < 0 && errno == EINTR) continue;
        if (got <= 0) {
            if (got < 0) error = errno;
            break;
        }
        error = write_all(out, block, (size_t)got);
        if (error != 0) break;
    }
    if (close(out) != 0 && error == 0) error = errno;
    close(in);
    if (error == 0 && rename(temporary, to) != 0) error = errno;
    if (error != 0) (void)unlink(temporary);
    return error;
}

/* Gives `newer` the name `path` and the old file at `path` the name `newer`, so that `path`
 * names a whole file at every instant. Where the file system cannot exchange two names in one
 * step (NFS, Lustre: renameat2 EINVAL), the old file is kept by a hard link `path`.kept while
 * `newer` is renamed over `path`; where it has no hard links either, `newer` is renamed over
 * `path` and copied back to `newer`. */
int eme_exchange_files(const char *newer, const char *path)
{
    if (renameat2(AT_FDCWD, newer, AT_FDCWD, path, RENAME_EXCHANGE) == 0) return 0;
    if (errno != EINVAL && errno != ENOSYS && errno != EOPNOTSUPP) return errno;
    char kept[4096];
    if (snprintf(kept, sizeof kept, "%s.kept", path) >= (int)sizeof kept) return ENAMETOOLONG;
    (void)unlink(kept);
    if (link(path, kept) == 0) {
        if (rename(newer, path) != 0) {
            int error = errno;
            (void)unlink(kept);
            return error;
        }
        return rename(kept, newer) == 0 ? 0 : errno;
    }
    if (errno != EPERM && errno != EOPNOTSUPP && errno != ENOSYS) return errno;
    if (rename(newer, path) != 0) return errno;
    return eme_copy_file(path, newer);
}

/* unlink(2); a missing file is not an error. */
int eme_remove_file(const char *path)
{
    if (unlink(path) != 0 && errno != ENOENT) return errno;
    return 0;
}

/* 1 if `path` names an existing regular file, 0 if not. */
int eme_file_exists(const char *path)
{
    struct stat info;
    return stat(path, &info) == 0 && S_ISREG(info.st_mode) ? 1 : 0;
}

static int write_all(int fd, const char *data, size_t size)
{
    while (size > 0) {
        ssize_t done = write(fd, data, size);
        if (done < 0) {
            if (errno == EINTR) continue;
            return errno;
        }
        data += done;
        size -= (size_t)done;
    }
    return 0;
}

/* Writes `size` bytes as the whole content of `path` (created or truncated); with `sync` the
 * data are on disk (fsync) before it returns. On failure the partial file is removed. */
int eme_write_whole_file(const char *path, const void *data, long size, int sync)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    if (fd < 0) return errno;
    int error = write_all(fd, data, (size_t)size);
    if (error == 0 && sync && fsync(fd) != 0) error = errno;
    if (close(fd) != 0 && error == 0) error = errno;
    if (error != 0) unlink(path);
    return error;
}

/* Appends `length` bytes (one or more whole lines) to `path`, creating it; with `sync`, fsync.
 * A short append is cut back, so the file never ends in a partial line. */
int eme_append_text(const char *path, const char *text, long length, int sync)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_APPEND, 0666);
    if (fd < 0) return errno;
    struct stat info;
    int error = fstat(fd, &info) != 0 ? errno : 0;
    if (error == 0) error = write_all(fd, text, (size_t)length);
    if (error != 0) (void)ftruncate(fd, info.st_size);
    if (error == 0 && sync && fsync(fd) != 0) error = errno;
    if (close(fd) != 0 && error == 0) error = errno;
    return error;
}

/* Allocates `bytes` of disk space past the end of the existing file `path` (posix_fallocate,
 * which also extends the file), so that writes into that range cannot fail for want of space.
 * On failure the file is cut back to its old size. */
int eme_reserve_space(const char *path, long bytes)
{
    int fd = open(path, O_WRONLY);
    if (fd < 0) return errno;
    struct stat info;
    int error = fstat(fd, &info) != 0 ? errno : 0;
    if (error == 0 && bytes > 0) {
        error = posix_fallocate(fd, info.st_size, (off_t)bytes);
        if (error != 0) (void)ftruncate(fd, info.st_size);
    }
    close(fd);
    return error;
}

/* Allocates `bytes` of disk space past the end of the existing file `path` without changing its
 * size (Linux fallocate, FALLOC_FL_KEEP_SIZE): a writer that later extends the file into that
 * range (parallel HDF5 appending a snapshot) cannot fail for want of space. 0 also where the file
 * system cannot allocate ahead (EOPNOTSUPP: nothing is reserved). */
int eme_reserve_space_ahead(const char *path, long bytes)
{
    int fd = open(path, O_WRONLY);
    if (fd < 0) return errno;
    struct stat info;
    int error = fstat(fd, &info) != 0 ? errno : 0;
    if (error == 0 && bytes > 0 && fallocate(fd, FALLOC_FL_KEEP_SIZE, info.st_size, (off_t)bytes) != 0)
        error = errno == EOPNOTSUPP ? 0 : errno;
    close(fd);
    return error;
}

/* fsync(2) of an existing file: its data are on disk on return. */
int eme_sync_file(const char *path)
{
    int fd = open(path, O_RDONLY);
    if (fd < 0) return errno;
    int error = fsync(fd) != 0 ? errno : 0;
    close(fd);
    return error;
}

/* 1 if standard error is a terminal. */
int eme_stderr_is_terminal(void)
{
    return isatty(STDERR_FILENO) ? 1 : 0;
}

/* eme_lock_output's answers besides 0 and an errno value. */
enum { lock_held_elsewhere = -1, lock_not_offered = -2 };

/* The line a lock holder leaves in its lock file, as `holder` text for the refused process. */
static void read_holder(int fd, char *holder, int capacity)
{
    ssize_t got = pread(fd, holder, (size_t)capacity - 1, 0);
    if (got < 0) got = 0;
    holder[got] = '\0';
    char *end = strchr(holder, '\n');
    if (end != NULL) *end = '\0';
}

/* Makes this process the only writer of an output: an exclusive flock(2) on the lock file `path`
 * (created, with its directory), which the OS releases when the process ends, however it ends,
 * so a killed writer's lock file is no obstacle. On success *descriptor is the open lock file
 * (eme_unlock_output releases it) and the file holds a line naming this process and its host.
 * Returns 0; lock_held_elsewhere if a live process holds the lock (`holder` gets its line, or
 * ""); lock_not_offered if the file system has no working flock (ENOLCK, EOPNOTSUPP, ENOSYS:
 * some NFS and Lustre mounts); else the errno value. */
int eme_lock_output(const char *path, int *descriptor, char *holder, int capacity)
{
    *descriptor = -1;
    if (capacity < 1) return EINVAL;
    holder[0] = '\0';
    for (int attempt = 0; attempt < 100; ++attempt) {
        int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
        if (fd < 0 && errno == ENOENT) {
            char directory[4096];
            const char *slash = strrchr(path, '/');
            if (slash != NULL && slash != path) {
                snprintf(directory, sizeof directory, "%.*s", (int)(slash - path), path);
                int error = eme_make_directories(directory);
                if (error != 0) return error;
                fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
            }
        }
        if (fd < 0) return errno;
        while (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            int error = errno;
            if (error == EINTR) continue;
            if (error == EWOULDBLOCK) read_holder(fd, holder, capacity);
            close(fd);
            if (error == EWOULDBLOCK) return lock_held_elsewhere;
            if (error == ENOLCK || error == EOPNOTSUPP || error == ENOSYS) return lock_not_offered;
            return error;
        }
        /* The holder before us removes the file as it lets go; if it did so after our open, our
         * lock is on a file that no longer has the name, and a third process could lock a new
         * file of that name: then start again. */
        struct stat held, named;
        if (fstat(fd, &held) == 0 && stat(path, &named) == 0 && held.st_dev == named.st_dev &&
            held.st_ino == named.st_ino) {
            char line[512], host[256];
            if (gethostname(host, sizeof host) != 0) snprintf(host, sizeof host, "unknown");
            host[sizeof host - 1] = '\0';
            int length = snprintf(line, sizeof line, "process %ld on host %s\n", (long)getpid(), host);
            /* Only the message of a refused writer needs the line: a full disk does not stop the run. */
            if (ftruncate(fd, 0) == 0) (void)!pwrite(fd, line, (size_t)length, 0);
            *descriptor = fd;
            return 0;
        }
        close(fd);
    }
    return EAGAIN;
}

/* Whether the lock file at `path` is still the file the open `descriptor` holds locked (an
 * eme_lock_output's): 0 if so; 1 if no file has the name (it was removed); 2 if another file has
 * it (removed and made again, by another writer); -1 for descriptor -1. Anyone can remove the
 * name of a file another process has locked: the lock then guards nothing. */
int eme_lock_state(const char *path, int descriptor)
{
    struct stat held, named;
    if (descriptor < 0 || fstat(descriptor, &held) != 0) return -1;
    if (stat(path, &named) != 0) return 1;
    return held.st_dev == named.st_dev && held.st_ino == named.st_ino ? 0 : 2;
}

/* Lets go of a lock taken by eme_lock_output: removes the lock file while still holding it, if
 * the name is still that file's (never another writer's lock file), then closes it (which
 * releases the lock). Nothing to do for descriptor -1. */
void eme_unlock_output(const char *path, int descriptor)
{
    if (descriptor < 0) return;
    if (eme_lock_state(path, descriptor) == 0) (void)unlink(path);
    close(descriptor);
}
