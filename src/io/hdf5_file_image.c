/* The HDF5 file in memory and the bytes of its image (docs/faults.md): a new file is built with
 * HDF5's core driver; its image is written to disk in one checked write (hdf5_storage.c), or
 * copied out and opened again as another in-memory file (a series of similar files:
 * src/io/hdf5_file_templates.f90); and the checksums that HDF5 keeps in an image are computed
 * here: the superblock's, which HDF5 1.10 leaves wrong in an image, and a chunk's Fletcher-32,
 * so that values put in place in an image read back as if HDF5 had written them. The file on
 * disk (its writes, locks and reserved space) is hdf5_storage.c's; reading a finished file back,
 * hdf5_run_file_check.c's. Called from Fortran through bind(C) (src/io/hdf5_files.f90).
 * Functions return 0 on success or -1 for an HDF5 failure, unless they say otherwise. */
#include <stdint.h>
#include <hdf5.h>
#include <string.h>

int eme_h5_texts_begin(hid_t file, int read_back);                                /* hdf5_text_checksum.c */

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
