/* Snapshots of a state split over MPI ranks, appended to an existing HDF5 file with parallel
 * HDF5 (docs/output.md, Snapshots): every rank writes its own masses and springs in one
 * collective write per dataset, so no rank gathers the whole state.
 *
 * One call opens the file collectively with the MPI-IO driver, creates the group /snapshots on
 * the first call, extends each of its datasets by one snapshot along the first axis, writes and
 * closes. No process may hold the file open meanwhile (the run's own writer closes it before and
 * reopens it after). The datasets are chunked with HDF5's Fletcher-32 filter, as every dataset of
 * a run file is; HDF5 1.10 writes filtered chunks in parallel only collectively
 * (H5FD_MPIO_COLLECTIVE), each chunk by one rank that receives the other ranks' parts of it. The
 * group's layout (its datasets, their chunks and texts, the dimension scales; made on the first
 * call, checked against the state on later ones) is hdf5_snapshot_layout.c's; what the two files
 * share, hdf5_snapshot_storage.h.
 *
 * The last snapshot is read back the same way, each rank its own part (a continued run starts
 * from it). All ranks return the same status and message (the first failing rank's). A call that
 * fails after extending the datasets shrinks them back, so the file keeps its earlier snapshots.
 * Called from Fortran through bind(C) (src/io/hdf5_snapshots.f90). Returns 0 on success, or one of
 * the snapshot_* codes of hdf5_snapshot_storage.h with a message. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <hdf5.h>
#include <mpi.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "hdf5_snapshot_storage.h"

/* Disk reserved for a snapshot beyond its values: HDF5's chunk index and object headers. */
enum { RESERVE_MARGIN = 262144 };

int eme_reserve_space_ahead(const char *path, long bytes);   /* posix_files.c */

/* Sets the outcome, unless an earlier failure has. */
void eme_snapshot_say(report *out, int status, const char *format, ...)
{
    if (out->status != snapshot_ok) return;
    out->status = status;
    int used = snprintf(out->message, (size_t)out->capacity, "%s: ", out->path);
    if (used < 0 || used >= out->capacity) return;
    va_list arguments;
    va_start(arguments, format);
    vsnprintf(out->message + used, (size_t)(out->capacity - used), format, arguments);
    va_end(arguments);
}

/* HDF5's innermost reason for the error on its default stack (H5Ewalk callback). */
static herr_t innermost(unsigned n, const H5E_error2_t *error, void *data)
{
    if (n == 0 && error->desc != NULL) snprintf(data, 160, "%s", error->desc);
    return 0;
}

/* Says that HDF5 failed at `what` (for dataset `dataset` of the group, or the file if NULL). */
void eme_snapshot_hdf5_failed(report *out, const char *dataset, const char *what)
{
    char reason[160] = "";
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, innermost, reason);
    if (dataset != NULL)
        eme_snapshot_say(out, snapshot_library, "cannot %s /%s/%s (HDF5: %s)", what, group_name, dataset,
            reason[0] ? reason : "failed");
    else
        eme_snapshot_say(out, snapshot_library, "cannot %s (HDF5: %s)", what, reason[0] ? reason : "failed");
}

/* Makes every rank's report the first failing rank's; returns the agreed status. */
static int agree(report *out, MPI_Comm comm)
{
    int rank, size, first;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    int mine = out->status != snapshot_ok ? rank : size;
    MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
    if (first == size) return snapshot_ok;
    MPI_Bcast(&out->status, 1, MPI_INT, first, comm);
    MPI_Bcast(out->message, out->capacity, MPI_CHAR, first, comm);
    return out->status;
}

/* Whether the ranks' parts [first, first + count) follow each other in rank order and cover
 * [0, total). Names the offending rank's `what` in out if not. */
