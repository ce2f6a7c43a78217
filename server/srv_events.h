/* srv_events.h: the event hub of ipsd: workers and the API publish job progress events; HTTP
 * event streams (server-sent events) subscribe and read them. Publishing never blocks on a slow
 * reader: events live in a ring of fixed capacity, each subscriber keeps its own read position
 * and learns when it fell so far behind that events were dropped. A ticker thread counts
 * heartbeats so idle streams can send a keep-alive comment.
 *
 * Waiting without a thread per reader: a subscriber registers sleep and wake callbacks. When
 * srv_events_next finds nothing to read it marks the subscriber waiting and calls sleep(ctx)
 * under the hub lock (the HTTP layer suspends its connection there); the next publish, heartbeat
 * or shutdown calls wake(ctx) once, outside the lock (the HTTP layer resumes the connection).
 * A waiting subscriber is therefore always asleep when woken and woken at most once per sleep.
 * Thread-safe. */
#ifndef IPSD_SERVER_SRV_EVENTS_H
#define IPSD_SERVER_SRV_EVENTS_H

#include <stddef.h>
#include <stdint.h>

#include "base/err.h"

typedef struct srv_event {
    uint64_t seq;                    /* set by the hub: 1, 2, ... */
    int64_t job_id, scan_id, fit_id; /* 0: none */
    int kind;                        /* storage_job_kind_t */
    int state;                       /* storage_state_t */
    double progress;                 /* 0..1 */
    int points_done, points_total;   /* raster points (scan jobs), 0 for fits */
    double eta_s;                    /* estimated seconds left, NaN when unknown */
    char phase[16];  /* what the job does now: "queued", "exposure", "centre", "focus",
                        "raster", "fit", "done", ... */
    char error[160]; /* why it failed, "" otherwise */
    int has_pixel;   /* a job of every pixel: the pixel the event is about (fitting it, or its fit
                        fit_id just stored), as offsets from the POI and on the sensor */
    int dcol, drow, col, row;
    double expected_err; /* an adaptive scan: the expected rms error of the map of the points
                            taken so far (fit/adapt_plan.h); NaN (or 0, unset) otherwise */
    int has_expected;    /* expected_err is set */
} srv_event_t;

typedef struct srv_events srv_events_t;
typedef struct srv_sub srv_sub_t;

/* What srv_events_next found. */
enum srv_next {
    SRV_EV_CLOSED = -1,   /* the hub shut down: end the stream */
    SRV_EV_NONE = 0,      /* nothing: the subscriber is now waiting (sleep was called) */
    SRV_EV_EVENT = 1,     /* *out holds the next event */
    SRV_EV_HEARTBEAT = 2, /* a heartbeat period passed since the last one this reader saw */
    SRV_EV_LOST = 3,      /* the reader fell behind: events were dropped, reading goes on */
};

/* A hub keeping the last capacity events, with a heartbeat every heartbeat_ms (0: none).
 * *out is the caller's (srv_events_close). Returns 0, -EINVAL or -ENOMEM / a pthread error. */
int srv_events_open(size_t capacity, int heartbeat_ms, srv_events_t **out, err_t *err);

/* Stops the hub: every reader gets SRV_EV_CLOSED from now on; waiting readers are woken. */
void srv_events_shutdown(srv_events_t *h);

/* Shuts down (if not yet), stops the ticker and frees the hub. Every subscriber must have
 * unsubscribed. Accepts NULL. */
void srv_events_close(srv_events_t *h);

/* Publishes a copy of ev (its seq is assigned here) and wakes the waiting readers. */
void srv_events_publish(srv_events_t *h, const srv_event_t *ev);

/* A new reader positioned after the last published event. sleep and wake may be NULL (a reader
 * that polls). *out is released by srv_events_unsubscribe. Returns 0 or -ENOMEM. */
int srv_events_subscribe(srv_events_t *h, void (*sleep)(void *), void (*wake)(void *), void *ctx,
                         srv_sub_t **out);

/* Removes and frees the reader (accepts NULL). It must not be waiting. */
void srv_events_unsubscribe(srv_events_t *h, srv_sub_t *s);

/* The next thing for reader s (enum srv_next). */
int srv_events_next(srv_events_t *h, srv_sub_t *s, srv_event_t *out);

/* Number of subscribed readers (for a graceful shutdown to wait for streams to end). */
size_t srv_events_readers(srv_events_t *h);

#endif
