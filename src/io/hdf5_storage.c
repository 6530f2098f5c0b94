/* How the code's HDF5 files reach the disk, so that a full disk or a kill never leaves a file
 * that lies (docs/faults.md):
 *  - a new file is built in memory (HDF5's core driver) and written in one checked write, so
 *    HDF5 itself never meets a write error on creation;
 *  - later writes (appended rows, final attributes) happen in a window: disk space for them is
 *    reserved first (posix_fallocate: a full disk is reported there, by the OS, before HDF5
 *    writes anything), then the file is opened, written and closed. A run writes its windows in
 *    a spare copy and then exchanges the names (src/io/crash_safe_file.f90), because a kill inside
 *    HDF5's writes can leave a file that HDF5 cannot read: the file under the run's name is
 *    always closed and whole;
 *  - a file written whole is checked by its size on disk; one grown in windows is read back.
 * HDF5 1.10 crashes at exit after a failed H5Fclose (HDFFV-11052); with the space reserved,
 * closes do not fail for want of space. Called from Fortran through bind(C)
 * (src/io/hdf5_files.f90). Functions return 0 on success, an errno value for an OS failure,
 * or -1 for an HDF5 failure. */
#define _DEFAULT_SOURCE /* flock, usleep */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

int eme_write_whole_file(const char *path, const void *data, long size, int sync);  /* posix_files.c */
int eme_reserve_space(const char *path, long bytes);                              /* posix_files.c */
int eme_h5_read_text_attribute(hid_t object, const char *name, char *text, int capacity);  /* hdf5_text.c */

/* A new, empty HDF5 file in memory (core driver, no backing store); `label` names it in HDF5's
 * list of open files and must differ between files open at once. */
int eme_h5_create_in_memory(const char *label, hid_t *file)
{
    hid_t access = H5Pcreate(H5P_FILE_ACCESS);
    if (access < 0) return -1;
    int status = -1;
    if (H5Pset_fapl_core(access, 64 * 1024, 0) >= 0) {
        *file = H5Fcreate(label, H5F_ACC_TRUNC, H5P_DEFAULT, access);
        if (*file >= 0) status = 0;
    }
    H5Pclose(access);
    return status;
}

/* The size of the image of the in-memory file `file` (flushed first), or -1. */
long eme_h5_image_size(hid_t file)
{
    if (H5Fflush(file, H5F_SCOPE_GLOBAL) < 0) return -1;
    ssize_t size = H5Fget_file_image(file, NULL, 0);
    return size > 0 ? (long)size : -1;
}

/* Copies the image of `file` (of `size` bytes: eme_h5_image_size) into `image`. */
int eme_h5_copy_image(hid_t file, void *image, long size)
{
    return H5Fget_file_image(file, image, (size_t)size) == (ssize_t)size ? 0 : -1;
}

/* A writable in-memory file (core driver, no backing store) that starts as a copy of `image`
 * (`size` bytes); `label` as for eme_h5_create_in_memory. */
int eme_h5_open_image(const char *label, const void *image, long size, hid_t *file)
{
    *file = -1;
    hid_t access = H5Pcreate(H5P_FILE_ACCESS);
    if (access < 0) return -1;
    if (H5Pset_fapl_core(access, 64 * 1024, 0) >= 0 && H5Pset_file_image(access, (void *)image, (size_t)size) >= 0)
        *file = H5Fopen(label, H5F_ACC_RDWR, access);
    H5Pclose(access);
    return *file >= 0 ? 0 : -1;
}

/* What eme_h5_numeric_datasets gathers. */
typedef struct {
    char *names;
    int capacity, used;
    int64_t *offsets, *sizes;
    int count, room, status;
} numeric_list;

/* For each dataset of the root group of native doubles or ints: its name and where its values
 * lie in the file (H5Literate callback). */
static herr_t list_numeric(hid_t group, const char *name, const H5L_info_t *info, void *data)
{
    (void)info;
    numeric_list *list = data;
    hid_t dataset = H5Dopen2(group, name, H5P_DEFAULT);
    if (dataset < 0) return list->status = -1;
    hid_t type = H5Dget_type(dataset);
    int numeric = type >= 0 && (H5Tequal(type, H5T_NATIVE_DOUBLE) > 0 || H5Tequal(type, H5T_NATIVE_INT) > 0);
    if (numeric) {
        haddr_t offset = H5Dget_offset(dataset);
        hsize_t size = H5Dget_storage_size(dataset);
        size_t length = strlen(name);
        if (size > 0 && offset == HADDR_UNDEF) list->status = 1;     /* chunked: not in one place */
        else if (list->count == list->room || list->used + (int)length + 2 > list->capacity) list->status = -1;
        else {
            memcpy(list->names + list->used, name, length);
            list->names[list->used + length] = '\n';
            list->used += (int)length + 1;
            list->offsets[list->count] = size > 0 ? (int64_t)offset : 0;
            list->sizes[list->count] = (int64_t)size;
            list->count++;
        }
    }
    if (type >= 0) H5Tclose(type);
    H5Dclose(dataset);
    return list->status == 0 ? 0 : 1;
}

/* The root group's datasets of native doubles or ints in `file`: their names, each ended by a
 * newline, in `names` (NUL-terminated, `capacity` bytes), and the offset and size in bytes of
 * each one's values in the file, in `offsets` and `sizes` (*count of them at most; on return,
 * how many). Returns 0, 1 if one of them is not stored in one place (chunked), -1 on an HDF5
 * error or too little room. */
