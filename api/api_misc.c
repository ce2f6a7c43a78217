/* api_misc.c: GET /api/health (cheap: no database access). GET /api/openapi.json is in
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

void api_h_health(api_req_t *q)
{
    const srv_config_t *cfg = srv_config(q->srv);
    size_t open = 0;
    uint64_t reaped = 0;
    if (q->conns) api_conns_counts(q->conns, &open, &reaped);
    /* the storage's health from memory (issue 10): answers while the disk is full */
    storage_health_t h;
    srv_storage_health(q->srv, &h);
    char unrec_msg[256];
    int64_t unrec = srv_scan_unrecorded(q->srv, unrec_msg, sizeof unrec_msg);
    json_t *body =
        json_pack("{s:s, s:s, s:s, s:I, s:I, s:I, s:s, s:I}", "status",
                  srv_stopping(q->srv) ? "stopping" : "ok", "version", IPSD_VERSION, "bench",
                  cfg->bench, "connections", (json_int_t)open, "connections_timed_out",
                  (json_int_t)reaped, "event_subscribers",
                  (json_int_t)srv_events_readers(srv_events(q->srv)), "storage",
                  storage_fault_name(h.fault), "storage_faults", (json_int_t)h.faults);
    if (body) {
        json_object_set_new(body, "storage_error", h.msg[0] ? json_string(h.msg) : json_null());
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
    api_reply_json(q, 200, body);
}
