/* Whether an input file can be read as a namelist, asked of the OS before Fortran opens it:
 * a FIFO would block Fortran's open and a device (/dev/zero) would never end, so the file is
 * opened non-blocking and must be a regular file. Called from src/util/namelist_text.f90. */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* 0 and the size in bytes for a readable regular file; -1 and the reason (the OS's words, or
 * what kind of file it is) otherwise. */
int eme_check_input_file(const char *path, long long *size, char *reason, int reason_size)
{
    struct stat status;
    const char *kind = NULL;
    int descriptor = open(path, O_RDONLY | O_NONBLOCK | O_NOCTTY);

    *size = 0;
    if (descriptor < 0) {
        snprintf(reason, (size_t)reason_size, "%s", strerror(errno));
        return -1;
    }
    if (fstat(descriptor, &status) != 0) {
        snprintf(reason, (size_t)reason_size, "%s", strerror(errno));
        close(descriptor);
        return -1;
    }
    close(descriptor);
    if (S_ISREG(status.st_mode)) {
        *size = (long long)status.st_size;
        return 0;
    }
    if (S_ISDIR(status.st_mode)) kind = "a directory";
    else if (S_ISFIFO(status.st_mode)) kind = "a FIFO (pipe)";
    else if (S_ISCHR(status.st_mode)) kind = "a character device";
    else if (S_ISBLK(status.st_mode)) kind = "a block device";
    else if (S_ISSOCK(status.st_mode)) kind = "a socket";
    else kind = "a special file";
    snprintf(reason, (size_t)reason_size, "it is %s, not a regular file", kind);
    return -1;
}
