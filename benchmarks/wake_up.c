/* What one wake-up of a 1 kHz loop costs this machine, with no Python and nothing done: the
 * thread's CPU per 1 ms deadline over DEADLINES deadlines (default 5000), sleeping to each
 * (clock_nanosleep to an absolute deadline, as Python's time.sleep does). Compare with the
 * wake-up figure of pam_bringup.model_cost (the same loop in Python).
 *
 *   gcc -O2 -o /tmp/wake_up benchmarks/wake_up.c && /tmp/wake_up [DEADLINES]
 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double seconds(const struct timespec *t) { return t->tv_sec + 1e-9 * t->tv_nsec; }

int main(int argc, char **argv)
{
    const int deadlines = argc > 1 ? atoi(argv[1]) : 5000;
    if (deadlines < 1 || argc > 2) {
        fprintf(stderr, "usage: %s [DEADLINES >= 1]\n", argv[0]);
        return 2;
    }
    struct timespec deadline, cpu0, cpu1;
    clock_gettime(CLOCK_MONOTONIC, &deadline);
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu0);
    for (int k = 0; k < deadlines; ++k) {
        deadline.tv_nsec += 1000000;
        if (deadline.tv_nsec >= 1000000000) {
            deadline.tv_nsec -= 1000000000;
            ++deadline.tv_sec;
        }
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, NULL);
    }
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu1);
    printf("a 1 kHz wake-up in C: %.1f us of CPU each (%d deadlines)\n",
           (seconds(&cpu1) - seconds(&cpu0)) / deadlines * 1e6, deadlines);
    return 0;
}
