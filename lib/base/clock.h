/* clock.h — time for crom (base layer): the monotonic clock that times
 * steps and training, and the wall-clock stamps written into files, which
 * SOURCE_DATE_EPOCH makes reproducible.
 */
#ifndef CROM_CLOCK_H
#define CROM_CLOCK_H

#include <stddef.h>

/* Monotonic seconds (for durations). */
double crom_clock_now(void);

/* 1 when SOURCE_DATE_EPOCH is set: outputs must then be byte-reproducible,
 * so history uses that time and recorded wall-clock durations are 0. */
int crom_clock_reproducible(void);

/* A wall-clock duration to store in a file: `seconds`, or 0 when
 * reproducible output is asked for. */
double crom_clock_wall(double seconds);

/* "2026-11-22T03:00:00Z" for now, or for SOURCE_DATE_EPOCH when set. */
void crom_clock_utc(char *buf, size_t n);

#endif
