/* A table as one HDF5 compound dataset, so that h5py loads it in one call as a numpy
 * structured array (`f["cases"][:]`). Columns are chosen at run time: float64 (width 0),
 * int32 (width -1) or fixed-length UTF-8 strings (width > 0, in bytes). HDF5's high-level table
 * API (H5TB) takes a layout fixed at compile time as a C struct; these tables' columns come from
 * a study's sweeps, so the compound type is built here. Tables are written and read whole:
 * numbers as doubles, row after row, each row's numeric columns in column order; texts as one
 * string holding each row's text columns in order, each followed by a newline. Called from
 * Fortran through bind(C) (src/io/hdf5_table.f90). Every function returns 0 on success and -1 on
 * an HDF5 error or a malformed argument. */
#define _POSIX_C_SOURCE 200809L /* strnlen */
#include <hdf5.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_COLUMNS = 64, MAX_NAME = 64 };

typedef struct {
    int count;
    char names[MAX_COLUMNS][MAX_NAME];
    int widths[MAX_COLUMNS];
    size_t offsets[MAX_COLUMNS];
    size_t row_size;
} layout;

/* Columns from newline-terminated names and their widths; packed offsets. */
static int make_layout(int count, const char *names, const int *widths, layout *out)
{
    if (count < 1 || count > MAX_COLUMNS) return -1;
    out->count = count;
    out->row_size = 0;
    const char *cursor = names;
    for (int i = 0; i < count; ++i) {
        const char *end = strchr(cursor, '\n');
        if (end == NULL || (size_t)(end - cursor) >= MAX_NAME) return -1;
        memcpy(out->names[i], cursor, (size_t)(end - cursor));
        out->names[i][end - cursor] = '\0';
        cursor = end + 1;
        out->widths[i] = widths[i];
        out->offsets[i] = out->row_size;
        out->row_size += widths[i] == 0 ? sizeof(double) : widths[i] < 0 ? sizeof(int) : (size_t)widths[i];
    }
    return 0;
}

static hid_t compound_type(const layout *columns)
{
    hid_t type = H5Tcreate(H5T_COMPOUND, columns->row_size);
    for (int i = 0; i < columns->count && type >= 0; ++i) {
        hid_t member;
        if (columns->widths[i] == 0) member = H5Tcopy(H5T_NATIVE_DOUBLE);
        else if (columns->widths[i] < 0) member = H5Tcopy(H5T_NATIVE_INT);
        else {
            member = H5Tcopy(H5T_C_S1);
            H5Tset_size(member, (size_t)columns->widths[i]);
            H5Tset_strpad(member, H5T_STR_NULLPAD);
            H5Tset_cset(member, H5T_CSET_UTF8);
        }
        if (H5Tinsert(type, columns->names[i], columns->offsets[i], member) < 0) {
            H5Tclose(member);
            H5Tclose(type);
            return -1;
        }
        H5Tclose(member);
    }
    return type;
}

/* Packs (pack != 0) numbers and texts into `buffer`, or unpacks `buffer` into them. */
static int convert(const layout *columns, long rows, unsigned char *buffer, double *numbers, char *texts,
                   long texts_capacity, int pack)
{
    const char *text_in = texts;
    long text_out = 0, number = 0;
    for (long r = 0; r < rows; ++r) {
        for (int i = 0; i < columns->count; ++i) {
            unsigned char *field = buffer + (size_t)r * columns->row_size + columns->offsets[i];
            if (columns->widths[i] == 0) {
                if (pack) memcpy(field, &numbers[number], sizeof(double));
                else memcpy(&numbers[number], field, sizeof(double));
                ++number;
            } else if (columns->widths[i] < 0) {
                int value;
                if (pack) {
                    value = (int)numbers[number];
                    memcpy(field, &value, sizeof(int));
                } else {
                    memcpy(&value, field, sizeof(int));
                    numbers[number] = value;
                }
                ++number;
            } else if (pack) {
                const char *end = strchr(text_in, '\n');
                if (end == NULL) return -1;
                size_t length = (size_t)(end - text_in);
                if (length > (size_t)columns->widths[i]) length = (size_t)columns->widths[i];
                memcpy(field, text_in, length);
                text_in = end + 1;
            } else {
                size_t length = strnlen((const char *)field, (size_t)columns->widths[i]);
                if (text_out + (long)length + 1 >= texts_capacity) return -1;
                memcpy(texts + text_out, field, length);
                texts[text_out + (long)length] = '\n';
                text_out += (long)length + 1;
            }
        }
    }
    if (!pack) texts[text_out] = '\0';
    return 0;
}

/* Creates dataset `name` of `rows` rows and writes them all. */
int eme_table_write(hid_t file, const char *name, int count, const char *names, const int *widths, long rows,
                    const double *numbers, const char *texts)
{
    layout columns;
    if (rows < 0 || make_layout(count, names, widths, &columns) < 0) return -1;
    unsigned char *buffer = calloc(rows > 0 ? (size_t)rows : 1, columns.row_size);
    if (buffer == NULL) return -1;
    int status = convert(&columns, rows, buffer, (double *)numbers, (char *)texts, 0, 1);
    hid_t type = status == 0 ? compound_type(&columns) : -1;
    if (type >= 0) {
        hsize_t dims[1] = {(hsize_t)rows};
        hid_t space = H5Screate_simple(1, dims, NULL);
        hid_t dataset = H5Dcreate2(file, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        status = dataset >= 0 && H5Dwrite(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer) >= 0 ? 0 : -1;
        if (dataset >= 0) H5Dclose(dataset);
        H5Sclose(space);
        H5Tclose(type);
    } else {
        status = -1;
    }
    free(buffer);
    return status;
}

/* Reads all `rows` rows of `name` (rows as eme_table_rows gives them) into numbers and texts
 * (capacity: the size of `texts`). HDF5 matches columns by name, so the file's may be in any
 * order; one the file lacks reads as 0 or as an empty text. */
int eme_table_read(hid_t file, const char *name, int count, const char *names, const int *widths, long rows,
                   double *numbers, char *texts, long texts_capacity)
{
    layout columns;
    if (rows < 0 || make_layout(count, names, widths, &columns) < 0) return -1;
    hid_t type = compound_type(&columns);
    if (type < 0) return -1;
    hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    unsigned char *buffer = calloc(rows > 0 ? (size_t)rows : 1, columns.row_size);
    int status = -1;
    if (dataset >= 0 && buffer != NULL && H5Dread(dataset, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer) >= 0)
        status = convert(&columns, rows, buffer, numbers, texts, texts_capacity, 0);
    free(buffer);
    if (dataset >= 0) H5Dclose(dataset);
    H5Tclose(type);
    return status;
}

/* Number of rows of dataset `name`, or -1. */
long eme_table_rows(hid_t file, const char *name)
{
    if (H5Lexists(file, name, H5P_DEFAULT) <= 0) return -1;
    hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    if (dataset < 0) return -1;
    hid_t space = H5Dget_space(dataset);
    hsize_t dims[1] = {0};
    long rows = H5Sget_simple_extent_ndims(space) == 1 && H5Sget_simple_extent_dims(space, dims, NULL) == 1
                    ? (long)dims[0] : -1;
    H5Sclose(space);
    H5Dclose(dataset);
    return rows;
}
