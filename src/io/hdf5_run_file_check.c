/* Reading a finished HDF5 file back (docs/faults.md): whether a run file's datasets have the rows
 * its attributes say, whether every dataset reads whole (a damaged chunk fails its Fletcher-32
 * checksum) and every text its checksum (hdf5_text_checksum.c), and whether its summary
 * attributes are those of the datasets they summarise; and what kind of file a path holds (a
 * run file of this project, another HDF5 file). A file grown in windows is checked this way, one
 * written whole by its size (hdf5_storage.c, whose eme_h5_open_file opens the files read here).
 * Called from Fortran through bind(C) (src/io/hdf5_files.f90) and from path_identity.c. */
#include <float.h>
#include <math.h>
#include <hdf5.h>
#include <stdlib.h>
#include <string.h>

int eme_h5_open_file(const char *path, int writable, long reserve, int wait_ms, hid_t *file);  /* hdf5_storage.c */
int eme_h5_read_text_attribute(hid_t object, const char *name, char *text, int capacity);  /* hdf5_text.c */
int eme_h5_verify_texts(hid_t file);                                              /* hdf5_text_checksum.c */

/* First dimension of dataset `name` in `file`, or -1. */
long eme_h5_dataset_rows(hid_t file, const char *name)
{
    hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    if (dataset < 0) return -1;
    hid_t space = H5Dget_space(dataset);
    hsize_t dims[H5S_MAX_RANK];
    long rows = -1;
    if (space >= 0 && H5Sget_simple_extent_ndims(space) >= 1 && H5Sget_simple_extent_dims(space, dims, NULL) >= 1)
        rows = (long)dims[0];
    if (space >= 0) H5Sclose(space);
    H5Dclose(dataset);
    return rows;
}

typedef struct {
    long steps;
    int mismatches;
    int datasets;
} row_check;

/* For each dataset of the root group: a `rows` attribute of 'point' needs steps + 1 rows, of
 * 'step' steps rows. */
static herr_t check_rows(hid_t group, const char *name, const H5L_info_t *info, void *data)
{
    (void)info;
    row_check *check = data;
    hid_t dataset = H5Oopen(group, name, H5P_DEFAULT);
    if (dataset < 0) {
        check->mismatches++;
        return 0;
    }
    if (H5Iget_type(dataset) != H5I_DATASET) {
        H5Oclose(dataset);
        return 0;
    }
    char rows[16] = "";
    if (eme_h5_read_text_attribute(dataset, "rows", rows, (int)sizeof rows) == 0) {
        long expected = strcmp(rows, "point") == 0 ? check->steps + 1 : strcmp(rows, "step") == 0 ? check->steps : -1;
        long found = eme_h5_dataset_rows(group, name);
        check->datasets++;
        if (expected >= 0 && found != expected) check->mismatches++;
    }
    H5Oclose(dataset);
    return 0;
}

/* The integer root attribute `name` of `file`, or -1 if it is missing or unreadable. */
static long long integer_attribute(hid_t file, const char *name)
{
    long long value = -1;
    if (H5Aexists(file, name) <= 0) return -1;
    hid_t attribute = H5Aopen(file, name, H5P_DEFAULT);
    if (attribute < 0) return -1;
    if (H5Aread(attribute, H5T_NATIVE_LLONG, &value) < 0) value = -1;
    H5Aclose(attribute);
    return value;
}

/* Every value of dataset `name` of `file` as doubles (numbers; NULL for other types or on a
 * failed read: a checksum that does not hold) and their count in *count; 0, or -1 if the
 * dataset cannot be read whole. A dataset of texts is read and its texts freed. */
