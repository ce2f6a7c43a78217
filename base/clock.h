/* base/clock.h: the clocks every room reads: the monotonic clock for durations and timeouts, the
 * wall clock for timestamps that are stored, and absolute deadlines for timed waits. */
#ifndef IPSD_BASE_CLOCK_H
#define IPSD_BASE_CLOCK_H

#include <stdint.h>
#include <time.h>

/* CLOCK_MONOTONIC in milliseconds and in seconds (durations, ETAs, timing figures). */
double clock_mono_ms(void);
double clock_mono_s(void);

/* CLOCK_REALTIME in whole milliseconds since the Unix epoch (stored timestamps). */
int64_t clock_wall_ms(void);

/* The absolute time ms milliseconds from now on clock id (CLOCK_MONOTONIC or CLOCK_REALTIME),
 * for pthread_cond_timedwait and the like. */
struct timespec clock_deadline(clockid_t id, long ms);

#endif
