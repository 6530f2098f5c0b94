/* Variable-length UTF-8 string attributes for HDF5 objects.
 * HDF5 1.10's Fortran API has no H5T_VARIABLE, and fixed-length strings come back from h5py
 * as bytes; variable-length UTF-8 strings come back as str. Called from Fortran through
 * bind(C) (src/io/hdf5_files.f90). Returns 0 on success, -1 on any HDF5 error. */
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>

int eme_h5_note_texts(hid_t object, const char *name, char *const *texts, size_t count);   /* hdf5_text_checksum.c */

static int write_text(hid_t object, const char *name, const char *value, int fresh);

/* Writes attribute `name` = `value` and notes it for the file's text checksum. On a
 * `fresh` object (created by this process, with no attributes yet) no existence query is made;
 * otherwise an old value is replaced. */
int eme_h5_write_text_attribute(hid_t object, const char *name, const char *value, int fresh)
{
    char *texts[1] = {(char *)value};
    int status = write_text(object, name, value, fresh);
    if (status == 0) (void)eme_h5_note_texts(object, name, texts, 1);
    return status;
}

static int write_text(hid_t object, const char *name, const char *value, int fresh)
{
    hid_t type = H5Tcopy(H5T_C_S1);
    if (type < 0) return -1;
    int status = -1;
    if (H5Tset_size(type, H5T_VARIABLE) >= 0 && H5Tset_cset(type, H5T_CSET_UTF8) >= 0) {
        if (!fresh && H5Aexists(object, name) > 0) {
            /* A text replaces a text in place: deleting an attribute can rewrite the whole object
             * header (hundreds of microseconds on a run file's root). */
            hid_t old = H5Aopen(object, name, H5P_DEFAULT);
            hid_t stored = old >= 0 ? H5Aget_type(old) : -1;
            hid_t shape = old >= 0 ? H5Aget_space(old) : -1;
            int same = stored >= 0 && shape >= 0 && H5Tget_class(stored) == H5T_STRING &&
                       H5Tis_variable_str(stored) > 0 && H5Sget_simple_extent_type(shape) == H5S_SCALAR;
            if (same && H5Awrite(old, type, &value) >= 0) status = 0;
            if (shape >= 0) H5Sclose(shape);
            if (stored >= 0) H5Tclose(stored);
            if (old >= 0) H5Aclose(old);
            if (same) {
                H5Tclose(type);
                return status;
            }
            H5Adelete(object, name);
        }
        hid_t space = H5Screate(H5S_SCALAR);
        if (space >= 0) {
            hid_t attribute = H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
            if (attribute >= 0) {
                if (H5Awrite(attribute, type, &value) >= 0) status = 0;
                H5Aclose(attribute);
            }
            H5Sclose(space);
        }
    }
    H5Tclose(type);
    return status;
}

/* Reads the string attribute `name` of `object` (variable or fixed length) into `text` (NUL-
 * terminated, cut at `capacity`); -1 if it is missing or not a string. */
int eme_h5_read_text_attribute(hid_t object, const char *name, char *text, int capacity)
{
    if (capacity < 1 || H5Aexists(object, name) <= 0) return -1;
    hid_t attribute = H5Aopen(object, name, H5P_DEFAULT);
    if (attribute < 0) return -1;
    int status = -1;
    hid_t stored = H5Aget_type(attribute);
    if (stored >= 0 && H5Tget_class(stored) == H5T_STRING) {
        if (H5Tis_variable_str(stored) > 0) {
            hid_t memory = H5Tcopy(H5T_C_S1);
            char *value = NULL;
            H5Tset_size(memory, H5T_VARIABLE);
            H5Tset_cset(memory, H5Tget_cset(stored));
            if (H5Aread(attribute, memory, &value) >= 0 && value != NULL) {
                snprintf(text, (size_t)capacity, "%s", value);
                H5free_memory(value);
                status = 0;
            }
            H5Tclose(memory);
        } else {
            size_t size = H5Tget_size(stored);
            char *value = calloc(size + 1, 1);
            hid_t memory = H5Tcopy(stored);
            if (value != NULL && H5Aread(attribute, memory, value) >= 0) {
                snprintf(text, (size_t)capacity, "%s", value);
                status = 0;
            }
            free(value);
            H5Tclose(memory);
        }
    }
    if (stored >= 0) H5Tclose(stored);
    H5Aclose(attribute);
    return status;
}
