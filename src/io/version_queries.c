/* The versions of the libraries the programs link, asked of the libraries themselves at run
 * time (not of the headers they were compiled with), for --version and provenance. None needs
 * MPI, PETSc or HDF5 to be initialized. Called from src/io/library_versions.f90. */
#include <stdio.h>
#include <string.h>
#include <hdf5.h>
#include <mpi.h>
#include <petscsys.h>
#include <sundials/sundials_version.h>

#ifdef H5_HAVE_PARALLEL
#define H5_HAVE_PARALLEL_TEXT " (parallel)"
#else
#define H5_HAVE_PARALLEL_TEXT ""
#endif

/* The version of library `which` (1 PETSc, 2 HDF5, 3 MPI, 4 SUNDIALS) into `text`; 0 on
 * success, -1 if the library did not answer or `which` is unknown. */
int eme_library_version(int which, char *text, int size)
{
    text[0] = '\0';
    switch (which) {
    case 1: {
        PetscInt major, minor, subminor, release;
        if (PetscGetVersionNumber(&major, &minor, &subminor, &release) != 0) return -1;
        snprintf(text, (size_t)size, "%d.%d.%d%s", (int)major, (int)minor, (int)subminor, release ? "" : " (development)");
        return 0;
    }
    case 2: {
        unsigned major, minor, release;
        if (H5get_libversion(&major, &minor, &release) < 0) return -1;
        snprintf(text, (size_t)size, "%u.%u.%u%s", major, minor, release, H5_HAVE_PARALLEL_TEXT);
        return 0;
    }
    case 3: {
        char library[MPI_MAX_LIBRARY_VERSION_STRING];
        int length = 0, version = 0, subversion = 0;
        if (MPI_Get_library_version(library, &length) != MPI_SUCCESS) return -1;
        if (MPI_Get_version(&version, &subversion) != MPI_SUCCESS) return -1;
        library[strcspn(library, "\n")] = '\0'; /* Open MPI ends it with a newline */
        snprintf(text, (size_t)size, "%s (MPI standard %d.%d)", library, version, subversion);
        return 0;
    }
    case 4:
        return SUNDIALSGetVersion(text, size) == 0 ? 0 : -1;
    default:
        return -1;
    }
}
