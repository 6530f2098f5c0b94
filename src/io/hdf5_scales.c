/* HDF5 dimension scales and text-array attributes for the run files, so that netCDF readers
 * (h5netcdf, xarray) see named dimensions with coordinates: `/time` is the scale of every
 * per-point dataset's rows, `/step` of every per-step dataset's, and `X_column` of the columns of
 * a 2-D dataset X. The scales' attributes (CLASS, NAME, REFERENCE_LIST; DIMENSION_LIST on each
 * dataset) are those of the high-level H5DS API, written once per object: H5DSattach_scale
 * rewrites the scale's whole REFERENCE_LIST for every dataset attached, which cost a case file
 * about 1 ms (docs/performance.md, Ensemble throughput). Called from Fortran through bind(C)
 * (src/io/hdf5_series.f90). Each function returns 0 on success, -1 on an HDF5 error. */
#define _POSIX_C_SOURCE 200809L /* strdup */
#include <hdf5.h>
#include <hdf5_hl.h>
#include <stdlib.h>
#include <string.h>

int eme_h5_note_texts(hid_t object, const char *name, char *const *texts, size_t count);   /* hdf5_text_checksum.c */

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
    if (status == 0) (void)eme_h5_note_texts(object, name, text.entries, text.count);
    text_array_close(&text);
    return status;
}

/* Creates dataset `name` in `file` holding `joined` (each entry ended by a newline) as
 * variable-length UTF-8 strings and makes it the dimension scale `name`; *scale is left open
 * (the caller attaches it with eme_h5_attach_scales and closes it). HDF5 takes no filter on a
 * variable-length type, so no Fletcher-32 here: the texts are under the file's text_checksum
 * (hdf5_text_checksum.c). The write converts through a buffer of its own size: HDF5's default
 * is a 1 MiB buffer, cleared for every write. */
int eme_h5_column_scale(hid_t file, const char *name, const char *joined, hid_t *scale)
{
    struct text_array text;
    *scale = -1;
    if (text_array_open(joined, &text) < 0) return -1;
    int status = -1;
    hid_t transfer = H5Pcreate(H5P_DATASET_XFER);
    if (transfer >= 0 && H5Pset_buffer(transfer, text.count * sizeof(char *) + 64, NULL, NULL) >= 0) {
        *scale = H5Dcreate2(file, name, text.type, text.space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        if (*scale >= 0 && H5Dwrite(*scale, text.type, H5S_ALL, H5S_ALL, transfer, text.entries) >= 0 &&
            H5DSset_scale(*scale, name) >= 0) {
            status = 0;
            (void)eme_h5_note_texts(*scale, "", text.entries, text.count);   /* (a failure drops the book) */
        }
    }
    if (transfer >= 0) H5Pclose(transfer);
    text_array_close(&text);
    return status;
}

/* One entry of a scale's REFERENCE_LIST, as H5DS lays it out (ds_list_t of H5DS.c). */
typedef struct {
    hobj_ref_t dataset;
    unsigned int dimension;
} reference_entry;

/* Writes attribute `name` of `object` from `data`, `count` values of `type` (memory = file type). */
static int write_array_attribute(hid_t object, const char *name, hid_t type, hsize_t count, const void *data)
{
    hid_t space = H5Screate_simple(1, &count, NULL);
    if (space < 0) return -1;
    int status = -1;
    hid_t attribute = H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
    if (attribute >= 0) {
        if (H5Awrite(attribute, type, data) >= 0) status = 0;
        if (H5Aclose(attribute) < 0) status = -1;
    }
    H5Sclose(space);
    return status;
}

/* Makes `scale` the dimension scale `name` of the rows (dimension 0) of the `count` datasets,
 * and columns[i] (if >= 0, a scale made by eme_h5_column_scale) that of dataset i's columns
 * (dimension 1): DIMENSION_LIST on each dataset, REFERENCE_LIST on each scale, in one write each.
 * The datasets must have no DIMENSION_LIST yet. */
int eme_h5_attach_scales(hid_t scale, const char *name, int count, const hid_t *datasets, const hid_t *columns)
{
    if (H5DSset_scale(scale, name) < 0) return -1;
    if (count <= 0) return 0;
    hid_t list_type = H5Tvlen_create(H5T_STD_REF_OBJ);
    hid_t entry_type = H5Tcreate(H5T_COMPOUND, sizeof(reference_entry));
    reference_entry *rows = calloc((size_t)count, sizeof *rows);
    int status = list_type >= 0 && entry_type >= 0 && rows != NULL &&
                 H5Tinsert(entry_type, "dataset", HOFFSET(reference_entry, dataset), H5T_STD_REF_OBJ) >= 0 &&
                 H5Tinsert(entry_type, "dimension", HOFFSET(reference_entry, dimension), H5T_NATIVE_INT) >= 0 ? 0 : -1;
    hobj_ref_t row_scale;
    if (status == 0 && H5Rcreate(&row_scale, scale, ".", H5R_OBJECT, -1) < 0) status = -1;
    for (int i = 0; i < count && status == 0; ++i) {
        hobj_ref_t column_scale;
        hvl_t dimensions[2] = {{1, &row_scale}, {1, &column_scale}};
        int rank = columns[i] >= 0 ? 2 : 1;
        rows[i].dimension = 0;
        if (H5Rcreate(&rows[i].dataset, datasets[i], ".", H5R_OBJECT, -1) < 0 ||
            (rank == 2 && H5Rcreate(&column_scale, columns[i], ".", H5R_OBJECT, -1) < 0)) {
            status = -1;
            break;
        }
        status = write_array_attribute(datasets[i], "DIMENSION_LIST", list_type, (hsize_t)rank, dimensions);
        if (status == 0 && rank == 2) {
            reference_entry column = {rows[i].dataset, 1};
            status = write_array_attribute(columns[i], "REFERENCE_LIST", entry_type, 1, &column);
        }
    }
    if (status == 0) status = write_array_attribute(scale, "REFERENCE_LIST", entry_type, (hsize_t)count, rows);
    free(rows);
    if (entry_type >= 0) H5Tclose(entry_type);
    if (list_type >= 0) H5Tclose(list_type);
    return status;
}
