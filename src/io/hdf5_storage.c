/* How the code's HDF5 files reach the disk, so that a full disk or a kill never leaves a file
 * that lies (docs/faults.md):
 *  - a new file is built in memory (HDF5's core driver: hdf5_file_image.c) and written in one
 *    checked write, so HDF5 itself never meets a write error on creation;
 *  - later writes (appended rows, final attributes) happen in a window: disk space for them is
 *    reserved first (posix_fallocate: a full disk is reported there, by the OS, before HDF5
 *    writes anything), then the file is opened, written and closed. A run writes its windows in
 *    a spare copy and then exchanges the names (src/io/crash_safe_file.f90), because a kill inside
 *    HDF5's writes can leave a file that HDF5 cannot read: the file under the run's name is
 *    always closed and whole;
 *  - a file written whole is checked by its size on disk; one grown in windows is read back
 *    (hdf5_run_file_check.c).
 * HDF5 1.10 crashes at exit after a failed H5Fclose (HDFFV-11052); with the space reserved,
 * closes do not fail for want of space. Called from Fortran through bind(C)
 * (src/io/hdf5_files.f90). Functions return 0 on success, an errno value for an OS failure,
 * or -1 for an HDF5 failure. The file in memory and its image are hdf5_file_image.c's. */
#define _DEFAULT_SOURCE /* flock, usleep */
#include <errno.h>
#include <fcntl.h>
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

int eme_write_whole_file(const char *path, const void *data, long size, int sync);  /* posix_files.c */
int eme_reserve_space(const char *path, long bytes);                              /* posix_files.c */
int eme_rename_file(const char *from, const char *to, int sync);                 /* posix_files.c */
int eme_h5_texts_begin(hid_t file, int read_back);                                /* hdf5_text_checksum.c */
void eme_h5_texts_end(hid_t file);                                                /* hdf5_text_checksum.c */
int eme_h5_texts_move(hid_t from, hid_t to);                                      /* hdf5_text_checksum.c */
long eme_h5_image_size(hid_t file);                                               /* hdf5_file_image.c */
int eme_h5_copy_image(hid_t file, void *image, long size);                        /* hdf5_file_image.c */

/* Writes the image of the in-memory file `file` as the whole of `path` (fsync'd with `sync`):
 * as path.tmp, checked to hold the image's size, renamed to `path`, so that `path` is never a
 * partial file. `file` stays open. An OS failure removes the partial file and returns errno; a
 * file of the wrong size gives -2. */
int eme_h5_store_image(hid_t file, const char *path, int sync)
{
    long size = eme_h5_image_size(file);
    if (size < 0) return -1;
    void *image = malloc((size_t)size);
    if (image == NULL) return -1;
    int status = -1;
    char temporary[4096];
    if (snprintf(temporary, sizeof temporary, "%s.tmp", path) >= (int)sizeof temporary) status = ENAMETOOLONG;
    else if (eme_h5_copy_image(file, image, size) == 0) {
        status = eme_write_whole_file(temporary, image, size, sync);
        struct stat written;
        if (status == 0 && (stat(temporary, &written) != 0 || written.st_size != (off_t)size)) {
            unlink(temporary);
            status = -2;      /* the file system does not hold what was written */
        }
        if (status == 0) status = eme_rename_file(temporary, path, sync);
    }
    free(image);
    return status;
}

/* 1 if another process holds a lock on `path` (HDF5 readers take a shared one while open). */
static int locked_by_other(const char *path)
{
    int fd = open(path, O_RDONLY);
    if (fd < 0) return 0;
    int locked = flock(fd, LOCK_EX | LOCK_NB) != 0 && (errno == EWOULDBLOCK || errno == EAGAIN);
    close(fd);                           /* releases the lock if it was taken */
    return locked;
}

/* Opens the existing file `path`: read-only, or for writing after reserving `reserve` bytes of
 * disk space for what the window will add. A writer takes HDF5's file lock, so that readers do
 * not open the file half-written. While a reader holds the file open, `wait_ms` < 0 returns -3
 * at once (the caller writes later); otherwise it waits up to wait_ms, then writes without the
 * lock rather than stall the run. */
int eme_h5_open_file(const char *path, int writable, long reserve, int wait_ms, hid_t *file)
{
    *file = -1;
    int unlocked = 0;
    if (writable) {
        for (int waited = 0; locked_by_other(path); waited += 10) {
            if (wait_ms < 0) return -3;
            if (waited >= wait_ms) {
                unlocked = 1;
                break;
            }
            usleep(10000);
        }
    }
    struct stat before;
    if (writable && stat(path, &before) != 0) return errno;
    /* A writer's texts are read back first, for the checksum it writes at the close
     * (hdf5_text_checksum.c), in an open of their own: read in the writer's open, the global heap
     * would take the new texts where it has room, and the file operations would depend on the
     * texts' lengths. */
    hid_t reader = -1;
    if (writable) {
        hid_t quiet = H5Pcreate(H5P_FILE_ACCESS);
        if (quiet >= 0 && H5Pset_file_locking(quiet, 0, 1) >= 0) reader = H5Fopen(path, H5F_ACC_RDONLY, quiet);
        if (quiet >= 0) H5Pclose(quiet);
        int read = reader >= 0 && eme_h5_texts_begin(reader, 1) == 0;
        if (reader >= 0) H5Fclose(reader);
        if (!read) return -1;
        int error = eme_reserve_space(path, reserve);
        if (error != 0) {
            eme_h5_texts_end(reader);
            return error;
        }
    }
    hid_t access = H5Pcreate(H5P_FILE_ACCESS);
    if (access < 0) return -1;
    unsigned mode = writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY;
    if (!unlocked) *file = H5Fopen(path, mode, access);
    if (*file < 0 && writable && H5Pset_file_locking(access, 0, 1) >= 0) *file = H5Fopen(path, mode, access);
    H5Pclose(access);
    if (writable && eme_h5_texts_move(reader, *file) != 0 && *file >= 0) {
        H5Fclose(*file);
        *file = -1;
    }
    if (*file < 0 && writable) (void)truncate(path, before.st_size);   /* give the reservation back */
    return *file >= 0 ? 0 : -1;
}
