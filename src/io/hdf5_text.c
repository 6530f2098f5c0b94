/* Variable-length UTF-8 string attributes for HDF5 objects.
 * HDF5 1.10's Fortran API has no H5T_VARIABLE, and fixed-length strings come back from h5py
 * as bytes; variable-length UTF-8 strings come back as str. Called from Fortran through
 * bind(C) (src/io/hdf5_series.f90). Returns 0 on success, -1 on any HDF5 error. */
#include <hdf5.h>

int eme_h5_write_text_attribute(hid_t object, const char *name, const char *value)
{
    hid_t type = H5Tcopy(H5T_C_S1);
    if (type < 0) return -1;
    int status = -1;
    if (H5Tset_size(type, H5T_VARIABLE) >= 0 && H5Tset_cset(type, H5T_CSET_UTF8) >= 0) {
        if (H5Aexists(object, name) > 0) H5Adelete(object, name);
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