static void check_split(report *out, const char *what, long long total, long long first, long long count, MPI_Comm comm)
{
    int rank;
    long long before = 0, sum;
    MPI_Comm_rank(comm, &rank);
    MPI_Exscan(&count, &before, 1, MPI_LONG_LONG, MPI_SUM, comm);
    if (rank == 0) before = 0;
    MPI_Allreduce(&count, &sum, 1, MPI_LONG_LONG, MPI_SUM, comm);
    if (count < 0 || first != before)
        eme_snapshot_say(out, snapshot_input,
            "rank %d's %s start at index %lld (count %lld); the ranks' %s must follow each other in rank order, "
            "so it must start at %lld", rank, what, first + 1, count, what, before + 1);
    else if (sum != total)
        eme_snapshot_say(out, snapshot_input, "the ranks hold %lld %s in all, the state has %lld", sum, what, total);
}

/* Writes (or with `reading`, reads) this rank's part of `dataset` collectively over `comm`: the
 * block at `start` of `count` (rank `rank`) from (into) `values`; a rank with an empty block takes
 * part with no selection. Returns 0, -1 if HDF5 failed, or -2 on every rank (none transferring)
 * if a rank's block lies outside the dataset: a rank whose collective transfer fails alone would
 * leave the others waiting for it. */
int eme_snapshot_transfer_part(hid_t dataset, hid_t memory_type, hid_t transfer, MPI_Comm comm, int rank,
                               const hsize_t *start, const hsize_t *count, const void *values, int reading)
{
    static double nothing[1] = {0};
    hsize_t elements = 1;
    for (int i = 0; i < rank; ++i) elements *= count[i];
    hsize_t memory_length = elements > 0 ? elements : 1;
    hid_t file_space = H5Dget_space(dataset);
    hid_t memory_space = H5Screate_simple(1, &memory_length, NULL);
    int status = -1;
    if (file_space >= 0 && memory_space >= 0) {
        herr_t selected = elements > 0 ? H5Sselect_hyperslab(file_space, H5S_SELECT_SET, start, NULL, count, NULL)
                          : H5Sselect_none(file_space) >= 0 && H5Sselect_none(memory_space) >= 0 ? 0 : -1;
        int inside = selected >= 0 && H5Sselect_valid(file_space) > 0, everywhere = 0;
        MPI_Allreduce(&inside, &everywhere, 1, MPI_INT, MPI_MIN, comm);
        /* A reader's `values` are the caller's writable array (eme_h5_read_last_snapshot). */
        void *values_or_nothing = elements > 0 ? (void *)values : nothing;
        if (!everywhere) status = -2;
        else if (reading ? H5Dread(dataset, memory_type, memory_space, file_space, transfer, values_or_nothing) >= 0
                         : H5Dwrite(dataset, memory_type, memory_space, file_space, transfer, values_or_nothing) >= 0)
            status = 0;
    } else {
        int everywhere = 0, inside = 0;
        MPI_Allreduce(&inside, &everywhere, 1, MPI_INT, MPI_MIN, comm);
    }
    if (memory_space >= 0) H5Sclose(memory_space);
    if (file_space >= 0) H5Sclose(file_space);
    return status;
}

/* Gives every dataset `rows` snapshots (H5Dset_extent is collective); the ranks agree after each
 * dataset, so a failure on one rank (a full disk meets the rank that writes HDF5's metadata)
 * stops them all at the same dataset rather than leaving the others in the next collective call. */
static void set_rows(snapshot_call *call, hsize_t rows, report *out)
{
    for (int s = 0; s < SET_COUNT; ++s) {
        if (call->datasets[s] < 0) continue;
        hsize_t dims[3], chunk[3], maximum[3];
        eme_snapshot_shape_of(&call->sets[s], rows, call->masses, call->springs, call->dimension, dims, chunk, maximum);
        if (H5Dset_extent(call->datasets[s], dims) < 0) eme_snapshot_hdf5_failed(out, call->sets[s].name, "extend");
        if (agree(out, call->comm) != snapshot_ok) return;
    }
}

/* Writes (or with `reading`, reads) snapshot `row` of every set: each rank its masses and springs,
 * and the time (rank 0 writes it, every rank reads it). */
