/* clock.c — the monotonic clock and the UTC time stamp (see clock.h). */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "base/clock.h"

double crom_clock_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void crom_clock_utc(char *buf, size_t n)
{
    time_t t = time(NULL);
    const char *sde = getenv("SOURCE_DATE_EPOCH");
    if (sde && *sde)
        t = (time_t)strtoll(sde, NULL, 10);
    struct tm tm;
    gmtime_r(&t, &tm);
    strftime(buf, n, "%Y-%m-%dT%H:%M:%SZ", &tm);
}

int crom_clock_reproducible(void)
{
    const char *sde = getenv("SOURCE_DATE_EPOCH");
    return sde && *sde;
}

double crom_clock_wall(double seconds) { return crom_clock_reproducible() ? 0.0 : seconds; }
