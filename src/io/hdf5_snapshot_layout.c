/* The group /snapshots of a run file (docs/output.md, Snapshots), as the snapshot storage
 * (hdf5_snapshot_storage.c, which opens the file and transfers the values collectively) makes it
 * on the first snapshot and finds it on later ones: its datasets, their shapes and chunks, their
 * texts, and the dimension scales time, mass, spring and component. What the two files share is
 * hdf5_snapshot_storage.h.
 *
 * A chunk of a per-mass dataset holds one snapshot of at most CHUNK_VALUES numbers (256 KiB), the
 * masses split evenly (chunk_length): for N = 10^5 masses in 3 components, (1, 10000, 3), 10
 * chunks a snapshot. One chunk per snapshot (2.4 MB) would send the whole of q to one rank; with
 * ten, a rank receives only the parts of the chunks that straddle its neighbours' ranges, and
 * every chunk fits HDF5's default 1 MiB chunk cache when read. The texts (units, description,
 * dims) are fixed-length strings: they live in the object headers, which carry checksums of their
 * own in HDF5 1.8's format, and stay out of the heap that the file's text_checksum covers
 * (hdf5_text_checksum.c), which this writer does not hold. */
#include <hdf5.h>
#include <hdf5_hl.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hdf5_snapshot_storage.h"

enum { CHUNK_VALUES = 32768, TIME_CHUNK = 64 };

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
int eme_snapshot_shape_of(const snapshot_set *set, hsize_t n, hsize_t masses, hsize_t springs, hsize_t d,
                          hsize_t *dims, hsize_t *chunk, hsize_t *maximum)
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
            status = labels != NULL ? eme_snapshot_transfer_part(scale, type, transfer, comm, 1, &first, &count,
                                                                 labels + first, 0)
                                    : eme_snapshot_transfer_part(scale, H5T_NATIVE_LLONG, transfer, comm, 1, &first,
                                                                 &count, numbers, 0);
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

/* Creates /snapshots with its empty datasets and their dimension scales (time, mass, spring,
 * component). */
void eme_snapshot_create_group(snapshot_call *call, hid_t file, report *out)
{
    static const char *const axes[3][3] = {{"time"}, {"time", "mass", "component"}, {"time", "spring"}};
    call->group = H5Gcreate2(file, group_name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (call->group < 0) {
        eme_snapshot_hdf5_failed(out, NULL, "create the group /snapshots");
        return;
    }
    const char *group_text = "the state at chosen times, written by every rank in parallel";
    if (write_fixed_texts(call->group, "description", &group_text, 0) < 0) {
        eme_snapshot_hdf5_failed(out, NULL, "describe the group /snapshots");
        return;
    }
    for (int s = 0; s < SET_COUNT; ++s) {
        const snapshot_set *set = &call->sets[s];
        if (set->local == NULL) continue;
        hsize_t dims[3], chunk[3], maximum[3];
        int rank = eme_snapshot_shape_of(set, 0, call->masses, call->springs, call->dimension, dims, chunk, maximum);
        hid_t space = H5Screate_simple(rank, dims, maximum);
        hid_t creation = checked_chunks(rank, chunk);
        if (space >= 0 && creation >= 0)
            call->datasets[s] = H5Dcreate2(call->group, set->name, H5T_IEEE_F64LE, space, H5P_DEFAULT, creation, H5P_DEFAULT);
        if (creation >= 0) H5Pclose(creation);
        if (space >= 0) H5Sclose(space);
        if (call->datasets[s] < 0 || describe(call->datasets[s], set->units, set->description, axes[set->per], rank) < 0) {
            eme_snapshot_hdf5_failed(out, set->name, "create");
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
    if (status != 0) eme_snapshot_hdf5_failed(out, "mass, spring and component", "make the dimension scales");
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
void eme_snapshot_open_group(snapshot_call *call, hid_t file, hsize_t *rows, report *out)
{
    call->group = H5Gopen2(file, group_name, H5P_DEFAULT);
    if (call->group < 0) {
        eme_snapshot_hdf5_failed(out, NULL, "open the group /snapshots");
        return;
    }
    for (int s = 0; s < SET_COUNT && out->status == snapshot_ok; ++s) {
        const snapshot_set *set = &call->sets[s];
        int stored = set->name[0] != '\0' && H5Lexists(call->group, set->name, H5P_DEFAULT) > 0;
        if (set->local == NULL) {
            if (stored)
                eme_snapshot_say(out, snapshot_mismatch, "/%s/%s is in the file, and this snapshot has no %s",
                    group_name, set->name, set->name);
            continue;
        }
        if (!stored) {
            eme_snapshot_say(out, snapshot_mismatch, "/%s/%s is not in the file; its snapshots were written without %s",
                group_name, set->name, set->name);
            return;
        }
        call->datasets[s] = H5Dopen2(call->group, set->name, H5P_DEFAULT);
        hid_t space = call->datasets[s] >= 0 ? H5Dget_space(call->datasets[s]) : -1;
        hsize_t found[3] = {0, 0, 0}, dims[3], chunk[3], maximum[3];
        int rank = eme_snapshot_shape_of(set, 0, call->masses, call->springs, call->dimension, dims, chunk, maximum);
        int found_rank = space >= 0 ? H5Sget_simple_extent_dims(space, found, NULL) : -1;
        if (space >= 0) H5Sclose(space);
        if (found_rank < 0) {
            eme_snapshot_hdf5_failed(out, set->name, "open");
            return;
        }
        if (s == SET_TIME) *rows = found[0];
        char found_shape[64], given_shape[64];
        shape_text(found_shape, found + 1, found_rank - 1);
        shape_text(given_shape, dims + 1, rank - 1);
        if (strcmp(found_shape, given_shape) != 0)
            eme_snapshot_say(out, snapshot_mismatch, "/%s/%s holds snapshots of shape %s; this snapshot's %s is %s",
                group_name, set->name, found_shape, set->name, given_shape);
        else if (found[0] != *rows)
            eme_snapshot_say(out, snapshot_mismatch, "/%s/%s holds %llu snapshots, /%s/time %llu", group_name,
                set->name, (unsigned long long)found[0], group_name, (unsigned long long)*rows);
    }
    /* Another thermodynamic variable than the one written before. */
    static const char *const variables[2] = {"entropy", "internal_energy"};
    for (int v = 0; v < 2 && out->status == snapshot_ok; ++v)
        if (strcmp(variables[v], call->sets[SET_TAU].name) != 0 && H5Lexists(call->group, variables[v], H5P_DEFAULT) > 0)
            eme_snapshot_say(out, snapshot_mismatch, "/%s/%s is in the file, and this snapshot has %s", group_name,
                variables[v], call->sets[SET_TAU].name[0] ? call->sets[SET_TAU].name : "no tau (tau is theta)");
}
