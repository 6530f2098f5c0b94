/* Snapshots of a state split over MPI ranks, appended to an existing HDF5 file with parallel
 * HDF5 (docs/output.md, Snapshots): every rank writes its own masses and springs in one
 * collective write per dataset, so no rank gathers the whole state.
 *
 * One call opens the file collectively with the MPI-IO driver, creates the group /snapshots on
 * the first call, extends each of its datasets by one snapshot along the first axis, writes and
 * closes. No process may hold the file open meanwhile (the run's own writer closes it before and
 * reopens it after). The datasets are chunked with HDF5's Fletcher-32 filter, as every dataset of
 * a run file is; HDF5 1.10 writes filtered chunks in parallel only collectively
 * (H5FD_MPIO_COLLECTIVE), each chunk by one rank that receives the other ranks' parts of it. A
 * chunk of a per-mass dataset holds one snapshot of at most CHUNK_VALUES numbers (256 KiB), the
 * masses split evenly (chunk_length): for N = 10^5 masses in 3 components, (1, 10000, 3), 10
 * chunks a snapshot. One chunk per snapshot (2.4 MB) would send the whole of q to one rank; with
 * ten, a rank receives only the parts of the chunks that straddle its neighbours' ranges, and
 * every chunk fits HDF5's default 1 MiB chunk cache when read. The texts (units, description,
 * dims) are fixed-length strings: they live in the object headers, which carry checksums of their
 * own in HDF5 1.8's format, and stay out of the heap that the file's text_checksum covers
 * (hdf5_text_checksum.c), which this writer does not hold.
 *
 * The last snapshot is read back the same way, each rank its own part (a continued run starts
 * from it). All ranks return the same status and message (the first failing rank's). A call that
 * fails after extending the datasets shrinks them back, so the file keeps its earlier snapshots.
 * Called from Fortran through bind(C) (src/io/hdf5_snapshots.f90). Returns 0 on success, or one of
 * the snapshot_* codes below with a message. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <hdf5.h>
#include <hdf5_hl.h>
#include <mpi.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

enum {
    snapshot_ok = 0,
    snapshot_input = 1,     /* the arguments do not describe one state split over the ranks */
    snapshot_io = 2,        /* the file cannot be opened for writing */
    snapshot_mismatch = 3,  /* the file's snapshots have other shapes or datasets */
    snapshot_library = 4    /* HDF5 or MPI failed */
};

enum { CHUNK_VALUES = 32768, TIME_CHUNK = 64 };
/* Disk reserved for a snapshot beyond its values: HDF5's chunk index and object headers. */
enum { RESERVE_MARGIN = 262144 };

int eme_reserve_space_ahead(const char *path, long bytes);   /* posix_files.c */
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

/* Sets the outcome, unless an earlier failure has. */
static void say(report *out, int status, const char *format, ...)
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
static void hdf5_failed(report *out, const char *dataset, const char *what)
{
    char reason[160] = "";
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, innermost, reason);
    if (dataset != NULL)
        say(out, snapshot_library, "cannot %s /%s/%s (HDF5: %s)", what, group_name, dataset,
            reason[0] ? reason : "failed");
    else
        say(out, snapshot_library, "cannot %s (HDF5: %s)", what, reason[0] ? reason : "failed");
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
        say(out, snapshot_input,
            "rank %d's %s start at index %lld (count %lld); the ranks' %s must follow each other in rank order, "
            "so it must start at %lld", rank, what, first + 1, count, what, before + 1);
    else if (sum != total)
        say(out, snapshot_input, "the ranks hold %lld %s in all, the state has %lld", sum, what, total);
}

/* Writes attribute `name` of `object`: `count` fixed-length UTF-8 strings (a scalar if count is 0). */
static int write_fixed_texts(hid_t object, const char *name, const char *const *texts, int count)
{
    size_t longest = 1;
    int entries = count > 0 ? count : 1;
    for (int i = 0; i < entries; ++i)
        if (strlen(texts[i]) > longest) longest = strlen(texts[i]);
    char *packed = calloc((size_t)entries, longest);
    if (packed == NULL) return -1;
    for (int i = 0; i < entries; ++i) memcpy(packed + (size_t)i * longest, texts[i], strlen(texts[i]));
    hsize_t dims[1] = {(hsize_t)count};
    hid_t type = H5Tcopy(H5T_C_S1);
    hid_t space = count > 0 ? H5Screate_simple(1, dims, NULL) : H5Screate(H5S_SCALAR);
    int status = -1;
    if (type >= 0 && space >= 0 && H5Tset_size(type, longest) >= 0 && H5Tset_strpad(type, H5T_STR_NULLPAD) >= 0 &&
        H5Tset_cset(type, H5T_CSET_UTF8) >= 0) {
        hid_t attribute = H5Acreate2(object, name, type, space, H5P_DEFAULT, H5P_DEFAULT);
        if (attribute >= 0) {
            if (H5Awrite(attribute, type, packed) >= 0) status = 0;
            if (H5Aclose(attribute) < 0) status = -1;
        }
    }
    if (space >= 0) H5Sclose(space);
    if (type >= 0) H5Tclose(type);
    free(packed);
    return status;
}