static void transfer_snapshot(snapshot_call *call, hsize_t row, int reading, report *out)
{
    for (int s = 0; s < SET_COUNT; ++s) {
        const snapshot_set *set = &call->sets[s];
        if (call->datasets[s] < 0) continue;
        hsize_t start[3] = {row, 0, 0}, count[3] = {1, 0, call->dimension};
        if (set->per == PER_TIME) count[0] = call->rank == 0 || reading ? 1 : 0;
        else if (set->per == PER_MASS) {
            start[1] = call->first_mass;
            count[1] = call->mass_count;
        } else {
            start[1] = call->first_spring;
            count[1] = call->spring_count;
        }
        int dims = set->per == PER_TIME ? 1 : set->per == PER_MASS ? 3 : 2;
        int status = eme_snapshot_transfer_part(call->datasets[s], H5T_NATIVE_DOUBLE, call->transfer, call->comm, dims,
                                                start, count, set->local, reading);
        if (status == -2)
            eme_snapshot_say(out, snapshot_library, "a rank's part lies outside /%s/%s; nothing %s", group_name,
                set->name, reading ? "read" : "written");
        else if (status != 0)
            eme_snapshot_hdf5_failed(out, set->name, reading ? "read a snapshot from" : "write a snapshot into");
        if (agree(out, call->comm) != snapshot_ok) return;   /* every rank stops at the same set */
    }
}

/* Checks the arguments on each rank and across the ranks: one state, split in rank order. */
static void check_arguments(const snapshot_call *call, double time, int dimension, long long masses, long long springs,
                            const char *tau_name, int has_tau, MPI_Comm comm, report *out)
{
    long long time_bits;
    memcpy(&time_bits, &time, sizeof time_bits);
    int tau_kind = strcmp(tau_name, "entropy") == 0 ? 1 : strcmp(tau_name, "internal_energy") == 0 ? 2 : 0;
    if (dimension < 1 || dimension > 3)
        eme_snapshot_say(out, snapshot_input, "the dimension is %d; allowed: 1, 2 or 3", dimension);
    else if (masses < 1 || springs < 0)
        eme_snapshot_say(out, snapshot_input,
            "%lld masses and %lld springs; allowed: at least 1 mass and no negative count", masses, springs);
    else if (tau_kind == 0 && tau_name[0] != '\0')
        eme_snapshot_say(out, snapshot_input,
            "tau's dataset name is '%s'; allowed: 'entropy', 'internal_energy' or none (tau is theta)", tau_name);
    else if (has_tau && tau_kind == 0)
        eme_snapshot_say(out, snapshot_input, "tau is given without its dataset name ('entropy' or 'internal_energy')");
    else if (!has_tau && tau_kind != 0)
        eme_snapshot_say(out, snapshot_input, "tau's dataset name '%s' is given without tau", tau_name);
    else if (call->mass_count > 0 && (call->sets[SET_Q].local == NULL || call->sets[SET_P].local == NULL))
        eme_snapshot_say(out, snapshot_input, "this rank holds %lld masses and no positions or momenta",
            (long long)call->mass_count);
    if (agree(out, comm) != snapshot_ok) return;
    const long long shared[] = {time_bits, masses, springs, dimension, tau_kind, call->sets[SET_GAMMA].local != NULL,
                                call->sets[SET_THETA].local != NULL};
    static const char *const shared_names[] = {"time", "number of masses", "number of springs", "dimension",
                                               "thermodynamic variable", "presence of gamma", "presence of theta"};
    enum { SHARED = sizeof shared / sizeof shared[0] };
    long long highest[SHARED], lowest[SHARED];
    MPI_Allreduce(shared, highest, SHARED, MPI_LONG_LONG, MPI_MAX, comm);
    MPI_Allreduce(shared, lowest, SHARED, MPI_LONG_LONG, MPI_MIN, comm);
    for (int i = 0; i < SHARED; ++i)
        if (highest[i] != lowest[i]) {
            eme_snapshot_say(out, snapshot_input, "the ranks give different values of the %s", shared_names[i]);
            break;
        }
    if (agree(out, comm) != snapshot_ok) return;
    check_split(out, "masses", masses, (long long)call->first_mass, (long long)call->mass_count, comm);
    if (agree(out, comm) != snapshot_ok) return;
    check_split(out, "springs", springs, (long long)call->first_spring, (long long)call->spring_count, comm);
    agree(out, comm);
}