static int read_values(hid_t file, const char *name, double **values, hssize_t *count)
{
    *values = NULL;
    *count = 0;
    hid_t dataset = H5Dopen2(file, name, H5P_DEFAULT);
    if (dataset < 0) return -1;
    hid_t space = H5Dget_space(dataset), stored = H5Dget_type(dataset);
    int status = -1;
    if (space >= 0 && stored >= 0 && (*count = H5Sget_simple_extent_npoints(space)) >= 0) {
        if (H5Tget_class(stored) == H5T_INTEGER || H5Tget_class(stored) == H5T_FLOAT) {
            *values = malloc((size_t)(*count > 0 ? *count : 1) * sizeof **values);
            if (*values != NULL && H5Dread(dataset, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, *values) >= 0)
                status = 0;
        } else {
            hid_t memory = H5Tget_native_type(stored, H5T_DIR_ASCEND);
            size_t size = memory >= 0 ? H5Tget_size(memory) : 0;
            void *buffer = size > 0 ? malloc((size_t)(*count > 0 ? *count : 1) * size) : NULL;
            if (buffer != NULL && H5Dread(dataset, memory, H5S_ALL, H5S_ALL, H5P_DEFAULT, buffer) >= 0) {
                status = 0;
                if (H5Tis_variable_str(memory) > 0 || H5Tdetect_class(memory, H5T_VLEN) > 0)
                    H5Dvlen_reclaim(memory, space, H5P_DEFAULT, buffer);
            }
            free(buffer);
            if (memory >= 0) H5Tclose(memory);
        }
    }
    if (status != 0) {
        free(*values);
        *values = NULL;
    }
    if (stored >= 0) H5Tclose(stored);
    if (space >= 0) H5Sclose(space);
    H5Dclose(dataset);
    return status;
}

/* Reads every dataset of the root group whole (H5Literate callback): a damaged chunk fails its
 * Fletcher-32 checksum here. */
static herr_t read_whole(hid_t group, const char *name, const H5L_info_t *info, void *data)
{
    (void)info;
    int *failures = data;
    H5O_info_t object;
    if (H5Oget_info_by_name(group, name, &object, H5P_DEFAULT) < 0) {
        ++*failures;
        return 0;
    }
    if (object.type != H5O_TYPE_DATASET) return 0;
    double *values;
    hssize_t count;
    if (read_values(group, name, &values, &count) != 0) ++*failures;
    free(values);
    return 0;
}

/* Whether `recorded` (from an attribute) is what the datasets give, `found`: the same number
 * (both NaN alike), or within a few units of the last place for a figure the reader
 * recomputes in another order. */
static int same_figure(double recorded, double found)
{
    if (recorded != recorded || found != found) return (recorded != recorded) == (found != found);
    return fabs(recorded - found) <= 4 * DBL_EPSILON * fmax(fabs(recorded), fabs(found));
}

/* The dataset `name` of `file` whole, or NULL if the file has none (*count 0); -1 if it cannot
 * be read. */
static int optional_values(hid_t file, const char *name, double **values, hssize_t *count)
{
    *values = NULL;
    *count = 0;
    if (H5Lexists(file, name, H5P_DEFAULT) <= 0) return 0;
    return read_values(file, name, values, count);
}

/* The largest drift max_n |J_n.a - J_0.a| over the conserved momentum components of a run file
 * (their axes a: the root attribute conserved_momentum_axes, 3 numbers each) from the `points`
 * rows of /angular_momentum, `columns` wide (J_x J_y J_z, or the planar J about e_z); files
 * older than the attribute conserved J_z. Summed in the order the time loop sums them
 * (src/structure/model_interface.f90, component_values); -1 if the axes cannot be read, -2 if
 * no component is conserved (conserved_momentum = 'none'). */
static double conserved_momentum_drift(hid_t file, const double *momentum, hssize_t points, hssize_t columns)
{
    double axes[3 * 3] = {0, 0, 1};
    hssize_t count = 1;
    if (H5Aexists(file, "conserved_momentum_axes") > 0) {
        hid_t attribute = H5Aopen(file, "conserved_momentum_axes", H5P_DEFAULT);
        hid_t shape = attribute >= 0 ? H5Aget_space(attribute) : -1;
        hssize_t numbers = shape >= 0 ? H5Sget_simple_extent_npoints(shape) : 0;
        count = numbers / 3;
        int readable = numbers == 3 * count && count >= 1 && count <= 3 &&
                       H5Aread(attribute, H5T_NATIVE_DOUBLE, axes) >= 0;
        if (shape >= 0) H5Sclose(shape);
        if (attribute >= 0) H5Aclose(attribute);
        if (!readable) return -1;
    } else if (H5Aexists(file, "conserved_momentum") > 0) {
        return -2;
    }
    double drift = 0;
    for (hssize_t k = 0; k < count; ++k) {
        const double *a = axes + 3 * k;
        double first = 0;
        for (hssize_t i = 0; i < points; ++i) {
            const double *j = momentum + columns * i;
            double value = columns == 3 ? j[0] * a[0] + j[1] * a[1] + j[2] * a[2] : j[0] * a[2];
            if (i == 0) first = value;
            drift = fmax(drift, fabs(value - first));
        }
    }
    return drift;
}

