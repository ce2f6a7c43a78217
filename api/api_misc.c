/* api_misc.c: GET /api/health (cheap: no database access; "degraded" during a storage fault). GET /api/openapi.json is in
 * api_openapi.c. */
#include <stdlib.h>
#include <string.h>

#include "api_calib_cache.h"
#include "api_conn.h"
#include "api_int.h"
#include "server/srv_events.h"

#ifndef IPSD_VERSION
#define IPSD_VERSION "unknown"
#endif

/* Appends text to a, or plain when text is NULL (json_sprintf refuses what is not UTF-8). */
static void add_reason(json_t *a, json_t *text, const char *plain)
{
    json_array_append_new(a, text ? text : json_string(plain));
}

/* Why the server is degraded (serving reads, but some writes fail or a failure is not recorded
 * yet): one sentence per cause, an empty array when it is not. NULL when out of memory. */
static json_t *degraded_reasons(const storage_health_t *h, int64_t unrec, const char *unrec_msg)
{
    json_t *a = json_array();
    if (a && h->fault)
        add_reason(a,
                   json_sprintf("storage %s: writes fail (%s)", storage_fault_name(h->fault),
                                h->msg),
                   "storage fault: writes fail");
    if (a && unrec)
        add_reason(a,
                   json_sprintf("job %lld failed and its failure is not recorded yet (%s)",
                                (long long)unrec, unrec_msg),
                   "a job's failure is not recorded yet");
    return a;
}

static json_t *str_or_null(const char *s)
{
    return s && *s ? json_string(s) : json_null();
}

void api_h_health(api_req_t *q)
{
    const srv_config_t *cfg = srv_config(q->srv);
    size_t open = 0;
    uint64_t reaped = 0;
    if (q->conns) api_conns_counts(q->conns, &open, &reaped);
    /* the storage's health from memory: answers while the disk is full */
    storage_health_t h;
    srv_storage_health(q->srv, &h);
    char unrec_msg[256];
    int64_t unrec = srv_scan_unrecorded(q->srv, unrec_msg, sizeof unrec_msg);
    /* "degraded": reads answer, but the storage refuses writes or a job's failure is
     * waiting to be written; "stopping" wins over it */
    json_t *reasons = degraded_reasons(&h, unrec, unrec_msg);
    const char *status = srv_stopping(q->srv) ? "stopping" : h.fault || unrec ? "degraded" : "ok";
    json_t *body =
        json_pack("{s:s, s:s, s:s, s:I, s:I, s:I, s:s, s:I}", "status", status, "version", IPSD_VERSION, "bench",
                  cfg->bench, "connections", (json_int_t)open, "connections_timed_out",
                  (json_int_t)reaped, "event_subscribers",
                  (json_int_t)srv_events_readers(srv_events(q->srv)), "storage",
                  storage_fault_name(h.fault), "storage_faults", (json_int_t)h.faults);
    if (body) {
        json_object_set_new(body, "storage_error", h.msg[0] ? json_string(h.msg) : json_null());
        json_object_set_new(body, "degraded_reasons", reasons ? json_incref(reasons) : json_array());
        json_object_set_new(body, "storage_fault_since_ms",
                            h.since_ms ? json_integer(h.since_ms) : json_null());
        json_object_set_new(body, "unrecorded_job",
                            unrec ? json_pack("{s:I, s:s}", "id", (json_int_t)unrec, "error",
                                              unrec_msg)
                                  : json_null());
    }
    uint64_t hits, misses;
    size_t entries, bytes;
    api_calib_cache_stats(q->calib_cache, &hits, &misses, &entries, &bytes);
    if (body)
        json_object_set_new(body, "calibration_cache",
                            json_pack("{s:I, s:I, s:I, s:I}", "hits", (json_int_t)hits, "misses",
                                      (json_int_t)misses, "entries", (json_int_t)entries, "bytes",
                                      (json_int_t)bytes));
    /* the instrument ipsd holds: its camera as found at start, and the stage string */
    const cam_info_t *cam = srv_camera(q->srv);
    json_t *c = json_object();
    if (c) {
        json_object_set_new(c, "backend", str_or_null(cam->backend));
        json_object_set_new(c, "id", str_or_null(cam->id));
        json_object_set_new(c, "vendor", str_or_null(cam->vendor));
        json_object_set_new(c, "model", str_or_null(cam->model));
        json_object_set_new(c, "serial", str_or_null(cam->serial));
    }
    if (body) {
        json_object_set_new(body, "camera", c ? c : json_null());
        json_object_set_new(body, "stage", json_string(cfg->stage));
        json_object_set_new(body, "bench_name", json_string(cfg->bench_name));
        json_object_set_new(body, "bench_lock", str_or_null(srv_bench_lock(q->srv)));
        json_object_set_new(body, "database",
                            json_string(storage_is_postgres(cfg->db_path) ? "postgresql" : "sqlite"));
    } else {
        json_decref(c);
    }
    json_decref(reasons);
    api_reply_json(q, 200, body);
}