/* Rank 0 checks that `path` is a regular file it may read and, with `writing`, write (an HDF5
 * error would say less). */
static void check_file(const char *path, int rank, int writing, report *out)
{
    struct stat info;
    if (rank != 0) return;
    const char *what = writing ? "append a snapshot" : "read a snapshot";
    if (stat(path, &info) != 0 || access(path, writing ? R_OK | W_OK : R_OK) != 0)
        eme_snapshot_say(out, snapshot_io, "cannot open the file to %s: %s", what, strerror(errno));
    else if (!S_ISREG(info.st_mode))
        eme_snapshot_say(out, snapshot_io, "cannot %s: not a regular file", what);
}

/* The call for the state split over `comm` as the arguments say (eme_h5_append_snapshot's), its
 * sets pointing at this rank's arrays and at `time`, checked on every rank. */
static snapshot_call new_call(MPI_Comm comm, const double *time, long long masses, long long springs, int dimension,
                              long long first_mass, long long mass_count, long long first_spring,
                              long long spring_count, const double *q, const double *p, const double *gamma,
                              const double *tau, const double *theta, const char *tau_name, report *out)
{
    int rank;
    MPI_Comm_rank(comm, &rank);
    snapshot_call call = {
        {{"time", "s", "time of the snapshot", PER_TIME, time},
         {"q", "m", "positions of the masses", PER_MASS, q},
         {"p", "N s", "momenta of the masses", PER_MASS, p},
         {"gamma", "m", "viscous elongation of each spring (the internal variable gamma)", PER_SPRING, gamma},
         {"theta", "K", "temperature of each spring", PER_SPRING, theta},
         {tau_name, strcmp(tau_name, "entropy") == 0 ? "J/K" : "J",
          strcmp(tau_name, "entropy") == 0 ? "entropy of each spring" : "internal energy of each spring", PER_SPRING, tau}},
        (hsize_t)masses, (hsize_t)springs, (hsize_t)dimension, (hsize_t)first_mass, (hsize_t)mass_count,
        (hsize_t)first_spring, (hsize_t)spring_count, rank, comm, -1, -1, {-1, -1, -1, -1, -1, -1}};
    check_arguments(&call, *time, dimension, masses, springs, tau_name, tau != NULL, comm, out);
    return call;
}

/* Rank 0 reserves the disk one more snapshot takes (its values and RESERVE_MARGIN) past the end
 * of `path`, so that a full disk is reported here, by the OS, before HDF5 writes: HDF5 1.10
 * crashes at exit after a failed close (HDFFV-11052), as docs/faults.md says of the rows. */
static void reserve_snapshot_space(const snapshot_call *call, const char *path, report *out)
{
    long bytes = RESERVE_MARGIN;
    for (int s = 0; s < SET_COUNT; ++s) {
        if (call->sets[s].local == NULL) continue;
        int per = call->sets[s].per;
        bytes += 8L * (per == PER_TIME ? 1L : per == PER_MASS ? (long)(call->masses * call->dimension) : (long)call->springs);
    }
    int error = eme_reserve_space_ahead(path, bytes);
    if (error != 0)
        eme_snapshot_say(out, snapshot_io, "cannot append a snapshot: %s (%ld bytes asked)", strerror(error), bytes);
}

/* Opens `path` collectively with the MPI-IO driver (read-write with `writing`) and sets up
 * collective transfers; returns the file, or -1 with out saying why. */
