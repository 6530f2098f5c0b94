/* The machine a file was made on: its host name, for the provenance a run file records, and its
 * online cores and load averages, which a study index records at its start and end (both
 * src/io/provenance.f90). */
#define _DEFAULT_SOURCE /* gethostname, getloadavg */
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

/* The host name into `text` (`size` bytes, NUL-ended); "unknown" if the OS does not say. */
void eme_host_name(char *text, int size)
{
    if (size < 1) return;
    if (gethostname(text, (size_t)size) != 0) snprintf(text, (size_t)size, "unknown");
    text[size - 1] = '\0';
}

/* The 1-, 5- and 15-minute load averages into `averages` (-1 each where the OS gives none) and
 * the cores online into `cores` (0 if unknown). Online, not this process's affinity: a rank that
 * mpirun bound to one core still shares the machine's cores with everything the load counts. */
void eme_machine_load(double averages[3], int *cores)
{
    long online = sysconf(_SC_NPROCESSORS_ONLN);
    int k;
    int given = getloadavg(averages, 3);

    for (k = given < 0 ? 0 : given; k < 3; k++) averages[k] = -1.0;
    *cores = online > 0 ? (int)online : 0;
}