/* Writes the texts of a dataset or scale: units, description and the names of its axes. */
static int describe(hid_t dataset, const char *units, const char *description, const char *const *axes, int rank)
{
    return write_fixed_texts(dataset, "units", &units, 0) < 0 || write_fixed_texts(dataset, "description", &description, 0) < 0 ||
                   write_fixed_texts(dataset, "dims", axes, rank) < 0
               ? -1
               : 0;
}

/* Entries of a chunk along an axis of `length` entries of `width` numbers each: the axis split
 * evenly into the fewest chunks of at most CHUNK_VALUES numbers. HDF5 stores a filtered edge
 * chunk whole: chunks of CHUNK_VALUES numbers exactly would store 100,000 springs in four chunks
 * of 32,768, 31 % more than the values. */
static hsize_t chunk_length(hsize_t length, hsize_t width)
{
    if (length == 0) return 1;
    hsize_t chunks = (length * width + CHUNK_VALUES - 1) / CHUNK_VALUES;
    return (length + chunks - 1) / chunks;
}

/* The shape of a snapshot dataset: its rank, and its dims, chunk and maximum dims for n snapshots. */
static int shape_of(const snapshot_set *set, hsize_t n, hsize_t masses, hsize_t springs, hsize_t d, hsize_t *dims,
                    hsize_t *chunk, hsize_t *maximum)
{
    for (int i = 0; i < 3; ++i) dims[i] = chunk[i] = maximum[i] = 1;
    dims[0] = n;
    chunk[0] = 1;
    maximum[0] = H5S_UNLIMITED;
    if (set->per == PER_TIME) {
        chunk[0] = TIME_CHUNK;
        return 1;
    }
    if (set->per == PER_SPRING) {
        dims[1] = maximum[1] = springs;
        chunk[1] = chunk_length(springs, 1);
        return 2;
    }
    dims[1] = maximum[1] = masses;
    dims[2] = maximum[2] = chunk[2] = d;
    chunk[1] = chunk_length(masses, d);
    return 3;
}

/* The creation properties of a chunked dataset with Fletcher-32 that is never filled. */
static hid_t checked_chunks(int rank, const hsize_t *chunk)
{
    hid_t creation = H5Pcreate(H5P_DATASET_CREATE);
    if (creation >= 0 && (H5Pset_chunk(creation, rank, chunk) < 0 || H5Pset_fletcher32(creation) < 0 ||
                          H5Pset_fill_time(creation, H5D_FILL_TIME_NEVER) < 0)) {
        H5Pclose(creation);
        return -1;
    }
    return creation;
}


/* Writes (or with `reading`, reads) this rank's part of `dataset` collectively over `comm`: the
 * block at `start` of `count` (rank `rank`) from (into) `values`; a rank with an empty block takes
 * part with no selection. Returns 0, -1 if HDF5 failed, or -2 on every rank (none transferring)
 * if a rank's block lies outside the dataset: a rank whose collective transfer fails alone would
 * leave the others waiting for it. */
static int transfer_part(hid_t dataset, hid_t memory_type, hid_t transfer, MPI_Comm comm, int rank, const hsize_t *start,
                         const hsize_t *count, const void *values, int reading)
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

/* Creates the dimension scale `name` of `length` entries in `group` with its coordinates, of
 * which this rank writes [first, first + count): the numbers 1 .. length, or with `labels` the
 * one-letter texts labels[0 .. length). Returns the open scale, or -1. */