/* The summary attributes of a run file against the datasets they summarise (src/run/simulation
 * .f90 computes both): newton_iterations_total is the sum of newton_iterations; run_figures'
 * min_entropy_increment and max_lyapunov_increment are the extremes of those datasets, and its
 * energy drift, conserved momentum drift (conserved_momentum_drift) and lowest temperature are
 * those of the points stored (equal when every point is stored, else no better than the points
 * show). 0 if all holds (or the file predates the attributes), 1 if not, -1 if a dataset cannot
 * be read. */
static int check_figures(hid_t file, long long steps)
{
    double figures[7];
    int mismatches = 0, failed = 0;
    if (steps <= 0 || H5Aexists(file, "run_figures") <= 0) return 0;
    hid_t attribute = H5Aopen(file, "run_figures", H5P_DEFAULT);
    hid_t shape = attribute >= 0 ? H5Aget_space(attribute) : -1;
    int readable = shape >= 0 && H5Sget_simple_extent_npoints(shape) == 7 &&
                   H5Aread(attribute, H5T_NATIVE_DOUBLE, figures) >= 0;
    if (shape >= 0) H5Sclose(shape);
    if (attribute >= 0) H5Aclose(attribute);
    if (!readable) return 1;
    long long newton_total = integer_attribute(file, "newton_iterations_total");
    double *newton, *dS, *dV, *energy, *heat, *momentum, *theta;
    hssize_t n_newton, n_dS, n_dV, n_energy, n_heat, n_momentum, n_theta;
    failed |= optional_values(file, "newton_iterations", &newton, &n_newton);
    failed |= optional_values(file, "min_entropy_increment", &dS, &n_dS);
    failed |= optional_values(file, "max_lyapunov_increment", &dV, &n_dV);
    failed |= optional_values(file, "energy", &energy, &n_energy);
    failed |= optional_values(file, "boundary_heat", &heat, &n_heat);
    failed |= optional_values(file, "angular_momentum", &momentum, &n_momentum);
    failed |= optional_values(file, "temperature", &theta, &n_theta);
    if (!failed) {
        long long points = n_energy;
        int every_point = points == steps + 1;
        if (newton != NULL && newton_total >= 0) {
            double sum = 0;
            for (hssize_t i = 0; i < n_newton; ++i) sum += newton[i];
            mismatches += sum != (double)newton_total;
        }
        if (dS != NULL && n_dS > 0) {
            double low = dS[0];
            for (hssize_t i = 1; i < n_dS; ++i) low = fmin(low, dS[i]);
            mismatches += !same_figure(figures[1], low);
        }
        if (dV != NULL && n_dV > 0) {
            double high = dV[0];
            for (hssize_t i = 1; i < n_dV; ++i) high = fmax(high, dV[i]);
            mismatches += !same_figure(figures[2], high);
        }
        /* Figures over the points: recomputed, then equal (every point) or bounded by the record. */
        double found[3] = {0, 0, HUGE_VAL};
        int have[3] = {0, 0, 0};
        if (energy != NULL && points > 0 && (heat == NULL || n_heat == points)) {
            for (hssize_t i = 0; i < points; ++i)
                found[0] = fmax(found[0], fabs(energy[i] - energy[0] - (heat ? heat[i] : 0)) / fabs(energy[0]));
            have[0] = 1;
        }
        if (momentum != NULL && points > 0 && (n_momentum == 3 * points || n_momentum == points)) {
            found[1] = conserved_momentum_drift(file, momentum, points, n_momentum / points);
            have[1] = found[1] >= 0;
            mismatches += found[1] == -1;
        }
        if (theta != NULL && n_theta > 0) {
            for (hssize_t i = 0; i < n_theta; ++i) found[2] = theta[i] != theta[i] ? NAN : fmin(found[2], theta[i]);
            have[2] = 1;
        }
        const int slot[3] = {0, 3, 4};
        for (int k = 0; k < 3; ++k) {
            if (!have[k]) continue;
            double recorded = figures[slot[k]];
            if (every_point) mismatches += !same_figure(recorded, found[k]);
            else if (k < 2) mismatches += !(found[k] <= recorded * (1 + 4 * DBL_EPSILON));
            else mismatches += !(recorded <= found[k] || (recorded != recorded && found[k] != found[k]));
        }
    }
    free(newton), free(dS), free(dV), free(energy), free(heat), free(momentum), free(theta);
    return failed ? -1 : mismatches > 0;
}

