/* HDF5 dimension scales (the high-level H5DS API) and text-array attributes for the run files,
 * so that netCDF readers (h5netcdf, xarray) see named dimensions with coordinates: `/time` is the
 * scale of every per-point dataset's rows, `/step` of every per-step dataset's. Called from
 * Fortran through bind(C) (src/io/hdf5_series.f90). Each function returns 0 on success, -1 on
 * an HDF5 error. */
#define _POSIX_C_SOURCE 200809L /* strdup */
#include <hdf5.h>
#include <hdf5_hl.h>
#include <stdlib.h>
#include <string.h>

/* The entries of `joined` (each ended by a newline) as strings in *copy (to be freed with the
 * returned array); NULL if there is none or memory is short. */
static char **split_lines(const char *joined, size_t *count, char **copy)
{
    *count = 0;
    for (const char *c = joined; *c; ++c) *count += *c == '\n';
    if (*count == 0) return NULL;
    *copy = strdup(joined);
    char **entries = calloc(*count, sizeof *entries);
    if (*copy == NULL || entries == NULL) {
        free(*copy);
        free(entries);
        return NULL;
    }
    char *cursor = *copy;
    for (size_t i = 0; i < *count; ++i) {
        char *end = strchr(cursor, '\n');
        *end = '\0';
        entries[i] = cursor;
        cursor = end + 1;
    }
    return entries;
}

/* Makes dataset `scale` a dimension scale named `name`. */
int eme_h5_make_scale(hid_t scale, const char *name)
{
    return H5DSset_scale(scale, name) < 0 ? -1 : 0;
}

/* Attaches `scale` to the first (row) dimension of `dataset`, as h5py and netCDF number it. */
int eme_h5_attach_row_scale(hid_t dataset, hid_t scale)
{
    return H5DSattach_scale(dataset, scale, 0) < 0 ? -1 : 0;
}

/* The entries of a joined text with what HDF5 writes them as: variable-length UTF-8 strings in
 * a 1-D space of their number. */
struct text_array {
    size_t count;
    char *copy;
    char **entries;
    hid_t type, space;
};

static void text_array_close(struct text_array *text)
{
    if (text->space >= 0) H5Sclose(text->space);
    if (text->type >= 0) H5Tclose(text->type);
    free(text->entries);
    free(text->copy);
}

/* Splits `joined` (each entry ended by a newline) into *text; -1 (with nothing to close) on failure. */
static int text_array_open(const char *joined, struct text_array *text)
{
    text->copy = NULL;
    text->type = text->space = -1;
    text->entries = split_lines(joined, &text->count, &text->copy);
    if (text->entries == NULL) return -1;
    hsize_t dims[1] = {text->count};
    text->type = H5Tcopy(H5T_C_S1);
    text->space = H5Screate_simple(1, dims, NULL);
    if (text->type < 0 || text->space < 0 || H5Tset_size(text->type, H5T_VARIABLE) < 0 ||
        H5Tset_cset(text->type, H5T_CSET_UTF8) < 0) {
        text_array_close(text);
        return -1;
    }
    return 0;
}

/* Writes attribute `name` of `object` as a 1-D array of variable-length UTF-8 strings (h5py:
 * an array of str): the entries of `joined`, each ended by a newline. */
int eme_h5_write_text_array_attribute(hid_t object, const char *name, const char *joined)
{
    struct text_array text;
    if (text_array_open(joined, &text) < 0) return -1;
    int status = -1;
    if (H5Aexists(object, name) > 0) H5Adelete(object, name);
    hid_t attribute = H5Acreate2(object, name, text.type, text.space, H5P_DEFAULT, H5P_DEFAULT);
    if (attribute >= 0) {
        if (H5Awrite(attribute, text.type, text.entries) >= 0) status = 0;
        H5Aclose(attribute);
    }
    text_array_close(&text);
    return status;
}

/* Creates dataset `name` in `file` holding `joined` (each entry ended by a newline) as
 * variable-length UTF-8 strings, makes it the dimension scale `name` and attaches it to the
 * second (column) dimension of `dataset`: the names of the columns as a coordinate. */
int eme_h5_column_scale(hid_t file, hid_t dataset, const char *name, const char *joined)
{
    struct text_array text;
    if (text_array_open(joined, &text) < 0) return -1;
    int status = -1;
    hid_t scale = H5Dcreate2(file, name, text.type, text.space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (scale >= 0) {
        if (H5Dwrite(scale, text.type, H5S_ALL, H5S_ALL, H5P_DEFAULT, text.entries) >= 0 &&
            H5DSset_scale(scale, name) >= 0 && H5DSattach_scale(dataset, scale, 1) >= 0)
            status = 0;
        H5Dclose(scale);
    }
    text_array_close(&text);
    return status;
}