static hid_t make_scale(hid_t group, const char *name, const char *description, hsize_t length, hsize_t first,
                        hsize_t count, const char *labels, hid_t transfer, MPI_Comm comm)
{
    hsize_t chunk = chunk_length(length, 1);
    hid_t space = H5Screate_simple(1, &length, NULL);
    hid_t creation = checked_chunks(1, &chunk);
    hid_t type = labels != NULL ? H5Tcopy(H5T_C_S1) : H5Tcopy(H5T_STD_I64LE);
    hid_t scale = -1;
    long long *numbers = malloc((count > 0 ? count : 1) * sizeof *numbers);
    int status = -1;
    if (numbers != NULL && space >= 0 && creation >= 0 && type >= 0 &&
        (labels == NULL || (H5Tset_size(type, 1) >= 0 && H5Tset_cset(type, H5T_CSET_UTF8) >= 0))) {
        scale = H5Dcreate2(group, name, type, space, H5P_DEFAULT, creation, H5P_DEFAULT);
        for (hsize_t i = 0; i < count; ++i) numbers[i] = (long long)(first + i + 1);
        if (scale >= 0)
            status = labels != NULL ? transfer_part(scale, type, transfer, comm, 1, &first, &count, labels + first, 0)
                                    : transfer_part(scale, H5T_NATIVE_LLONG, transfer, comm, 1, &first, &count, numbers, 0);
        const char *axes[1] = {name};
        if (status == 0) status = describe(scale, "1", description, axes, 1);
        if (status == 0 && H5DSset_scale(scale, name) < 0) status = -1;
    }
    free(numbers);
    if (type >= 0) H5Tclose(type);
    if (creation >= 0) H5Pclose(creation);
    if (space >= 0) H5Sclose(space);
    if (status != 0 && scale >= 0) {
        H5Dclose(scale);
        scale = -1;
    }
    return scale;
}

/* What one call writes: the sets, this rank's part and the file. */
typedef struct {
    snapshot_set sets[SET_COUNT];
    hsize_t masses, springs, dimension, first_mass, mass_count, first_spring, spring_count;
    int rank;
    MPI_Comm comm;
    hid_t group, transfer, datasets[SET_COUNT];
} snapshot_call;

/* Creates /snapshots with its empty datasets and their dimension scales (time, mass, spring,
 * component). */
