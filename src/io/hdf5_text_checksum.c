/* The checksum of an HDF5 file's texts (docs/output.md, Checksums). HDF5 keeps the characters
 * of variable-length strings in its global heap, which has no checksum of its own: a damaged
 * byte there reads as another text. The root attribute `text_checksum` holds the CRC-32 (zlib's,
 * as Python's zlib.crc32) of every variable-length text of the file, as records in this order:
 * the root group's (object name "/"), then those of each object of the root group by name (byte
 * order); of each object, its attributes by name (byte order) whose type is a variable-length
 * string (one or an array), then the values of a dataset of variable-length strings (under the
 * attribute name ""). A record's bytes: the object name, NUL, the attribute name, NUL, each text
 * followed by a NUL, and 0x1E.
 *
 * Reading every text back costs about as much as writing them (a few microseconds an attribute,
 * a run file has about 200), so a file being written keeps its records in a book, in order: the
 * writers of texts (hdf5_text.c, hdf5_scales.c) note each text they write, and sealing only runs the
 * CRC over the book. A file opened for writing from disk starts its book by reading its texts
 * back; a file made from a template's image, from the book kept with the image. Called from
 * Fortran through bind(C) (src/io/hdf5_files.f90). */
#include <hdf5.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

typedef struct {
    char *bytes;           /* the record; its key is the object and attribute names with their NULs */
    size_t length;
} text_record;

typedef struct {
    hid_t file;            /* the file id the book belongs to (-1: a free slot) */
    text_record *records;  /* in checksum order */
    int count, room;
} text_book;

static text_book *books;
static int book_slots;

/* Orders two keys as the checksum takes them: the root group "/" first, then by object name,
 * then by attribute name (bytes). */
static int compare_keys(const char *a, const char *b)
{
    int a_root = strcmp(a, "/") == 0, b_root = strcmp(b, "/") == 0;
    if (a_root != b_root) return a_root ? -1 : 1;
    int order = strcmp(a, b);
    if (order != 0) return order;
    return strcmp(a + strlen(a) + 1, b + strlen(b) + 1);
}

static void clear_book(text_book *book)
{
    for (int i = 0; i < book->count; ++i) free(book->records[i].bytes);
    book->count = 0;
}

/* The book of the file `file`, or NULL if it has none. */
static text_book *book_of_file(hid_t file)
{
    for (int i = 0; i < book_slots; ++i)
        if (books[i].file == file) return &books[i];
    return NULL;
}

/* The book of the file that holds `object`, or NULL. */
static text_book *book_of(hid_t object)
{
    if (H5Iget_type(object) == H5I_FILE) return book_of_file(object);
    hid_t file = H5Iget_file_id(object);
    if (file < 0) return NULL;
    text_book *book = book_of_file(file);
    H5Fclose(file);           /* (gives back the reference H5Iget_file_id took) */
    return book;
}

/* The name `object` has in the checksum: "/" for the root group or the file, else its name in the
 * root group (into `name`, `capacity` bytes); -1 if it has none. */
static int object_name(hid_t object, char *name, size_t capacity)
{
    if (H5Iget_type(object) == H5I_FILE) {
        snprintf(name, capacity, "/");
        return 0;
    }
    ssize_t length = H5Iget_name(object, name, capacity);
    if (length <= 0 || (size_t)length >= capacity) return -1;
    if (strcmp(name, "/") != 0 && name[0] == '/') memmove(name, name + 1, (size_t)length);
    return 0;
}

/* Finds the record of `key` (its position) or where it would go (*found 0). */
static int find_record(const text_book *book, const char *key, int *found)
{
    int low = 0, high = book->count;
    *found = 0;
    while (low < high) {
        int middle = (low + high) / 2, order = compare_keys(book->records[middle].bytes, key);
        if (order == 0) {
            *found = 1;
            return middle;
        }
        if (order < 0) low = middle + 1;
        else high = middle;
    }
    return low;
}

/* Puts `record` (whose bytes the book takes over) in `book`, replacing one of the same key. 0, or -1. */
static int put_record(text_book *book, text_record record)
{
    int found, at = find_record(book, record.bytes, &found);
    if (found) {
        free(book->records[at].bytes);
        book->records[at] = record;
        return 0;
    }
    if (book->count == book->room) {
        int room = book->room > 0 ? 2 * book->room : 256;
        text_record *larger = realloc(book->records, (size_t)room * sizeof *larger);
        if (larger == NULL) {
            free(record.bytes);
            return -1;
        }
        book->records = larger;
        book->room = room;
    }
    memmove(book->records + at + 1, book->records + at, (size_t)(book->count - at) * sizeof *book->records);
    book->records[at] = record;
    book->count++;
    return 0;
}