int eme_h5_numeric_datasets(hid_t file, char *names, int capacity, int64_t *offsets, int64_t *sizes, int *count)
{
    numeric_list list = {names, capacity, 0, offsets, sizes, 0, *count, 0};
    hsize_t position = 0;
    if (capacity < 1) return -1;
    if (H5Literate(file, H5_INDEX_NAME, H5_ITER_NATIVE, &position, list_numeric, &list) < 0) list.status = -1;
    names[list.used] = '\0';
    *count = list.count;
    return list.status;
}

int eme_rename_file(const char *from, const char *to, int sync);                 /* posix_files.c */

/* Writes the image of the in-memory file `file` as the whole of `path` (fsync'd with `sync`):
 * as path.tmp, checked to hold the image's size, renamed to `path`, so that `path` is never a
 * partial file. `file` stays open. An OS failure removes the partial file and returns errno; a
 * file of the wrong size gives -2. */
int eme_h5_store_image(hid_t file, const char *path, int sync)
{
    if (H5Fflush(file, H5F_SCOPE_GLOBAL) < 0) return -1;
    ssize_t size = H5Fget_file_image(file, NULL, 0);
    if (size <= 0) return -1;
    void *image = malloc((size_t)size);
    if (image == NULL) return -1;
    int status = -1;
    char temporary[4096];
    if (snprintf(temporary, sizeof temporary, "%s.tmp", path) >= (int)sizeof temporary) status = ENAMETOOLONG;
    else if (H5Fget_file_image(file, image, (size_t)size) == size) {
        status = eme_write_whole_file(temporary, image, (long)size, sync);
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
    if (writable) {
        int error = eme_reserve_space(path, reserve);
        if (error != 0) return error;
    }
    hid_t access = H5Pcreate(H5P_FILE_ACCESS);
    if (access < 0) return -1;
    unsigned mode = writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY;
    if (!unlocked) *file = H5Fopen(path, mode, access);
    if (*file < 0 && writable && H5Pset_file_locking(access, 0, 1) >= 0) *file = H5Fopen(path, mode, access);
    H5Pclose(access);
    if (*file < 0 && writable) (void)truncate(path, before.st_size);   /* give the reservation back */
    return *file >= 0 ? 0 : -1;
}

/* First dimension of dataset `name` in `file`, or -1. */
long eme_h5_dataset_rows(hid_t file, const char *name)
{
    hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    if (dataset < 0) return -1;
    hid_t space = H5Dget_space(dataset);
    hsize_t dims[H5S_MAX_RANK];
    long rows = -1;
    if (space >= 0 && H5Sget_simple_extent_ndims(space) >= 1 && H5Sget_simple_extent_dims(space, dims, NULL) >= 1)
        rows = (long)dims[0];
    if (space >= 0) H5Sclose(space);
    H5Dclose(dataset);
    return rows;
}

typedef struct {
    long steps;
    int mismatches;
    int datasets;
} row_check;

/* For each dataset of the root group: a `rows` attribute of 'point' needs steps + 1 rows, of
 * 'step' steps rows. */
static herr_t check_rows(hid_t group, const char *name, const H5L_info_t *info, void *data)
{
    (void)info;
    row_check *check = data;
    hid_t dataset = H5Oopen(group, name, H5P_DEFAULT);
    if (dataset < 0) {
        check->mismatches++;
        return 0;
    }
    if (H5Iget_type(dataset) != H5I_DATASET) {
        H5Oclose(dataset);
        return 0;
    }
    char rows[16] = "";
    if (eme_h5_read_text_attribute(dataset, "rows", rows, (int)sizeof rows) == 0) {
        long expected = strcmp(rows, "point") == 0 ? check->steps + 1 : strcmp(rows, "step") == 0 ? check->steps : -1;
        long found = eme_h5_dataset_rows(group, name);
        check->datasets++;
        if (expected >= 0 && found != expected) check->mismatches++;
    }
    H5Oclose(dataset);
    return 0;
}

/* The integer root attribute `name` of `file`, or -1 if it is missing or unreadable. */
static long long integer_attribute(hid_t file, const char *name)
{
    long long value = -1;
    if (H5Aexists(file, name) <= 0) return -1;
    hid_t attribute = H5Aopen(file, name, H5P_DEFAULT);
    if (attribute < 0) return -1;
    if (H5Aread(attribute, H5T_NATIVE_LLONG, &value) < 0) value = -1;
    H5Aclose(attribute);
    return value;
}

/* Reads a run file back: its `status` into `status` (capacity bytes) and `steps_completed`, and
 * checks that every per-point dataset has R + 1 rows and every per-step dataset R rows, R being
 * the attribute step_rows (a row can stand for several steps: &output every), or
 * steps_completed in files without it. Returns 0 if all holds, 1 if the file cannot be opened,
 * 2 if status or steps_completed is missing, 3 if a dataset has the wrong length or cannot be
 * read. */
int eme_h5_check_run_file(const char *path, char *status, int capacity, long *steps_completed)
{
    hid_t file;
    status[0] = '\0';
    *steps_completed = -1;
    if (eme_h5_open_file(path, 0, 0, 0, &file) != 0) return 1;
    int result = 2;
    long long steps = integer_attribute(file, "steps_completed");
    if (eme_h5_read_text_attribute(file, "status", status, capacity) == 0 && steps >= 0) {
        long long rows = H5Aexists(file, "step_rows") > 0 ? integer_attribute(file, "step_rows") : steps;
        row_check check = {(long)rows, 0, 0};
        *steps_completed = (long)steps;
        hsize_t position = 0;
        if (rows < 0 || H5Literate(file, H5_INDEX_NAME, H5_ITER_NATIVE, &position, check_rows, &check) < 0)
            check.mismatches++;
        result = check.mismatches == 0 && check.datasets > 0 ? 0 : 3;
    }
    if (H5Fclose(file) < 0 && result == 0) result = 1;
    return result;
}
