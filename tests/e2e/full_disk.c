/* A full disk without privileges, for the tests (tests/e2e/test_full_disk.py): loaded with
 * LD_PRELOAD, it makes the files under the directory $EME_FULL_DISK_DIR behave as if that
 * directory were a file system of $EME_FULL_DISK_BYTES bytes: a write, pwrite, (posix_)fallocate
 * or ftruncate that would make the files there hold more fails with ENOSPC, as a full tmpfs does.
 * Everything else passes through. Used where `mount -t tmpfs` is not permitted. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <ftw.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

static long long total_bytes;

static int add_size(const char *path, const struct stat *info, int kind, struct FTW *position)
{
    (void)path;
    (void)position;
    if (kind == FTW_F && S_ISREG(info->st_mode)) total_bytes += (long long)info->st_size;
    return 0;
}

/* Bytes held by the regular files under `directory` (at any depth). */
static long long used_bytes(const char *directory)
{
    total_bytes = 0;
    nftw(directory, add_size, 16, FTW_PHYS);
    return total_bytes;
}

/* 1 if making fd's file reach `end` bytes would overfill the simulated file system. */
static int overfills(int fd, long long end)
{
    const char *directory = getenv("EME_FULL_DISK_DIR");
    const char *capacity = getenv("EME_FULL_DISK_BYTES");
    if (directory == NULL || capacity == NULL) return 0;
    char link[64], path[PATH_MAX];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t length = readlink(link, path, sizeof path - 1);
    if (length <= 0) return 0;
    path[length] = '\0';
    size_t prefix = strlen(directory);
    if (strncmp(path, directory, prefix) != 0 || path[prefix] != '/') return 0;
    struct stat info;
    if (fstat(fd, &info) != 0 || end <= (long long)info.st_size) return 0;
    return used_bytes(directory) + (end - (long long)info.st_size) > atoll(capacity);
}

#define NEXT(name) ((__typeof__(&name))dlsym(RTLD_NEXT, #name))

ssize_t write(int fd, const void *data, size_t size)
{
    off_t at = lseek(fd, 0, SEEK_CUR);
    if (at >= 0 && (fcntl(fd, F_GETFL) & O_APPEND)) {
        struct stat info;
        if (fstat(fd, &info) == 0) at = info.st_size;
    }
    if (at >= 0 && overfills(fd, (long long)at + (long long)size)) {
        errno = ENOSPC;
        return -1;
    }
    return NEXT(write)(fd, data, size);
}

ssize_t pwrite(int fd, const void *data, size_t size, off_t offset)
{
    if (overfills(fd, (long long)offset + (long long)size)) {
        errno = ENOSPC;
        return -1;
    }
    return NEXT(pwrite)(fd, data, size, offset);
}

ssize_t pwrite64(int fd, const void *data, size_t size, off_t offset)
{
    return pwrite(fd, data, size, offset);
}

int posix_fallocate(int fd, off_t offset, off_t length)
{
    if (overfills(fd, (long long)offset + (long long)length)) return ENOSPC;
    return NEXT(posix_fallocate)(fd, offset, length);
}

int posix_fallocate64(int fd, off_t offset, off_t length)
{
    return posix_fallocate(fd, offset, length);
}

/* Linux fallocate: one that keeps the size (FALLOC_FL_KEEP_SIZE, a reservation ahead of the
 * writes: hdf5_snapshot_storage.c) is refused when its range would overfill; the file's size,
 * which this shim counts, does not change until the writes come. */
int fallocate(int fd, int mode, off_t offset, off_t length)
{
    if (overfills(fd, (long long)offset + (long long)length)) {
        errno = ENOSPC;
        return -1;
    }
    return NEXT(fallocate)(fd, mode, offset, length);
}

int fallocate64(int fd, int mode, off_t offset, off_t length)
{
    return fallocate(fd, mode, offset, length);
}

int ftruncate(int fd, off_t length)
{
    if (overfills(fd, (long long)length)) {
        errno = ENOSPC;
        return -1;
    }
    return NEXT(ftruncate)(fd, length);
}

int ftruncate64(int fd, off_t length)
{
    return ftruncate(fd, length);
}
