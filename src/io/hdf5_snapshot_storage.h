/* What the two files of the snapshot storage share, and no other file includes:
 * hdf5_snapshot_storage.c (the collective call: its checks, the ranks' agreement on its outcome,
 * the collective transfers and the two functions Fortran calls) and hdf5_snapshot_layout.c (the
 * group /snapshots: its datasets, their chunks and texts, and the dimension scales). The status
 * codes, the datasets of a snapshot, the outcome of a call and the call itself, and the
 * functions each file takes from the other (docs/output.md, Snapshots). */
#ifndef EME_HDF5_SNAPSHOT_STORAGE_H
#define EME_HDF5_SNAPSHOT_STORAGE_H
#include <hdf5.h>
#include <mpi.h>

enum {
    snapshot_ok = 0,
    snapshot_input = 1,     /* the arguments do not describe one state split over the ranks */
    snapshot_io = 2,        /* the file cannot be opened for writing */
    snapshot_mismatch = 3,  /* the file's snapshots have other shapes or datasets */
    snapshot_library = 4    /* HDF5 or MPI failed */
};

static const char group_name[] = "snapshots";

/* The datasets of a snapshot, in the order they are written. */
enum { SET_TIME, SET_Q, SET_P, SET_GAMMA, SET_THETA, SET_TAU, SET_COUNT };
enum { PER_TIME, PER_MASS, PER_SPRING };

typedef struct {
    const char *name, *units, *description;
    int per;
    const double *local;   /* this rank's values; NULL: the dataset is not written */
} snapshot_set;

/* The outcome of a call: a snapshot_* status and its message, which starts with the file's path. */
typedef struct {
    int status;
    char *message;
    int capacity;
    const char *path;
} report;

/* What one call writes: the sets, this rank's part and the file. */
typedef struct {
    snapshot_set sets[SET_COUNT];
    hsize_t masses, springs, dimension, first_mass, mass_count, first_spring, spring_count;
    int rank;
    MPI_Comm comm;
    hid_t group, transfer, datasets[SET_COUNT];
} snapshot_call;

/* hdf5_snapshot_storage.c */
void eme_snapshot_say(report *out, int status, const char *format, ...);
void eme_snapshot_hdf5_failed(report *out, const char *dataset, const char *what);
int eme_snapshot_transfer_part(hid_t dataset, hid_t memory_type, hid_t transfer, MPI_Comm comm, int rank,
                               const hsize_t *start, const hsize_t *count, const void *values, int reading);
/* hdf5_snapshot_layout.c */
int eme_snapshot_shape_of(const snapshot_set *set, hsize_t n, hsize_t masses, hsize_t springs, hsize_t d,
                          hsize_t *dims, hsize_t *chunk, hsize_t *maximum);
void eme_snapshot_create_group(snapshot_call *call, hid_t file, report *out);
void eme_snapshot_open_group(snapshot_call *call, hid_t file, hsize_t *rows, report *out);

#endif
