/* api_sse.c: GET /api/events, the job progress stream (text/event-stream). Each stream subscribes
 * to the server's event hub; its content reader sends what is there and, when nothing is, suspends
 * its connection (the hub's sleep callback, run under the hub lock) until the hub resumes it for
 * the next event, heartbeat or the shutdown. So a waiting stream costs no thread. Events:
 *   event: job / id: SEQ / data: {"id", "kind", "state", "progress", "points_done",
 *   "points_total", "eta_s", "scan_id", "fit_id", "phase", "error"[, "pixel": {"dcol", "drow",
 *   "col", "row"}][, "expected_err"]} (pixel: a job of every pixel, the pixel being fitted or
 *   whose fit fit_id was just stored; expected_err: an adaptive scan's map at its last plan)
 * and a ": heartbeat" comment every --heartbeat seconds. ?job=ID sends that job's events only,
 * starting with its current state. POST /api/events/ticket gives a client that cannot send a
 * header (a browser's EventSource) a short-lived ticket for ?ticket= (server/srv_token.h). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "server/srv_token.h"

#include "api_int.h"

struct sse {
    srv_t *srv;
    struct MHD_Connection *conn;
    srv_sub_t *sub;
    int64_t job;    /* only this job's events; 0: all */
    char buf[2048]; /* text not yet sent: [off, len) */
    size_t off, len;
};

static void sse_sleep(void *ctx)
{
    MHD_suspend_connection(((struct sse *)ctx)->conn);
}
static void sse_wake(void *ctx)
{
    MHD_resume_connection(((struct sse *)ctx)->conn);
}

/* Appends the event to the unsent text (the buffer is empty when the reader formats one). */
static void put_event(struct sse *s, const srv_event_t *ev)
{
    json_t *o = json_pack(
        "{s:I, s:s, s:s, s:f, s:i, s:i, s:o, s:o, s:o, s:s, s:o}", "id", (json_int_t)ev->job_id,
        "kind", storage_job_kind_name(ev->kind), "state", storage_state_name(ev->state), "progress",
        ev->progress, "points_done", ev->points_done, "points_total", ev->points_total, "eta_s",
        api_num(ev->eta_s), "scan_id", ev->scan_id ? json_integer(ev->scan_id) : json_null(),
        "fit_id", ev->fit_id ? json_integer(ev->fit_id) : json_null(), "phase", ev->phase, "error",
        ev->error[0] ? json_string(ev->error) : json_null());
    if (o && ev->has_pixel) /* a job of every pixel: which one */
        json_object_set_new(o, "pixel",
                            json_pack("{s:i, s:i, s:i, s:i}", "dcol", ev->dcol, "drow", ev->drow,
                                      "col", ev->col, "row", ev->row));
    if (o && ev->has_expected) /* an adaptive scan: the map's expected rms error so far */
        json_object_set_new(o, "expected_err", api_num(ev->expected_err));
    char *data = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(10)) : NULL;
    json_decref(o);
    if (!data) return;
    size_t room = sizeof s->buf - s->len;
    int n = snprintf(s->buf + s->len, room, "event: job\nid: %llu\ndata: %s\n\n",
                     (unsigned long long)ev->seq, data);
    if (n > 0 && (size_t)n < room) s->len += (size_t)n; /* (an event is < 1 KiB: always fits) */
    free(data);
}

/* Replaces the unsent text (empty when called) with a comment or field line. */
static void put_text(struct sse *s, const char *text)
{
    s->len = (size_t)snprintf(s->buf, sizeof s->buf, "%s", text);
    s->off = 0;
}