/* A record's bytes: object NUL name NUL, each of the `count` texts and a NUL, then 0x1E. */
static int make_record(const char *object, const char *name, char *const *texts, size_t count, text_record *record)
{
    size_t length = strlen(object) + 1 + strlen(name) + 1 + 1;
    for (size_t i = 0; i < count; ++i) length += (texts[i] ? strlen(texts[i]) : 0) + 1;
    char *bytes = malloc(length), *cursor = bytes;
    if (bytes == NULL) return -1;
    memcpy(cursor, object, strlen(object) + 1);
    cursor += strlen(object) + 1;
    memcpy(cursor, name, strlen(name) + 1);
    cursor += strlen(name) + 1;
    for (size_t i = 0; i < count; ++i) {
        size_t size = texts[i] ? strlen(texts[i]) : 0;
        memcpy(cursor, texts[i] ? texts[i] : "", size);
        cursor[size] = '\0';
        cursor += size + 1;
    }
    *cursor = '\x1e';
    *record = (text_record){bytes, length};
    return 0;
}

/* Notes that attribute `name` of `object` (or, for name "", the values of the dataset `object`)
 * now holds the `count` texts: the writers of variable-length texts call it. Nothing to do for a
 * file without a book. 0, or -1 (the book is then dropped: sealing reads the texts back). */
int eme_h5_note_texts(hid_t object, const char *name, char *const *texts, size_t count)
{
    text_book *book = book_of(object);
    char object_text[1024];
    text_record record;
    if (book == NULL) return 0;
    if (object_name(object, object_text, sizeof object_text) == 0 &&
        make_record(object_text, name, texts, count, &record) == 0 && put_record(book, record) == 0)
        return 0;
    clear_book(book);
    book->file = -1;
    return -1;
}

/* Deletes attribute `name` of `object` (and its record). 0, or -1. */
int eme_h5_delete_attribute(hid_t object, const char *name)
{
    if (H5Adelete(object, name) < 0) return -1;
    text_book *book = book_of(object);
    char key[2048];
    if (book == NULL || object_name(object, key, 1024) != 0) return 0;
    snprintf(key + strlen(key) + 1, sizeof key - strlen(key) - 1, "%s", name);
    int found, at = find_record(book, key, &found);
    if (found) {
        free(book->records[at].bytes);
        memmove(book->records + at, book->records + at + 1, (size_t)(book->count - at - 1) * sizeof *book->records);
        book->count--;
    }
    return 0;
}

/* Reads the variable-length strings of an attribute (dataset < 0) or of a dataset (attribute <
 * 0) of file type `stored` and notes them as `name` of `object` in `book`. 0, or -1. */
static int read_strings(text_book *book, const char *object, hid_t attribute, hid_t dataset, hid_t stored,
                        const char *name)
{
    hid_t space = attribute >= 0 ? H5Aget_space(attribute) : H5Dget_space(dataset);
    hid_t memory = H5Tcopy(H5T_C_S1), transfer = H5Pcreate(H5P_DATASET_XFER);
    hssize_t count = space >= 0 ? H5Sget_simple_extent_npoints(space) : -1;
    char **texts = count >= 0 ? calloc((size_t)(count > 0 ? count : 1), sizeof *texts) : NULL;
    int status = -1;
    text_record record;
    /* (a conversion buffer of the texts' size: HDF5's default, 1 MiB, is cleared for every read) */
    if (texts != NULL && memory >= 0 && transfer >= 0 && H5Tset_size(memory, H5T_VARIABLE) >= 0 &&
        H5Tset_cset(memory, H5Tget_cset(stored)) >= 0 &&
        H5Pset_buffer(transfer, (size_t)(count + 1) * sizeof(char *) + 64, NULL, NULL) >= 0 &&
        (attribute >= 0 ? H5Aread(attribute, memory, texts)
                        : H5Dread(dataset, memory, H5S_ALL, H5S_ALL, transfer, texts)) >= 0) {
        if (make_record(object, name, texts, (size_t)count, &record) == 0) status = put_record(book, record);
        H5Dvlen_reclaim(memory, space, H5P_DEFAULT, texts);
    }
    free(texts);
    if (transfer >= 0) H5Pclose(transfer);
    if (memory >= 0) H5Tclose(memory);
    if (space >= 0) H5Sclose(space);
    return status;
}