static hid_t open_collectively(snapshot_call *call, const char *path, int writing, report *out)
{
    hid_t access_list = H5Pcreate(H5P_FILE_ACCESS);
    hid_t file = -1;
    if (access_list < 0 || H5Pset_fapl_mpio(access_list, call->comm, MPI_INFO_NULL) < 0 ||
        H5Pset_libver_bounds(access_list, H5F_LIBVER_V18, H5F_LIBVER_V18) < 0)
        eme_snapshot_hdf5_failed(out, NULL, "set up the MPI-IO driver");
    else if ((file = H5Fopen(path, writing ? H5F_ACC_RDWR : H5F_ACC_RDONLY, access_list)) < 0) {
        eme_snapshot_hdf5_failed(out, NULL, writing ? "open the file as HDF5 to append a snapshot"
                                                    : "open the file as HDF5 to read a snapshot");
        out->status = snapshot_io;
    }
    if (access_list >= 0) H5Pclose(access_list);
    call->transfer = H5Pcreate(H5P_DATASET_XFER);
    if (out->status == snapshot_ok && (call->transfer < 0 || H5Pset_dxpl_mpio(call->transfer, H5FD_MPIO_COLLECTIVE) < 0))
        eme_snapshot_hdf5_failed(out, NULL, "set up collective transfers");
    return file;
}

/* Closes what `call` opened in `file`. */
static void close_call(snapshot_call *call)
{
    for (int s = 0; s < SET_COUNT; ++s)
        if (call->datasets[s] >= 0) H5Dclose(call->datasets[s]);
    if (call->group >= 0) H5Gclose(call->group);
    call->group = -1;
    for (int s = 0; s < SET_COUNT; ++s) call->datasets[s] = -1;
}

/* Appends one snapshot of the state split over the ranks of `fortran_comm` to the existing HDF5
 * file `path` (docs/output.md, Snapshots): at `time`, of `masses` masses and `springs` springs in
 * `dimension` components; this rank holds masses [first_mass, first_mass + mass_count) (0-based)
 * with positions q and momenta p (mass_count x dimension, the component fastest) and springs
 * [first_spring, first_spring + spring_count) with gamma, tau and theta (each NULL when the state
 * has none; tau is named `tau_name`, "entropy" or "internal_energy", or "" when tau is theta).
 * Collective over the communicator. Returns 0, or a snapshot_* code with the same `message`
 * (`capacity` bytes) on every rank. */
int eme_h5_append_snapshot(const char *path, MPI_Fint fortran_comm, double time, long long masses, long long springs,
                           int dimension, long long first_mass, long long mass_count, long long first_spring,
                           long long spring_count, const double *q, const double *p, const double *gamma,
                           const double *tau, const double *theta, const char *tau_name, char *message, int capacity)
{
    MPI_Comm comm = MPI_Comm_f2c(fortran_comm);
    report out = {snapshot_ok, message, capacity, path};
    message[0] = '\0';
    snapshot_call call = new_call(comm, &time, masses, springs, dimension, first_mass, mass_count, first_spring,
                                  spring_count, q, p, gamma, tau, theta, tau_name, &out);
    if (out.status != snapshot_ok) return out.status;
    /* Positions and momenta are always written; a rank without masses may pass no arrays. */
    static const double none[1] = {0};
    if (call.sets[SET_Q].local == NULL) call.sets[SET_Q].local = none;
    if (call.sets[SET_P].local == NULL) call.sets[SET_P].local = none;
    check_file(path, call.rank, 1, &out);
    if (out.status == snapshot_ok && call.rank == 0) reserve_snapshot_space(&call, path, &out);
    if (agree(&out, comm) != snapshot_ok) return out.status;

    H5E_auto2_t printer;
    void *printer_data;
    H5Eget_auto2(H5E_DEFAULT, &printer, &printer_data);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    hid_t file = open_collectively(&call, path, 1, &out);
    hsize_t rows = 0;
    int creating = 0;
    if (agree(&out, comm) == snapshot_ok) {
        creating = H5Lexists(file, group_name, H5P_DEFAULT) <= 0;
        if (creating) eme_snapshot_create_group(&call, file, &out);
        else eme_snapshot_open_group(&call, file, &rows, &out);
    }
    if (agree(&out, comm) == snapshot_ok) {
        set_rows(&call, rows + 1, &out);
        if (out.status == snapshot_ok) transfer_snapshot(&call, rows, 0, &out);
        if (agree(&out, comm) != snapshot_ok) {   /* the snapshots before stay */
            char scratch_text[1] = "";
            report scratch = {snapshot_ok, scratch_text, 1, path};
            set_rows(&call, rows, &scratch);
        }
    }
    close_call(&call);
    if (creating && agree(&out, comm) != snapshot_ok) (void)H5Ldelete(file, group_name, H5P_DEFAULT);   /* no half group */
    if (call.transfer >= 0) H5Pclose(call.transfer);
    if (file >= 0 && H5Fclose(file) < 0) eme_snapshot_hdf5_failed(&out, NULL, "close the file after a snapshot");
    H5Eset_auto2(H5E_DEFAULT, printer, printer_data);
    return agree(&out, comm);
}

