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
#include <float.h>
#include <math.h>
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
int eme_h5_verify_texts(hid_t file);                                              /* hdf5_text_checksum.c */
int eme_h5_texts_begin(hid_t file, int read_back);                                /* hdf5_text_checksum.c */
void eme_h5_texts_end(hid_t file);                                                /* hdf5_text_checksum.c */
int eme_h5_texts_move(hid_t from, hid_t to);                                      /* hdf5_text_checksum.c */

/* A new, empty HDF5 file in memory (core driver, no backing store); `label` names it in HDF5's
 * list of open files and must differ between files open at once. Its format is HDF5 1.8's
 * (readable by HDF5 1.8 and later): its superblock, object headers (the attributes among them)
 * and attribute heaps carry checksums, so that a damaged byte there fails to read rather than
 * read as another value (the datasets' values carry theirs: Fletcher-32, hdf5_series). Not
 * 1.10's format: its superblock marks a file open for writing, and a killed writer would leave
 * it unreadable without h5clear. */
int eme_h5_create_in_memory(const char *label, hid_t *file)
{
    hid_t access = H5Pcreate(H5P_FILE_ACCESS);
    hid_t creation = H5Pcreate(H5P_FILE_CREATE);
    int status = -1;
    /* Every dataset is chunked (its checksum): B-tree nodes of 2 x 4 chunks rather than 2 x 32
     * keep the index of a one-chunk dataset at a tenth of its default 2.5 kB. */
    if (access >= 0 && creation >= 0 && H5Pset_fapl_core(access, 64 * 1024, 0) >= 0 &&
        H5Pset_libver_bounds(access, H5F_LIBVER_V18, H5F_LIBVER_V18) >= 0 && H5Pset_istore_k(creation, 4) >= 0) {
        *file = H5Fcreate(label, H5F_ACC_TRUNC, creation, access);
        if (*file >= 0) status = eme_h5_texts_begin(*file, 0);
    }
    if (creation >= 0) H5Pclose(creation);
    if (access >= 0) H5Pclose(access);
    return status;
}

/* HDF5's checksum of metadata (H5_checksum_lookup3 of H5checksum.c, Bob Jenkins' lookup3 hash
 * taken byte by byte, initial value 0). */
static uint32_t metadata_checksum(const unsigned char *k, size_t length)
{
#define EME_ROT(x, r) (((x) << (r)) | ((x) >> (32 - (r))))
    uint32_t a, b, c;
    a = b = c = 0xdeadbeef + (uint32_t)length;
    while (length > 12) {
        a += k[0] + ((uint32_t)k[1] << 8) + ((uint32_t)k[2] << 16) + ((uint32_t)k[3] << 24);
        b += k[4] + ((uint32_t)k[5] << 8) + ((uint32_t)k[6] << 16) + ((uint32_t)k[7] << 24);
        c += k[8] + ((uint32_t)k[9] << 8) + ((uint32_t)k[10] << 16) + ((uint32_t)k[11] << 24);
        a -= c; a ^= EME_ROT(c, 4);  c += b;
        b -= a; b ^= EME_ROT(a, 6);  a += c;
        c -= b; c ^= EME_ROT(b, 8);  b += a;
        a -= c; a ^= EME_ROT(c, 16); c += b;
        b -= a; b ^= EME_ROT(a, 19); a += c;
        c -= b; c ^= EME_ROT(b, 4);  b += a;
        length -= 12;
        k += 12;
    }
    switch (length) {   /* the last bytes; each case falls through */
    case 12: c += (uint32_t)k[11] << 24; /* fall through */
    case 11: c += (uint32_t)k[10] << 16; /* fall through */
    case 10: c += (uint32_t)k[9] << 8;   /* fall through */
    case 9: c += k[8];                   /* fall through */
    case 8: b += (uint32_t)k[7] << 24;   /* fall through */
    case 7: b += (uint32_t)k[6] << 16;   /* fall through */
    case 6: b += (uint32_t)k[5] << 8;    /* fall through */
    case 5: b += k[4];                   /* fall through */
    case 4: a += (uint32_t)k[3] << 24;   /* fall through */
    case 3: a += (uint32_t)k[2] << 16;   /* fall through */
    case 2: a += (uint32_t)k[1] << 8;    /* fall through */
    case 1: a += k[0]; break;
    case 0: return c;
    }
    c ^= b; c -= EME_ROT(b, 14);
    a ^= c; a -= EME_ROT(c, 11);
    b ^= a; b -= EME_ROT(a, 25);
    c ^= b; c -= EME_ROT(b, 16);
    a ^= c; a -= EME_ROT(c, 4);
    b ^= a; b -= EME_ROT(a, 14);
    c ^= b; c -= EME_ROT(b, 24);
#undef EME_ROT
    return c;
}