static int variable_text(hid_t type)
{
    return type >= 0 && H5Tget_class(type) == H5T_STRING && H5Tis_variable_str(type) > 0;
}

typedef struct {
    text_book *book;
    const char *object;
    int status;
} reading;

/* H5Aiterate2 callback: notes an attribute that is a variable-length string. */
static herr_t read_attribute(hid_t location, const char *name, const H5A_info_t *info, void *data)
{
    (void)info;
    reading *read = data;
    hid_t attribute = H5Aopen(location, name, H5P_DEFAULT);
    hid_t stored = attribute >= 0 ? H5Aget_type(attribute) : -1;
    if (stored < 0) read->status = -1;
    else if (variable_text(stored) && read_strings(read->book, read->object, attribute, -1, stored, name) != 0)
        read->status = -1;
    if (stored >= 0) H5Tclose(stored);
    if (attribute >= 0) H5Aclose(attribute);
    return read->status == 0 ? 0 : 1;
}

/* Notes the texts of the open object `object` named `name`: its attributes, a dataset's values. */
static void read_object(reading *read, hid_t object, const char *name)
{
    hsize_t position = 0;
    read->object = name;
    if (H5Aiterate2(object, H5_INDEX_NAME, H5_ITER_NATIVE, &position, read_attribute, read) < 0) read->status = -1;
    if (read->status == 0 && H5Iget_type(object) == H5I_DATASET) {
        hid_t stored = H5Dget_type(object);
        if (stored < 0 || (variable_text(stored) && read_strings(read->book, name, -1, object, stored, "") != 0))
            read->status = -1;
        if (stored >= 0) H5Tclose(stored);
    }
}

/* H5Literate callback: the texts of one object of the root group. */
static herr_t read_member(hid_t group, const char *name, const H5L_info_t *info, void *data)
{
    (void)info;
    reading *read = data;
    hid_t object = H5Oopen(group, name, H5P_DEFAULT);
    if (object < 0) read->status = -1;
    else read_object(read, object, name);
    if (object >= 0) H5Oclose(object);
    return read->status == 0 ? 0 : 1;
}

/* Fills `book` with every text of `file`. 0, or -1 if one cannot be read. */
static int read_book(text_book *book, hid_t file)
{
    reading read = {book, "/", 0};
    hsize_t position = 0;
    clear_book(book);
    read_object(&read, file, "/");
    if (read.status == 0 && H5Literate(file, H5_INDEX_NAME, H5_ITER_NATIVE, &position, read_member, &read) < 0)
        read.status = -1;
    return read.status;
}

/* The CRC-32 of the records of `book`, in order. */
static uint32_t book_checksum(const text_book *book)
{
    uLong crc = crc32(0L, Z_NULL, 0);
    for (int i = 0; i < book->count; ++i)
        crc = crc32(crc, (const Bytef *)book->records[i].bytes, (uInt)book->records[i].length);
    return (uint32_t)crc;
}

/* Starts the book of `file`, just created or opened for writing: empty (0), or its texts read
 * back (`read_back` 1). 0, or -1. */
int eme_h5_texts_begin(hid_t file, int read_back)
{
    text_book *book = book_of_file(file);
    if (book == NULL) book = book_of_file(-1);
    if (book == NULL) {
        text_book *larger = realloc(books, (size_t)(book_slots + 1) * sizeof *larger);
        if (larger == NULL) return -1;
        books = larger;
        book = &books[book_slots++];
        *book = (text_book){-1, NULL, 0, 0};
    }
    clear_book(book);
    book->file = file;
    if (read_back && read_book(book, file) != 0) {
        clear_book(book);
        book->file = -1;
        return -1;
    }
    return 0;
}

/* Drops the book of `file` (at its close). */
void eme_h5_texts_end(hid_t file)
{
    text_book *book = book_of_file(file);
    if (book == NULL) return;
    clear_book(book);
    book->file = -1;
}

