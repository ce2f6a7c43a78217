/* api_int.h: what the files of api/ share: the request being served, the reply functions, the
 * input functions that name the offending field, and the handlers the router calls. */
#ifndef IPSD_API_API_INT_H
#define IPSD_API_API_INT_H

#include <jansson.h>
#include <microhttpd.h>
#include <stddef.h>
#include <stdint.h>
#include <time.h>

#include "api/api.h"
#include "server/srv.h"
#include "storage/storage.h"

#define API_MAX_ARGS 4

typedef struct api_req api_req_t;
typedef void (*api_handler_fn)(api_req_t *q);

/* A route: method, pattern, handler, and whether it takes a JSON body (API_BODY_OPTIONAL: a
 * body is read when one comes, and must then be a JSON object; the handler checks it). */
#define API_BODY_OPTIONAL 2
typedef struct api_route {
    const char *method;
    const char *pattern;
    api_handler_fn fn;
    int json_body;
} api_route_t;

/* 1 when the route is a POST that only computes (a read's access: api_router.c). */
int api_route_computes_only(const api_route_t *r);

/* One request, from its first callback to its completion. */
typedef struct api_conns api_conns_t;

struct api_req {
    srv_t *srv;
    api_conns_t *conns; /* the HTTP server's connection tracker (api_conn.h) */
    struct api_calib_cache *calib_cache; /* current calibrations' replies (api_calib_cache.h) */
    struct MHD_Connection *conn;
    const api_route_t *route;
    int64_t arg[API_MAX_ARGS]; /* the route's {name} segments, in order */
    char *body;                /* the request body (NUL-terminated), NULL when none */
    size_t body_len, body_cap;
    int too_big;     /* the body exceeded --max-body: it is read and dropped */
    int started;     /* the first callback (headers) has been handled */
    storage_t *st;   /* borrowed by api_db, given back when the reply is queued */
    unsigned status; /* the reply */
    struct MHD_Response *resp;
    long long resp_bytes;  /* the reply body's size for the request log, -1 unknown (a stream) */
    struct timespec t0;    /* CLOCK_MONOTONIC at the first callback (request log) */
    char *log_method;      /* method and path as the request log writes them (api_log.h) */
    char *log_path;
};

/* ---- routing (api_router.c) ---- */

/* Matches method and path. Returns the route with its arguments in arg, or NULL with
 * *path_known = 1 when the path exists for another method (405), 0 when it does not (404). */
const api_route_t *api_route_find(const char *method, const char *path, int64_t *arg,
                                  int *path_known);
/* The methods a known path allows ("GET, POST"), into buf. */
const char *api_route_allow(const char *path, char *buf, size_t n);

/* The unescape of the URL path and of query keys and values (api_http.c; libmicrohttpd's
 * MHD_OPTION_UNESCAPE_CALLBACK): %XX decoded in place, except %00, which stays literal. Returns
 * the new length. */
size_t api_unescape_keep_nul(void *cls, struct MHD_Connection *c, char *s);

/* ---- replies (api_reply.c) ---- */

/* The text api_reply_json sends for body (takes its reference): malloc'ed, *len bytes; NULL on
 * out of memory. */
char *api_json_text(json_t *body, size_t *len);
/* Replies with JSON (takes the reference of body; NULL body: 500 out of memory). */
void api_reply_json(api_req_t *q, unsigned status, json_t *body);
/* Replies with text of a content type (takes buf, malloc'ed, len bytes). */
void api_reply_text(api_req_t *q, unsigned status, const char *ctype, char *buf, size_t len);
/* The same with a buffer the reply borrows: release(buf) when it has been sent (or at once when
 * the request has a reply already). */
void api_reply_shared(api_req_t *q, unsigned status, const char *ctype, char *buf, size_t len,
                      void (*release)(void *));
/* Replies with the error body {"error": {"code", "message", "field"}} (field may be NULL). */
void api_error(api_req_t *q, unsigned status, const char *code, const char *field, const char *fmt,
               ...) __attribute__((format(printf, 5, 6)));
/* Replies with the error of a storage or server call: -ENOENT 404, -EINVAL 422, -EEXIST and
 * -ESTALE 409, -EBUSY and -ESHUTDOWN 503, -ENOMEM and others 500. */
void api_error_rc(api_req_t *q, int rc, const char *field, const char *msg);
/* The request's database handle (borrowed once per request); NULL after replying 503. */
storage_t *api_db(api_req_t *q);

/* ---- input (api_input.c) ---- */

/* A query-string value, NULL when absent. */
const char *api_query(api_req_t *q, const char *key);
/* Query integer in lo..hi (def when absent); replies 400/422 and returns -1 when bad. */
int api_query_int(api_req_t *q, const char *key, long long def, long long lo, long long hi,
                  long long *v);
/* The parsed JSON object body; replies 400 and returns NULL when it is not one. */
json_t *api_body_object(api_req_t *q);
/* Reads member key of o (named path for errors, e.g. "raster.step_um"):
 *   present = 0 when absent (then *v keeps its default, unless required: 422);
 *   wrong type: 400; out of range: 422. Returns 0, or -1 after replying. */