static void create_group(snapshot_call *call, hid_t file, report *out)
{
    static const char *const axes[3][3] = {{"time"}, {"time", "mass", "component"}, {"time", "spring"}};
    call->group = H5Gcreate2(file, group_name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (call->group < 0) {
        hdf5_failed(out, NULL, "create the group /snapshots");
        return;
    }
    const char *group_text = "the state at chosen times, written by every rank in parallel";
    if (write_fixed_texts(call->group, "description", &group_text, 0) < 0) {
        hdf5_failed(out, NULL, "describe the group /snapshots");
        return;
    }
    for (int s = 0; s < SET_COUNT; ++s) {
        const snapshot_set *set = &call->sets[s];
        if (set->local == NULL) continue;
        hsize_t dims[3], chunk[3], maximum[3];
        int rank = shape_of(set, 0, call->masses, call->springs, call->dimension, dims, chunk, maximum);
        hid_t space = H5Screate_simple(rank, dims, maximum);
        hid_t creation = checked_chunks(rank, chunk);
        if (space >= 0 && creation >= 0)
            call->datasets[s] = H5Dcreate2(call->group, set->name, H5T_IEEE_F64LE, space, H5P_DEFAULT, creation, H5P_DEFAULT);
        if (creation >= 0) H5Pclose(creation);
        if (space >= 0) H5Sclose(space);
        if (call->datasets[s] < 0 || describe(call->datasets[s], set->units, set->description, axes[set->per], rank) < 0) {
            hdf5_failed(out, set->name, "create");
            return;
        }
    }
    hid_t mass = make_scale(call->group, "mass", "number of the mass (1: next to the first support)", call->masses,
                            call->first_mass, call->mass_count, NULL, call->transfer, call->comm);
    hid_t component = make_scale(call->group, "component", "component of a position or momentum", call->dimension, 0,
                                 call->rank == 0 ? call->dimension : 0, "xyz", call->transfer, call->comm);
    hid_t spring = -1;
    int spring_sets = call->datasets[SET_GAMMA] >= 0 || call->datasets[SET_THETA] >= 0 || call->datasets[SET_TAU] >= 0;
    if (spring_sets)
        spring = make_scale(call->group, "spring", "number of the spring (1: from the first support)", call->springs,
                            call->first_spring, call->spring_count, NULL, call->transfer, call->comm);
    hid_t time = call->datasets[SET_TIME];
    int status = mass >= 0 && component >= 0 && (spring >= 0 || !spring_sets) && H5DSset_scale(time, "time") >= 0 ? 0 : -1;
    for (int s = SET_Q; s < SET_COUNT && status == 0; ++s) {
        hid_t dataset = call->datasets[s];
        if (dataset < 0) continue;
        if (H5DSattach_scale(dataset, time, 0) < 0) status = -1;
        else if (call->sets[s].per == PER_MASS)
            status = H5DSattach_scale(dataset, mass, 1) < 0 || H5DSattach_scale(dataset, component, 2) < 0 ? -1 : 0;
        else status = H5DSattach_scale(dataset, spring, 1) < 0 ? -1 : 0;
    }
    if (status != 0) hdf5_failed(out, "mass, spring and component", "make the dimension scales");
    if (spring >= 0) H5Dclose(spring);
    if (component >= 0) H5Dclose(component);
    if (mass >= 0) H5Dclose(mass);
}

/* The shape of `rank` dims as "(a, b)" into `text` (64 bytes). */
static void shape_text(char *text, const hsize_t *dims, int rank)
{
    int used = snprintf(text, 64, "(");
    for (int i = 0; i < rank && used < 48; ++i)
        used += snprintf(text + used, (size_t)(64 - used), i > 0 ? ", %llu" : "%llu", (unsigned long long)dims[i]);
    snprintf(text + used, (size_t)(64 - used), ")");
}

/* Opens the datasets of an existing /snapshots and checks that they are the sets given, with
 * the shapes of this state, and that all hold the same number of snapshots (*rows). */
static void open_group(snapshot_call *call, hid_t file, hsize_t *rows, report *out)
{
    call->group = H5Gopen2(file, group_name, H5P_DEFAULT);
    if (call->group < 0) {
        hdf5_failed(out, NULL, "open the group /snapshots");
        return;
    }
    for (int s = 0; s < SET_COUNT && out->status == snapshot_ok; ++s) {
        const snapshot_set *set = &call->sets[s];
        int stored = set->name[0] != '\0' && H5Lexists(call->group, set->name, H5P_DEFAULT) > 0;
        if (set->local == NULL) {
            if (stored)
                say(out, snapshot_mismatch, "/%s/%s is in the file, and this snapshot has no %s", group_name,
                    set->name, set->name);
            continue;
        }
        if (!stored) {
            say(out, snapshot_mismatch, "/%s/%s is not in the file; its snapshots were written without %s",
                group_name, set->name, set->name);
            return;
        }
        call->datasets[s] = H5Dopen2(call->group, set->name, H5P_DEFAULT);
        hid_t space = call->datasets[s] >= 0 ? H5Dget_space(call->datasets[s]) : -1;
        hsize_t found[3] = {0, 0, 0}, dims[3], chunk[3], maximum[3];
        int rank = shape_of(set, 0, call->masses, call->springs, call->dimension, dims, chunk, maximum);
        int found_rank = space >= 0 ? H5Sget_simple_extent_dims(space, found, NULL) : -1;
        if (space >= 0) H5Sclose(space);
        if (found_rank < 0) {
            hdf5_failed(out, set->name, "open");
            return;
        }
        if (s == SET_TIME) *rows = found[0];
        char found_shape[64], given_shape[64];
        shape_text(found_shape, found + 1, found_rank - 1);
        shape_text(given_shape, dims + 1, rank - 1);
        if (strcmp(found_shape, given_shape) != 0)
            say(out, snapshot_mismatch, "/%s/%s holds snapshots of shape %s; this snapshot's %s is %s", group_name,
                set->name, found_shape, set->name, given_shape);
        else if (found[0] != *rows)
            say(out, snapshot_mismatch, "/%s/%s holds %llu snapshots, /%s/time %llu", group_name, set->name,
                (unsigned long long)found[0], group_name, (unsigned long long)*rows);
    }
    /* Another thermodynamic variable than the one written before. */
    static const char *const variables[2] = {"entropy", "internal_energy"};
    for (int v = 0; v < 2 && out->status == snapshot_ok; ++v)
        if (strcmp(variables[v], call->sets[SET_TAU].name) != 0 && H5Lexists(call->group, variables[v], H5P_DEFAULT) > 0)
            say(out, snapshot_mismatch, "/%s/%s is in the file, and this snapshot has %s", group_name, variables[v], call->sets[SET_TAU].name[0] ? call->sets[SET_TAU].name : "no tau (tau is theta)");
}

/* Gives every dataset `rows` snapshots (H5Dset_extent is collective); the ranks agree after each
 * dataset, so a failure on one rank (a full disk meets the rank that writes HDF5's metadata)
 * stops them all at the same dataset rather than leaving the others in the next collective call. */
static void set_rows(snapshot_call *call, hsize_t rows, report *out)
{
    for (int s = 0; s < SET_COUNT; ++s) {
        if (call->datasets[s] < 0) continue;
        hsize_t dims[3], chunk[3], maximum[3];
        shape_of(&call->sets[s], rows, call->masses, call->springs, call->dimension, dims, chunk, maximum);
        if (H5Dset_extent(call->datasets[s], dims) < 0) hdf5_failed(out, call->sets[s].name, "extend");
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
        int status = transfer_part(call->datasets[s], H5T_NATIVE_DOUBLE, call->transfer, call->comm, dims, start, count,
                                   set->local, reading);
        if (status == -2)
            say(out, snapshot_library, "a rank's part lies outside /%s/%s; nothing %s", group_name, set->name,
                reading ? "read" : "written");
        else if (status != 0) hdf5_failed(out, set->name, reading ? "read a snapshot from" : "write a snapshot into");
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
        say(out, snapshot_input, "the dimension is %d; allowed: 1, 2 or 3", dimension);
    else if (masses < 1 || springs < 0)
        say(out, snapshot_input, "%lld masses and %lld springs; allowed: at least 1 mass and no negative count", masses,
            springs);
    else if (tau_kind == 0 && tau_name[0] != '\0')
        say(out, snapshot_input, "tau's dataset name is '%s'; allowed: 'entropy', 'internal_energy' or none (tau is theta)",
            tau_name);
    else if (has_tau && tau_kind == 0)
        say(out, snapshot_input, "tau is given without its dataset name ('entropy' or 'internal_energy')");
    else if (!has_tau && tau_kind != 0)
        say(out, snapshot_input, "tau's dataset name '%s' is given without tau", tau_name);
    else if (call->mass_count > 0 && (call->sets[SET_Q].local == NULL || call->sets[SET_P].local == NULL))
        say(out, snapshot_input, "this rank holds %lld masses and no positions or momenta", (long long)call->mass_count);
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
            say(out, snapshot_input, "the ranks give different values of the %s", shared_names[i]);
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
        say(out, snapshot_io, "cannot open the file to %s: %s", what, strerror(errno));
    else if (!S_ISREG(info.st_mode))
        say(out, snapshot_io, "cannot %s: not a regular file", what);
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
    if (error != 0) say(out, snapshot_io, "cannot append a snapshot: %s (%ld bytes asked)", strerror(error), bytes);
}

/* Opens `path` collectively with the MPI-IO driver (read-write with `writing`) and sets up
 * collective transfers; returns the file, or -1 with out saying why. */
static hid_t open_collectively(snapshot_call *call, const char *path, int writing, report *out)
{
    hid_t access_list = H5Pcreate(H5P_FILE_ACCESS);
    hid_t file = -1;
    if (access_list < 0 || H5Pset_fapl_mpio(access_list, call->comm, MPI_INFO_NULL) < 0 ||
        H5Pset_libver_bounds(access_list, H5F_LIBVER_V18, H5F_LIBVER_V18) < 0)
        hdf5_failed(out, NULL, "set up the MPI-IO driver");
    else if ((file = H5Fopen(path, writing ? H5F_ACC_RDWR : H5F_ACC_RDONLY, access_list)) < 0) {
        hdf5_failed(out, NULL, writing ? "open the file as HDF5 to append a snapshot"
                                       : "open the file as HDF5 to read a snapshot");
        out->status = snapshot_io;
    }
    if (access_list >= 0) H5Pclose(access_list);
    call->transfer = H5Pcreate(H5P_DATASET_XFER);
    if (out->status == snapshot_ok && (call->transfer < 0 || H5Pset_dxpl_mpio(call->transfer, H5FD_MPIO_COLLECTIVE) < 0))
        hdf5_failed(out, NULL, "set up collective transfers");
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
        if (creating) create_group(&call, file, &out);
        else open_group(&call, file, &rows, &out);
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
    if (file >= 0 && H5Fclose(file) < 0) hdf5_failed(&out, NULL, "close the file after a snapshot");
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
            say(&out, snapshot_mismatch, "the file has no /%s: its run wrote no snapshot", group_name);
        else open_group(&call, file, &rows, &out);
        if (out.status == snapshot_ok && rows == 0) say(&out, snapshot_mismatch, "/%s holds no snapshot", group_name);
    }
    if (agree(&out, comm) == snapshot_ok) transfer_snapshot(&call, rows - 1, 1, &out);
    close_call(&call);
    if (call.transfer >= 0) H5Pclose(call.transfer);
    if (file >= 0 && H5Fclose(file) < 0) hdf5_failed(&out, NULL, "close the file after reading a snapshot");
    H5Eset_auto2(H5E_DEFAULT, printer, printer_data);
    return agree(&out, comm);
}
