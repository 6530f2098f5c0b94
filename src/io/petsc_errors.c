/* PETSc's errors as one line for the drivers (src/io/command_line.f90): an error handler that
 * keeps the first message of the latest error and prints nothing, so that a bad option (an
 * unknown -snes_type, a missing -options_file) ends with the project's one-line message and
 * exit status 2 instead of PETSc's traceback. (The files PETSc's options would write are
 * checked in petsc_option_files.c.) */
#include <stdio.h>
#include <petscsys.h>

static char first_message[1024];

static PetscErrorCode keep_first_message(MPI_Comm comm, int line, const char *function, const char *file,
                                         PetscErrorCode code, PetscErrorType kind, const char *message, void *context)
{
    (void)comm; (void)line; (void)file; (void)context;
    if (kind == PETSC_ERROR_INITIAL) {
        const char *generic = NULL;
        if (PetscErrorMessage(code, &generic, NULL) != 0 || generic == NULL) generic = "PETSc error";
        if (message != NULL && message[0] != '\0')
            snprintf(first_message, sizeof first_message, "%s (%s)", message, function ? function : "?");
        else
            snprintf(first_message, sizeof first_message, "%s (%s)", generic, function ? function : "?");
        /* PETSc's messages may carry line ends; one line is wanted. */
        for (char *c = first_message; *c != '\0'; ++c)
            if (*c == '\n' || *c == '\r') *c = ' ';
    }
    return code;
}

/* From now on PETSc's errors are returned, not printed; callable before PetscInitialize (PETSc
 * allocates with malloc until then). 0 on success. */
int eme_petsc_capture_errors(void)
{
    first_message[0] = '\0';
    return (int)PetscPushErrorHandler(keep_first_message, NULL);
}

/* The first message of PETSc's latest error ('' if none), at most size - 1 characters. */
void eme_petsc_error_text(char *text, int size)
{
    snprintf(text, (size_t)size, "%s", first_message);
}