int api_get_int(api_req_t *q, json_t *o, const char *key, const char *path, int required,
                long long lo, long long hi, long long *v);
int api_get_num(api_req_t *q, json_t *o, const char *key, const char *path, int required, double lo,
                double hi, int open_lo, double *v);
int api_get_str(api_req_t *q, json_t *o, const char *key, const char *path, int required,
                size_t max_len, const char **v);
int api_get_bool(api_req_t *q, json_t *o, const char *key, const char *path, int *v);
/* An object member (absent: NULL and 0; another type: 400 and -1). */
int api_get_obj(api_req_t *q, json_t *o, const char *key, const char *path, json_t **v);
/* Replies 422 when o has a member not in the NULL-terminated list keys. */
int api_no_unknown(api_req_t *q, json_t *o, const char *prefix, const char *const *keys);
/* POST /api/fits's "scan_fits" (a FITS scan cube, base64, and the pixel to cut) replaced by the
 * "scan" file of that pixel (api_fitscube.c). 0 when done or absent; -1 after replying. */
int api_fits_cube_scan(api_req_t *q, json_t *o);
/* The client asked for CSV (?format=csv or Accept: text/csv); -1 after replying 400 to a bad
 * format value. */
int api_wants_csv(api_req_t *q);
/* ?state=NAME into *state (STORAGE_ANY when absent); -1 after replying 422. */
int api_query_state(api_req_t *q, int *state);
/* ?limit= (1..1000, default 50) and ?offset= (>= 0); -1 after replying. */
int api_query_page(api_req_t *q, long long *limit, long long *offset);
/* Path argument i as an id (>= 1); replies 404 naming what and returns -1 when it is not. */
int api_arg_id(api_req_t *q, int i, const char *what, int64_t *id);

/* ---- JSON / CSV encodings (api_enc.c) ---- */

json_t *api_enc_sensor(const storage_sensor_t *s);
json_t *api_enc_scan(const storage_scan_t *sc);
json_t *api_enc_job(const storage_job_t *j);
/* with_result: include the whole fit document (result), else leave it out (lists) */
json_t *api_enc_fit(const storage_fit_t *f, int with_result);
json_t *api_enc_calib(const storage_calib_t *c);
/* {"items": [...], "total", "limit", "offset"} (takes items). */
json_t *api_enc_page(json_t *items, int64_t total, long long limit, long long offset);
/* Calibrations as CSV, one line per sub-pixel (docs/api.md); malloc'ed text, *len bytes. */
char *api_csv_calibs(const storage_calib_t *c, size_t n, size_t *len);
/* A number or null (NaN), a time or null (0). */
json_t *api_num(double v);
json_t *api_time(int64_t ms);

/* ---- handlers ---- */

void api_h_health(api_req_t *q);
void api_h_events_ticket(api_req_t *q);
void api_h_openapi(api_req_t *q);
void api_h_sensors_list(api_req_t *q);
void api_h_sensors_create(api_req_t *q);
void api_h_sensor_get(api_req_t *q);
void api_h_pixel_calib(api_req_t *q);
void api_h_pixel_history(api_req_t *q);
void api_h_scans_list(api_req_t *q);
void api_h_scans_create(api_req_t *q);
void api_h_scan_get(api_req_t *q);
void api_h_scan_cancel(api_req_t *q);
void api_h_scan_resume(api_req_t *q);
void api_h_scan_pixel(api_req_t *q);
void api_h_scan_scanfile(api_req_t *q);
void api_h_scan_point(api_req_t *q);
void api_h_scan_fits_list(api_req_t *q);
void api_h_scan_fit_create(api_req_t *q);
void api_h_scan_coverage(api_req_t *q);
void api_h_fit_upload(api_req_t *q);
void api_h_fit_get(api_req_t *q);
void api_h_fit_interp(api_req_t *q);
void api_h_fit_promote(api_req_t *q);
void api_h_calibs_search(api_req_t *q);
void api_h_calib_get(api_req_t *q);
void api_h_calib_interp(api_req_t *q);
void api_h_jobs_list(api_req_t *q);
void api_h_job_get(api_req_t *q);
void api_h_job_cancel(api_req_t *q);
void api_h_events(api_req_t *q);
void api_h_backup(api_req_t *q);
/* calibrations as FITS files (api_export.c) and jitter photometry (api_jitter.c) */
void api_h_calib_fits(api_req_t *q);
void api_h_pixel_calib_fits(api_req_t *q);
void api_h_sensor_calibs_fits(api_req_t *q);
void api_h_jitter(api_req_t *q);
void api_h_sensor_ptc_create(api_req_t *q); /* api_ptc.c */
void api_h_sensor_ptc(api_req_t *q);
void api_h_ptc_get(api_req_t *q);
/* GET / and static files of the web directory (not under /api/). */
void api_h_static(api_req_t *q, const char *path);

/* The event streams must end before the daemon stops (api_sse.c): waits up to ms for them. */
void api_sse_drain(srv_t *srv, int ms);

#endif