/* Gives the book of `from` (a file closed since) to `to` (the same file opened again); with `to`
 * < 0 it is dropped. 0, or -1 if `from` has no book. */
int eme_h5_texts_move(hid_t from, hid_t to)
{
    text_book *book = book_of_file(from);
    if (book == NULL) return -1;
    if (to < 0) {
        eme_h5_texts_end(from);
        return 0;
    }
    if (to != from) eme_h5_texts_end(to);   /* (a stale book of the id, if any) */
    book->file = to;
    return 0;
}

/* The book of `file` as bytes (each record: its length in 20 digits, then its bytes) in `buffer`
 * of `capacity` bytes; returns the size needed (call with capacity 0 to learn it), -1 if the file
 * has no book. A template keeps it with its image (src/io/hdf5_file_templates.f90). */
long eme_h5_texts_export(hid_t file, char *buffer, long capacity)
{
    text_book *book = book_of_file(file);
    if (book == NULL) return -1;
    long size = 0;
    for (int i = 0; i < book->count; ++i) {
        size_t length = book->records[i].length;
        if (size + 20 + (long)length <= capacity) {
            char digits[21];
            snprintf(digits, sizeof digits, "%020zu", length);
            memcpy(buffer + size, digits, 20);
            memcpy(buffer + size + 20, book->records[i].bytes, length);
        }
        size += 20 + (long)length;
    }
    return size;
}

/* Starts the book of `file` (made from a template's image) from what eme_h5_texts_export gave for
 * that image (`size` bytes). 0, or -1. */
int eme_h5_texts_import(hid_t file, const char *buffer, long size)
{
    if (eme_h5_texts_begin(file, 0) != 0) return -1;
    text_book *book = book_of_file(file);
    for (long at = 0; at + 20 <= size;) {
        char digits[21];
        memcpy(digits, buffer + at, 20);
        digits[20] = '\0';
        size_t length = (size_t)strtoull(digits, NULL, 10);
        char *bytes = malloc(length);
        if (bytes == NULL || at + 20 + (long)length > size) {
            free(bytes);
            eme_h5_texts_end(file);
            return -1;
        }
        memcpy(bytes, buffer + at + 20, length);
        text_record record = {bytes, length};
        if (put_record(book, record) != 0) {
            eme_h5_texts_end(file);
            return -1;
        }
        at += 20 + (long)length;
    }
    return 0;
}

/* Writes the root attribute text_checksum of the open, writable `file` from its book (read back
 * if it has none). 0, or -1 on an HDF5 error. */
int eme_h5_seal_texts(hid_t file)
{
    text_book *book = book_of_file(file);
    if (book == NULL) {
        if (eme_h5_texts_begin(file, 1) != 0) return -1;
        book = book_of_file(file);
    }
    uint32_t checksum = book_checksum(book);
    hid_t attribute = -1;
    if (H5Aexists(file, "text_checksum") > 0) {
        attribute = H5Aopen(file, "text_checksum", H5P_DEFAULT);
    } else {
        hid_t space = H5Screate(H5S_SCALAR);
        if (space >= 0) attribute = H5Acreate2(file, "text_checksum", H5T_STD_U32LE, space, H5P_DEFAULT, H5P_DEFAULT);
        if (space >= 0) H5Sclose(space);
    }
    if (attribute < 0) return -1;
    int status = H5Awrite(attribute, H5T_NATIVE_UINT32, &checksum) >= 0 ? 0 : -1;
    if (H5Aclose(attribute) < 0) status = -1;
    return status;
}

/* Whether the texts of `file` (open for reading) are those its text_checksum was computed from:
 * 0 if so, 1 if not (a damaged text), 2 if the file has no text_checksum (written before it
 * existed), -1 if a text cannot be read. */
int eme_h5_verify_texts(hid_t file)
{
    if (H5Aexists(file, "text_checksum") <= 0) return 2;
    uint32_t stored;
    hid_t attribute = H5Aopen(file, "text_checksum", H5P_DEFAULT);
    int readable = attribute >= 0 && H5Aread(attribute, H5T_NATIVE_UINT32, &stored) >= 0;
    if (attribute >= 0) H5Aclose(attribute);
    text_book book = {file, NULL, 0, 0};
    int status = readable && read_book(&book, file) == 0 ? (book_checksum(&book) == stored ? 0 : 1) : -1;
    clear_book(&book);
    free(book.records);
    return status;
}