/* The image of the in-memory file `file` in `image` (`size` bytes: H5Fget_file_image). HDF5
 * 1.10 clears the superblock's status flags in the image but leaves the checksum it computed
 * with them set, so that the image would not open (superblock versions 2 and 3, with a
 * checksum): the checksum is computed again here. */
static int file_image(hid_t file, void *image, size_t size)
{
    if (H5Fget_file_image(file, image, size) != (ssize_t)size) return -1;
    unsigned char *bytes = image;
    if (size >= 12 && (bytes[8] == 2 || bytes[8] == 3)) {
        size_t length = 12 + 4 * (size_t)bytes[9];   /* signature .. root group address */
        if (length + 4 > size) return -1;
        uint32_t sum = metadata_checksum(bytes, length);
        for (int i = 0; i < 4; ++i) bytes[length + i] = (unsigned char)(sum >> (8 * i));
    }
    return 0;
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
    return file_image(file, image, (size_t)size);
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

/* HDF5's Fletcher-32 checksum of `size` bytes (H5_checksum_fletcher32 of HDF5's H5checksum.c,
 * which the filter H5Z_FILTER_FLETCHER32 appends to every chunk, little-endian): 16-bit words,
 * most significant byte first, summed modulo 65535 in two running sums. */
static uint32_t fletcher32(const unsigned char *data, size_t size)
{
    uint32_t sum1 = 0, sum2 = 0;
    size_t words = size / 2;
    while (words > 0) {
        size_t block = words > 360 ? 360 : words;     /* the most sums without overflow */
        words -= block;
        do {
            sum1 += (uint32_t)((data[0] << 8) | data[1]);
            data += 2;
            sum2 += sum1;
        } while (--block);
        sum1 = (sum1 & 0xffff) + (sum1 >> 16);
        sum2 = (sum2 & 0xffff) + (sum2 >> 16);
    }
    if (size % 2) {
        sum1 += (uint32_t)(*data << 8);
        sum2 += sum1;
        sum1 = (sum1 & 0xffff) + (sum1 >> 16);
        sum2 = (sum2 & 0xffff) + (sum2 >> 16);
    }
    sum1 = (sum1 & 0xffff) + (sum1 >> 16);
    sum2 = (sum2 & 0xffff) + (sum2 >> 16);
    return (sum2 << 16) | sum1;
}

/* Writes the Fletcher-32 checksum of the `size` bytes at `data` into the 4 bytes after them, as
 * HDF5's filter stores it at the end of a chunk: a chunk whose values were put in place in a
 * file image (src/io/hdf5_file_templates.f90) then reads back as if HDF5 had written it. */
void eme_h5_seal_chunk(void *data, long size)
{
    unsigned char *bytes = data;
    uint32_t sum = fletcher32(bytes, (size_t)size);
    for (int i = 0; i < 4; ++i) bytes[size + i] = (unsigned char)(sum >> (8 * i));
}

/* What eme_h5_numeric_datasets gathers. */
typedef struct {
    char *names;
    int capacity, used;
    int64_t *offsets, *sizes;
    int *sealed;
    int count, room, status;
    const unsigned char *image;     /* the file's image, to check the stored checksums against */
    long image_size;
} numeric_list;

/* Where the values of `dataset` lie in the file, if in one place: contiguous (*sealed = 0), or
 * one chunk filtered by Fletcher-32 alone whose stored checksum is the one fletcher32 computes
 * (*sealed = 1: the checksum follows the values). 0 if so, 1 if not. */
static int values_in_one_place(hid_t dataset, const numeric_list *list, haddr_t *offset, hsize_t *size, int *sealed)
{
    *sealed = 0;
    *size = H5Dget_storage_size(dataset);
    *offset = H5Dget_offset(dataset);
    if (*size == 0 || *offset != HADDR_UNDEF) return 0;
    hid_t creation = H5Dget_create_plist(dataset);
    hid_t space = H5Dget_space(dataset);
    int result = 1;
    unsigned flags, mask;
    size_t elements = 0;
    unsigned int config;
    char filter_name[16];
    hsize_t chunks = 0, origin[H5S_MAX_RANK] = {0};
    haddr_t address;
    hsize_t stored;
    hid_t type = H5Dget_type(dataset);
    size_t type_size = type >= 0 ? H5Tget_size(type) : 0;
    if (type >= 0) H5Tclose(type);
    if (creation >= 0 && space >= 0 && H5Pget_nfilters(creation) == 1 &&
        H5Pget_filter2(creation, 0, &flags, &elements, NULL, sizeof filter_name, filter_name, &config) ==
            H5Z_FILTER_FLETCHER32 &&
        H5Dget_num_chunks(dataset, space, &chunks) >= 0 && chunks == 1 &&
        H5Dget_chunk_info(dataset, space, 0, origin, &mask, &address, &stored) >= 0 && mask == 0) {
        hssize_t values = H5Sget_simple_extent_npoints(space);
        hsize_t bytes = values > 0 ? (hsize_t)values * type_size : 0;
        if (bytes > 0 && stored == bytes + 4 && address + stored <= (haddr_t)list->image_size) {
            uint32_t sum = fletcher32(list->image + address, (size_t)bytes);
            const unsigned char *kept = list->image + address + bytes;
            if (kept[0] == (sum & 0xff) && kept[1] == ((sum >> 8) & 0xff) && kept[2] == ((sum >> 16) & 0xff) &&
                kept[3] == (sum >> 24)) {
                *offset = address;
                *size = bytes;
                *sealed = 1;
                result = 0;
            }
        }
    }
    if (space >= 0) H5Sclose(space);
    if (creation >= 0) H5Pclose(creation);
    return result;
}

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
        haddr_t offset;
        hsize_t size;
        int sealed;
        size_t length = strlen(name);
        if (values_in_one_place(dataset, list, &offset, &size, &sealed) != 0) list->status = 1;
        else if (list->count == list->room || list->used + (int)length + 2 > list->capacity) list->status = -1;
        else {
            memcpy(list->names + list->used, name, length);
            list->names[list->used + length] = '\n';
            list->used += (int)length + 1;
            list->offsets[list->count] = size > 0 ? (int64_t)offset : 0;
            list->sizes[list->count] = (int64_t)size;
            list->sealed[list->count] = sealed;
            list->count++;
        }
    }
    if (type >= 0) H5Tclose(type);
    H5Dclose(dataset);
    return list->status == 0 ? 0 : 1;
}

