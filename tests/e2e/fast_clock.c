/* A machine that seems 100 times slower, for tests/e2e/test_kill_points.py: loaded with
 * LD_PRELOAD, it makes CLOCK_MONOTONIC run $EME_CLOCK_SPEED times faster (default 100) from the
 * process's first reading on, so that everything a program schedules by the clock comes due
 * after a hundredth of the work it would otherwise take. With $EME_CLOCK_TICK (seconds) the clock
 * instead counts its readings: each reading is the last one plus that tick, whatever the time
 * taken between them, so that a run's measured durations are the same on any machine
 * (tests/e2e/test_provenance.py: the per-step times that a strided row sums). Other clocks pass
 * through. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdlib.h>
#include <time.h>

int clock_gettime(clockid_t clock, struct timespec *now)
{
    static int (*real)(clockid_t, struct timespec *);
    static long double first = -1;
    static long readings = 0;
    if (real == NULL) real = (int (*)(clockid_t, struct timespec *))dlsym(RTLD_NEXT, "clock_gettime");
    int status = real(clock, now);
    if (status != 0 || clock != CLOCK_MONOTONIC) return status;
    long double seconds = (long double)now->tv_sec + (long double)now->tv_nsec * 1e-9L;
    if (first < 0) first = seconds;
    const char *tick = getenv("EME_CLOCK_TICK");
    if (tick != NULL) {
        seconds = first + (long double)(++readings) * strtold(tick, NULL);
    } else {
        const char *text = getenv("EME_CLOCK_SPEED");
        long double speed = text != NULL ? strtold(text, NULL) : 100;
        seconds = first + (seconds - first) * speed;
    }
    now->tv_sec = (time_t)seconds;
    now->tv_nsec = (long)((seconds - (long double)now->tv_sec) * 1e9L);
    return 0;
}
