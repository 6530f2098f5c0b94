/* The machine's host name, for the provenance a run file records (src/io/provenance.f90). */
#define _DEFAULT_SOURCE /* gethostname */
#include <stdio.h>
#include <unistd.h>

/* The host name into `text` (`size` bytes, NUL-ended); "unknown" if the OS does not say. */
void eme_host_name(char *text, int size)
{
    if (size < 1) return;
    if (gethostname(text, (size_t)size) != 0) snprintf(text, (size_t)size, "unknown");
    text[size - 1] = '\0';
}