/* The root group's datasets of native doubles or ints in `file`, whose image (of `image_size`
 * bytes: eme_h5_copy_image) is `image`: their names, each ended by a newline, in `names`
 * (NUL-terminated, `capacity` bytes), and the offset and size in bytes of each one's values in
 * the file, in `offsets` and `sizes` (*count of them at most; on return, how many), with
 * `sealed` 1 where a Fletcher-32 checksum follows them (eme_h5_seal_chunk). Returns 0, 1 if one
 * of them is not stored in one place (several chunks, other filters) or its checksum is not the
 * one computed here, -1 on an HDF5 error or too little room. */
int eme_h5_numeric_datasets(hid_t file, const void *image, long image_size, char *names, int capacity, int64_t *offsets,
                            int64_t *sizes, int *sealed, int *count)
{
    numeric_list list = {names, capacity, 0, offsets, sizes, sealed, 0, *count, 0, image, image_size};
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
    else if (file_image(file, image, (size_t)size) == 0) {
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

/* Every value of dataset `name` of `file` as doubles (numbers; NULL for other types or on a
 * failed read: a checksum that does not hold) and their count in *count; 0, or -1 if the
 * dataset cannot be read whole. A dataset of texts is read and its texts freed. */
static int read_values(hid_t file, const char *name, double **values, hssize_t *count)
{
    *values = NULL;
    *count = 0;
    hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    if (dataset < 0) return -1;
    hid_t space = H5Dget_space(dataset), stored = H5Dget_type(dataset);
    int status = -1;
    if (space >= 0 && stored >= 0 && (*count = H5Sget_simple_extent_npoints(space)) >= 0) {
        if (H5Tget_class(stored) == H5T_INTEGER || H5Tget_class(stored) == H5T_FLOAT) {
            *values = malloc((size_t)(*count > 0 ? *count : 1) * sizeof **values);
            if (*values != NULL && H5Dread(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, *values) >= 0)
                status = 0;
        } else {
            hid_t memory = H5Tget_native_type(stored, H5T_DIR_ASCEND);
            size_t size = memory >= 0 ? H5Tget_size(memory) : 0;
            void *buffer = size > 0 ? malloc((size_t)(*count > 0 ? *count : 1) * size) : NULL;
            if (buffer != NULL && H5Dread(dataset, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer) >= 0) {
                status = 0;
                if (H5Tis_variable_str(memory) > 0 || H5Tdetect_class(memory, H5T_VLEN) > 0)
                    H5Dvlen_reclaim(memory, space, H5P_DEFAULT, buffer);
            }
            free(buffer);
            if (memory >= 0) H5Tclose(memory);
        }
    }
    if (status != 0) {
        free(*values);
        *values = NULL;
    }
    if (stored >= 0) H5Tclose(stored);
    if (space >= 0) H5Sclose(space);
    H5Dclose(dataset);
    return status;
}

/* Reads every dataset of the root group whole (H5Literate callback): a damaged chunk fails its
 * Fletcher-32 checksum here. */
static herr_t read_whole(hid_t group, const char *name, const H5L_info_t *info, void *data)
{
    (void)info;
    int *failures = data;
    H5O_info_t object;
    if (H5Oget_info_by_name(group, name, &object, H5P_DEFAULT) < 0) {
        ++*failures;
        return 0;
    }
    if (object.type != H5O_TYPE_DATASET) return 0;
    double *values;
    hssize_t count;
    if (read_values(group, name, &values, &count) != 0) ++*failures;
    free(values);
    return 0;
}

/* Whether `recorded` (from an attribute) is what the datasets give, `found`: the same number
 * (both NaN alike), or within a few units of the last place for a figure the reader
 * recomputes in another order. */
static int same_figure(double recorded, double found)
{
    if (recorded != recorded || found != found) return (recorded != recorded) == (found != found);
    return fabs(recorded - found) <= 4 * DBL_EPSILON * fmax(fabs(recorded), fabs(found));
}

/* The dataset `name` of `file` whole, or NULL if the file has none (*count 0); -1 if it cannot
 * be read. */
static int optional_values(hid_t file, const char *name, double **values, hssize_t *count)
{
    *values = NULL;
    *count = 0;
    if (H5Lexists(file, name, H5P_DEFAULT) <= 0) return 0;
    return read_values(file, name, values, count);
}

/* The largest drift max_n |J_n.a - J_0.a| over the conserved momentum components of a run file
 * (their axes a: the root attribute conserved_momentum_axes, 3 numbers each) from the `points`
 * rows of /angular_momentum, `columns` wide (J_x J_y J_z, or the planar J about e_z); files
 * older than the attribute conserved J_z. Summed in the order the time loop sums them
 * (src/structure/model_interface.f90, component_values); -1 if the axes cannot be read, -2 if
 * no component is conserved (conserved_momentum = 'none'). */
static double conserved_momentum_drift(hid_t file, const double *momentum, hssize_t points, hssize_t columns)
{
    double axes[3 * 3] = {0, 0, 1};
    hssize_t count = 1;
    if (H5Aexists(file, "conserved_momentum_axes") > 0) {
        hid_t attribute = H5Aopen(file, "conserved_momentum_axes", H5P_DEFAULT);
        hid_t shape = attribute >= 0 ? H5Aget_space(attribute) : -1;
        hssize_t numbers = shape >= 0 ? H5Sget_simple_extent_npoints(shape) : 0;
        count = numbers / 3;
        int readable = numbers == 3 * count && count >= 1 && count <= 3 &&
                       H5Aread(attribute, H5T_NATIVE_DOUBLE, axes) >= 0;
        if (shape >= 0) H5Sclose(shape);
        if (attribute >= 0) H5Aclose(attribute);
        if (!readable) return -1;
    } else if (H5Aexists(file, "conserved_momentum") > 0) {
        return -2;
    }
    double drift = 0;
    for (hssize_t k = 0; k < count; ++k) {
        const double *a = axes + 3 * k;
        double first = 0;
        for (hssize_t i = 0; i < points; ++i) {
            const double *j = momentum + columns * i;
            double value = columns == 3 ? j[0] * a[0] + j[1] * a[1] + j[2] * a[2] : j[0] * a[2];
            if (i == 0) first = value;
            drift = fmax(drift, fabs(value - first));
        }
    }
    return drift;
}

/* The summary attributes of a run file against the datasets they summarise (src/run/simulation
 * .f90 computes both): newton_iterations_total is the sum of newton_iterations; run_figures'
 * min_entropy_increment and max_lyapunov_increment are the extremes of those datasets, and its
 * energy drift, conserved momentum drift (conserved_momentum_drift) and lowest temperature are
 * those of the points stored (equal when every point is stored, else no better than the points
 * show). 0 if all holds (or the file predates the attributes), 1 if not, -1 if a dataset cannot
 * be read. */
static int check_figures(hid_t file, long long steps)
{
    double figures[7];
    int mismatches = 0, failed = 0;
    if (steps <= 0 || H5Aexists(file, "run_figures") <= 0) return 0;
    hid_t attribute = H5Aopen(file, "run_figures", H5P_DEFAULT);
    hid_t shape = attribute >= 0 ? H5Aget_space(attribute) : -1;
    int readable = shape >= 0 && H5Sget_simple_extent_npoints(shape) == 7 &&
                   H5Aread(attribute, H5T_NATIVE_DOUBLE, figures) >= 0;
    if (shape >= 0) H5Sclose(shape);
    if (attribute >= 0) H5Aclose(attribute);
    if (!readable) return 1;
    long long newton_total = integer_attribute(file, "newton_iterations_total");
    double *newton, *dS, *dV, *energy, *heat, *momentum, *theta;
    hssize_t n_newton, n_dS, n_dV, n_energy, n_heat, n_momentum, n_theta;
    failed |= optional_values(file, "newton_iterations", &newton, &n_newton);
    failed |= optional_values(file, "min_entropy_increment", &dS, &n_dS);
    failed |= optional_values(file, "max_lyapunov_increment", &dV, &n_dV);
    failed |= optional_values(file, "energy", &energy, &n_energy);
    failed |= optional_values(file, "boundary_heat", &heat, &n_heat);
    failed |= optional_values(file, "angular_momentum", &momentum, &n_momentum);
    failed |= optional_values(file, "temperature", &theta, &n_theta);
    if (!failed) {
        long long points = n_energy;
        int every_point = points == steps + 1;
        if (newton != NULL && newton_total >= 0) {
            double sum = 0;
            for (hssize_t i = 0; i < n_newton; ++i) sum += newton[i];
            mismatches += sum != (double)newton_total;
        }
        if (dS != NULL && n_dS > 0) {
            double low = dS[0];
            for (hssize_t i = 1; i < n_dS; ++i) low = fmin(low, dS[i]);
            mismatches += !same_figure(figures[1], low);
        }
        if (dV != NULL && n_dV > 0) {
            double high = dV[0];
            for (hssize_t i = 1; i < n_dV; ++i) high = fmax(high, dV[i]);
            mismatches += !same_figure(figures[2], high);
        }
        /* Figures over the points: recomputed, then equal (every point) or bounded by the record. */
        double found[3] = {0, 0, HUGE_VAL};
        int have[3] = {0, 0, 0};
        if (energy != NULL && points > 0 && (heat == NULL || n_heat == points)) {
            for (hssize_t i = 0; i < points; ++i)
                found[0] = fmax(found[0], fabs(energy[i] - energy[0] - (heat ? heat[i] : 0)) / fabs(energy[0]));
            have[0] = 1;
        }
        if (momentum != NULL && points > 0 && (n_momentum == 3 * points || n_momentum == points)) {
            found[1] = conserved_momentum_drift(file, momentum, points, n_momentum / points);
            have[1] = found[1] >= 0;
            mismatches += found[1] == -1;
        }
        if (theta != NULL && n_theta > 0) {
            for (hssize_t i = 0; i < n_theta; ++i) found[2] = theta[i] != theta[i] ? NAN : fmin(found[2], theta[i]);
            have[2] = 1;
        }
        const int slot[3] = {0, 3, 4};
        for (int k = 0; k < 3; ++k) {
            if (!have[k]) continue;
            double recorded = figures[slot[k]];
            if (every_point) mismatches += !same_figure(recorded, found[k]);
            else if (k < 2) mismatches += !(found[k] <= recorded * (1 + 4 * DBL_EPSILON));
            else mismatches += !(recorded <= found[k] || (recorded != recorded && found[k] != found[k]));
        }
    }
    free(newton), free(dS), free(dV), free(energy), free(heat), free(momentum), free(theta);
    return failed ? -1 : mismatches > 0;
}

/* Whether the open `file` reads whole: every dataset of its root group (a damaged chunk fails its
 * Fletcher-32 checksum), and its texts against their checksum (eme_h5_verify_texts). 0 if so, 4
 * if a dataset cannot be read, 6 if a text fails its checksum or cannot be read. */
static int file_integrity(hid_t file)
{
    int failures = 0;
    hsize_t position = 0;
    if (H5Literate(file, H5_INDEX_NAME, H5_ITER_NATIVE, &position, read_whole, &failures) < 0 || failures > 0) return 4;
    int texts = eme_h5_verify_texts(file);
    return texts == 0 || texts == 2 ? 0 : 6;
}

/* Whether the HDF5 file at `path` is whole (file_integrity): 0, 1 if it cannot be opened, 4 or 6. */
int eme_h5_check_integrity(const char *path)
{
    hid_t file;
    if (eme_h5_open_file(path, 0, 0, 0, &file) != 0) return 1;
    int result = file_integrity(file);
    if (H5Fclose(file) < 0 && result == 0) result = 1;
    return result;
}

/* What the file at `path` is: 1 a run file of this project (its root has the attributes status
 * and steps_completed, as every run file has had), 2 another HDF5 file (a study's index.h5,
 * another program's data), 0 no HDF5 file that opens. */
int eme_h5_file_kind(const char *path)
{
    hid_t file;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);     /* (called before the Fortran side opened HDF5 too) */
    if (H5Fis_hdf5(path) <= 0 || eme_h5_open_file(path, 0, 0, 0, &file) != 0) return 0;
    int kind = H5Aexists(file, "status") > 0 && H5Aexists(file, "steps_completed") > 0 ? 1 : 2;
    H5Fclose(file);
    return kind;
}

/* Reads a run file back: its `status` into `status` (capacity bytes) and `steps_completed`, and
 * checks that every per-point dataset has R + 1 rows and every per-step dataset R rows, R being
 * the attribute step_rows (a row can stand for several steps: &output every), or
 * steps_completed in files without it. With `whole`, it also reads every dataset whole (a
 * damaged chunk fails its checksum), checks its texts against their checksum, and checks the
 * summary attributes against the datasets (check_figures). Returns 0 if all holds, 1 if the file
 * cannot be opened, 2 if status or steps_completed is missing, 3 if a dataset has the wrong
 * length or cannot be read, 4 if a dataset fails its checksum (`whole`), 5 if a summary attribute
 * disagrees with the datasets, 6 if a text fails its checksum (`whole`). */
int eme_h5_check_run_file(const char *path, char *status, int capacity, long *steps_completed, int whole)
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
        if (result == 0 && whole) {
            result = file_integrity(file);
            if (result == 0 && check_figures(file, steps) != 0) result = 5;
        }
    }
    if (H5Fclose(file) < 0 && result == 0) result = 1;
    return result;
}