static ssize_t sse_read(void *cls, uint64_t pos, char *out, size_t max)
{
    (void)pos;
    struct sse *s = cls;
    for (;;) {
        if (s->off < s->len) {
            size_t n = s->len - s->off < max ? s->len - s->off : max;
            memcpy(out, s->buf + s->off, n);
            s->off += n;
            return (ssize_t)n;
        }
        s->off = s->len = 0;
        srv_event_t ev;
        switch (srv_events_next(srv_events(s->srv), s->sub, &ev)) {
        case SRV_EV_EVENT:
            if (!s->job || ev.job_id == s->job) put_event(s, &ev);
            break;
        case SRV_EV_HEARTBEAT:
            put_text(s, ": heartbeat\n\n");
            break;
        case SRV_EV_LOST:
            put_text(s, ": some events were dropped (slow reader)\n\n");
            break;
        case SRV_EV_CLOSED:
            return MHD_CONTENT_READER_END_OF_STREAM;
        default:
            return 0; /* suspended until the hub wakes us */
        }
    }
}

static void sse_free(void *cls)
{
    struct sse *s = cls;
    srv_events_unsubscribe(srv_events(s->srv), s->sub);
    free(s);
}

/* The current state of the job the stream follows, as its first event. */
static void first_event(api_req_t *q, struct sse *s)
{
    storage_job_t j;
    storage_scan_t sc;
    storage_t *st = api_db(q);
    if (!st || storage_job_get(st, s->job, &j, NULL)) return;
    srv_event_t ev = {.job_id = j.id,
                      .scan_id = j.scan_id,
                      .fit_id = j.fit_id,
                      .kind = j.kind,
                      .state = j.state,
                      .progress = j.progress,
                      .points_done = j.points_done,
                      .eta_s = NAN};
    if (j.kind == STORAGE_JOB_SCAN && j.scan_id &&
        storage_scan_get(st, j.scan_id, &sc, NULL) == 0) {
        ev.points_total = sc.points_total;
        storage_scan_free(&sc);
    }
    snprintf(ev.phase, sizeof ev.phase, "%s", storage_state_name(j.state));
    if (j.error) snprintf(ev.error, sizeof ev.error, "%s", j.error);
    put_event(s, &ev);
    storage_job_free(&j);
}

void api_h_events_ticket(api_req_t *q)
{
    char t[SRV_TICKET_MAX];
    err_t err = {{0}};
    if (srv_token_ticket((long long)clock_mono_ms(), SRV_TICKET_TTL_MS, t, &err)) {
        api_error(q, 500, "internal", NULL, "%s", err.msg);
        return;
    }
    api_reply_json(q, 200,
                   json_pack("{s:s, s:i}", "ticket", t, "expires_in_s", SRV_TICKET_TTL_MS / 1000));
    if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
    explicit_bzero(t, sizeof t);
}

void api_h_events(api_req_t *q)
{
    long long job;
    if (api_query_int(q, "job", 0, 0, INT64_MAX, &job)) return;
    size_t cap = (size_t)srv_config(q->srv)->max_subscribers;
    if (srv_events_readers(srv_events(q->srv)) >= cap) {
        api_error(q, 503, "busy", NULL,
                  "%zu event streams are open, the most ipsd serves (--max-subscribers): "
                  "try again later",
                  cap);
        if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_RETRY_AFTER, "5");
        return;
    }
    struct sse *s = calloc(1, sizeof *s);
    if (!s || srv_events_subscribe(srv_events(q->srv), sse_sleep, sse_wake, s, &s->sub)) {
        free(s);
        api_error(q, 503, "unavailable", NULL, "cannot follow events now");
        return;
    }
    s->srv = q->srv;
    s->conn = q->conn;
    s->job = job;
    put_text(s, "retry: 3000\n: ipsd events\n\n");
    if (job) first_event(q, s);
    q->resp = MHD_create_response_from_callback(MHD_SIZE_UNKNOWN, 4096, sse_read, s, sse_free);
    if (!q->resp) {
        sse_free(s);
        api_error(q, 500, "internal", NULL, "out of memory");
        return;
    }
    q->status = 200;
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CONTENT_TYPE, "text/event-stream");
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-cache");
}

void api_sse_drain(srv_t *srv, int ms)
{
    struct timespec t = {0, 10 * 1000000L};
    for (int waited = 0; waited < ms && srv_events_readers(srv_events(srv)); waited += 10)
        nanosleep(&t, NULL);
}