/* Whether the open `file` reads whole: every dataset of its root group (a damaged chunk fails its
 * Fletcher-32 checksum), and its texts against their checksum (eme_h5_verify_texts). 0 if so, 4
 * if a dataset cannot be read, 6 if a text fails its checksum or cannot be read. */
static int file_integrity(hid_t file)
{
    int failures = 0;
    hsize_t position = 0;
    if (H5Literate(file, H5_INDEX_NAME, H5_ITER_NATIVE, &position, read_whole, &failures) < 0 || failures > 0) return 4;
    int texts = eme_h5_verify_texts(file);
    return texts == 0 || texts == 2 ? 0 : 6;
}

/* Whether the HDF5 file at `path` is whole (file_integrity): 0, 1 if it cannot be opened, 4 or 6. */
int eme_h5_check_integrity(const char *path)
{
    hid_t file;
    if (eme_h5_open_file(path, 0, 0, 0, &file) != 0) return 1;
    int result = file_integrity(file);
    if (H5Fclose(file) < 0 && result == 0) result = 1;
    return result;
}

/* What the file at `path` is: 1 a run file of this project (its root has the attributes status
 * and steps_completed, as every run file has had), 2 another HDF5 file (a study's index.h5,
 * another program's data), 0 no HDF5 file that opens. */
int eme_h5_file_kind(const char *path)
{
    hid_t file;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);     /* (called before the Fortran side opened HDF5 too) */
    if (H5Fis_hdf5(path) <= 0 || eme_h5_open_file(path, 0, 0, 0, &file) != 0) return 0;
    int kind = H5Aexists(file, "status") > 0 && H5Aexists(file, "steps_completed") > 0 ? 1 : 2;
    H5Fclose(file);
    return kind;
}

/* Reads a run file back: its `status` into `status` (capacity bytes) and `steps_completed`, and
 * checks that every per-point dataset has R + 1 rows and every per-step dataset R rows, R being
 * the attribute step_rows (a row can stand for several steps: &output every), or
 * steps_completed in files without it. With `whole`, it also reads every dataset whole (a
 * damaged chunk fails its checksum), checks its texts against their checksum, and checks the
 * summary attributes against the datasets (check_figures). Returns 0 if all holds, 1 if the file
 * cannot be opened, 2 if status or steps_completed is missing, 3 if a dataset has the wrong
 * length or cannot be read, 4 if a dataset fails its checksum (`whole`), 5 if a summary attribute
 * disagrees with the datasets, 6 if a text fails its checksum (`whole`). */
int eme_h5_check_run_file(const char *path, char *status, int capacity, long *steps_completed, int whole)
{
    hid_t file;
    status[0] = '\0';
    *steps_completed = -1;
    if (eme_h5_open_file(path, 0, 0, 0, &file) != 0) return 1;
    int result = 2;
    long long steps = integer_attribute(file, "steps_completed");
    if (eme_h5_read_text_attribute(file, "status", status, capacity) == 0 && steps >= 0) {
        long long rows = H5Aexists(file, "step_rows") > 0 ? integer_attribute(file, "step_rows") : steps;
        row_check check = {(long)rows, 0, 0};
        *steps_completed = (long)steps;
        hsize_t position = 0;
        if (rows < 0 || H5Literate(file, H5_INDEX_NAME, H5_ITER_NATIVE, &position, check_rows, &check) < 0)
            check.mismatches++;
        result = check.mismatches == 0 && check.datasets > 0 ? 0 : 3;
        if (result == 0 && whole) {
            result = file_integrity(file);
            if (result == 0 && check_figures(file, steps) != 0) result = 5;
        }
    }
    if (H5Fclose(file) < 0 && result == 0) result = 1;
    return result;
}