/* Reads the last snapshot of the HDF5 file `path` into this rank's part of the state, the part
 * and arrays as eme_h5_append_snapshot takes them (writable here: q, p, gamma, tau, theta receive
 * the values, each NULL when the state has none), and its time into *time. The file's snapshots
 * must be of this state: the same datasets (tau's named `tau_name`) and shapes (a snapshot_mismatch
 * names the dataset otherwise). Every rank reads its own masses and springs, collectively over
 * the communicator, so none holds the whole state (a continued run: docs/faults.md). Returns 0, or
 * a snapshot_* code with the same `message` on every rank. */
int eme_h5_read_last_snapshot(const char *path, MPI_Fint fortran_comm, long long masses, long long springs,
                              int dimension, long long first_mass, long long mass_count, long long first_spring,
                              long long spring_count, double *q, double *p, double *gamma, double *tau, double *theta,
                              const char *tau_name, double *time, char *message, int capacity)
{
    MPI_Comm comm = MPI_Comm_f2c(fortran_comm);
    report out = {snapshot_ok, message, capacity, path};
    message[0] = '\0';
    *time = 0;
    snapshot_call call = new_call(comm, time, masses, springs, dimension, first_mass, mass_count, first_spring,
                                  spring_count, q, p, gamma, tau, theta, tau_name, &out);
    if (out.status != snapshot_ok) return out.status;
    static double none[1] = {0};
    if (call.sets[SET_Q].local == NULL) call.sets[SET_Q].local = none;
    if (call.sets[SET_P].local == NULL) call.sets[SET_P].local = none;
    check_file(path, call.rank, 0, &out);
    if (agree(&out, comm) != snapshot_ok) return out.status;

    H5E_auto2_t printer;
    void *printer_data;
    H5Eget_auto2(H5E_DEFAULT, &printer, &printer_data);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    hid_t file = open_collectively(&call, path, 0, &out);
    hsize_t rows = 0;
    if (agree(&out, comm) == snapshot_ok) {
        if (H5Lexists(file, group_name, H5P_DEFAULT) <= 0)
            eme_snapshot_say(&out, snapshot_mismatch, "the file has no /%s: its run wrote no snapshot", group_name);
        else eme_snapshot_open_group(&call, file, &rows, &out);
        if (out.status == snapshot_ok && rows == 0)
            eme_snapshot_say(&out, snapshot_mismatch, "/%s holds no snapshot", group_name);
    }
    if (agree(&out, comm) == snapshot_ok) transfer_snapshot(&call, rows - 1, 1, &out);
    close_call(&call);
    if (call.transfer >= 0) H5Pclose(call.transfer);
    if (file >= 0 && H5Fclose(file) < 0)
        eme_snapshot_hdf5_failed(&out, NULL, "close the file after reading a snapshot");
    H5Eset_auto2(H5E_DEFAULT, printer, printer_data);
    return agree(&out, comm);
}
