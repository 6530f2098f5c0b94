/* SIGTERM and SIGINT (a batch scheduler's warning, Ctrl-C) are caught, not obeyed at once: the
 * handler only records the signal, and the time loop and the ensemble's scheduler look at it
 * between steps, stop, and leave their files marked (docs/faults.md). The handler
 * then restores the default action, so a second signal ends the process at once. SIGXFSZ is
 * ignored, so that a file-size limit (ulimit -f) makes writes fail with EFBIG, which the code
 * reports, instead of killing the process. Called from Fortran (src/run/run_signals.f90). */
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <string.h>

static volatile sig_atomic_t caught = 0;

static void remember(int number)
{
    if (caught == 0) caught = number;
    signal(number, SIG_DFL);
}

/* Installs the handlers (again, harmlessly). Returns 0, or -1 if the OS refused. */
int eme_install_interrupt_handlers(void)
{
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = remember;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;
    int status = 0;
    if (caught == 0) {
        if (sigaction(SIGTERM, &action, NULL) != 0) status = -1;
        if (sigaction(SIGINT, &action, NULL) != 0) status = -1;
    }
    if (signal(SIGXFSZ, SIG_IGN) == SIG_ERR) status = -1;
    return status;
}

/* The first SIGTERM or SIGINT caught so far, or 0. */
int eme_interrupting_signal(void)
{
    return (int)caught;
}

/* Signal numbers of this platform. */
int eme_signal_number(int which)
{
    return which == 0 ? SIGTERM : SIGINT;
}
