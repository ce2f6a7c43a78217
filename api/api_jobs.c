/* api_jobs.c: the job queue: list (filter by kind, state and scan, paginated), get, cancel
 * (queued or running; 409 when the job has ended). A job of every pixel ("pixels": "all") also
 * answers, when got alone, each pixel of its scan's sub-frame with what the job did of it. */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"
#include "server/srv_cover.h"

/* "pixels" of a job of every pixel: each pixel of the scan's sub-frame in row-major order,
 * "fitted" with its fit_id (the k-th covered pixel's fit is the job's k-th: srv_fitall.c fits
 * the covered pixels in this order), "pending" (the job has not got there yet), "not_fitted"
 * (the job ended before it), or "not_covered" with the reason (GET /api/scans/{id}/coverage). */
static int add_pixels(storage_t *st, const storage_job_t *j, json_t *o, err_t *err)
{
    json_t *ids = json_object_get(o, "fit_ids");
    json_t *params = json_object_get(o, "params");
    json_t *scan_id = json_is_object(params) ? json_object_get(params, "scan_id") : NULL;
    if (!json_is_array(ids) || !json_is_integer(scan_id)) return 0; /* not a job of every pixel */
    storage_scan_t sc;
    scan_cover_t *cover = NULL;
    int ret = storage_scan_get(st, json_integer_value(scan_id), &sc, err);
    if (ret) return ret;
    if ((ret = srv_scan_cover(st, &sc, &cover, err))) {
        storage_scan_free(&sc);
        return ret;
    }
    int m = sc.sub_px, h = m / 2,
        ongoing = j->state == STORAGE_QUEUED || j->state == STORAGE_RUNNING;
    size_t k = 0;
    json_t *pixels = json_array();
    for (int i = 0; pixels && i < m * m; i++) {
        json_t *fit = json_null(), *reason = json_null();
        const char *status;
        if (!cover[i].covered) {
            status = SRV_NOT_COVERED;
            reason = json_string(cover[i].reason);
        } else if (k < json_array_size(ids)) {
            status = "fitted";
            fit = json_incref(json_array_get(ids, k++));
        } else {
            status = ongoing ? "pending" : "not_fitted";
        }
        int dcol = i % m - h, drow = i / m - h;
        json_array_append_new(pixels,
                              json_pack("{s:i, s:i, s:i, s:i, s:s, s:o, s:o}", "dcol", dcol, "drow",
                                        drow, "col", sc.poi_col + dcol, "row", sc.poi_row + drow,
                                        "status", status, "fit_id", fit, "reason", reason));
    }
    json_object_set_new(o, "pixels", pixels);
    free(cover);
    storage_scan_free(&sc);
    return 0;
}

void api_h_jobs_list(api_req_t *q)
{
    storage_t *st;
    storage_job_list_t l;
    long long scan, limit, offset;
    int state, kind = STORAGE_ANY;
    err_t err = {{0}};
    const char *k = api_query(q, "kind");
    storage_job_kind_t kv;
    if (k && storage_job_kind_parse(k, &kv)) {
        api_error(q, 422, "out_of_range", "kind", "kind must be scan, fit or ptc (got '%s')", k);
        return;
    }
    if (k) kind = (int)kv;
    if (api_query_int(q, "scan", 0, 0, INT64_MAX, &scan) || api_query_page(q, &limit, &offset) ||
        api_query_state(q, &state) || !(st = api_db(q)))
        return;
    int ret = storage_job_list(st, kind, state, scan, (int)limit, (int)offset, &l, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *items = json_array();
    for (size_t i = 0; items && i < l.n; i++)
        json_array_append_new(items, api_enc_job(&l.items[i]));
    api_reply_json(q, 200, api_enc_page(items, l.total, limit, offset));
    storage_job_list_free(&l);
}

void api_h_job_get(api_req_t *q)
{
    storage_t *st;
    storage_job_t j;
    int64_t id;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "job", &id) || !(st = api_db(q))) return;
    int ret = storage_job_get(st, id, &j, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    /* a scan job that failed while the storage refuses to record it (docs/server.md, "Storage
     * faults") reads as failed, with its error, though its row still says running */
    char unrecorded[256];
    char *copy;
    if (j.state == STORAGE_RUNNING &&
        srv_scan_unrecorded(q->srv, unrecorded, sizeof unrecorded) == id &&
        (copy = strdup(unrecorded))) {
        j.state = STORAGE_FAILED;
        free(j.error);
        j.error = copy;
    }
    json_t *o = api_enc_job(&j);
    if (o && (ret = add_pixels(st, &j, o, &err))) {
        json_decref(o);
        api_error_rc(q, ret, NULL, err.msg);
    } else {
        api_reply_json(q, 200, o);
    }
    storage_job_free(&j);
}

void api_h_job_cancel(api_req_t *q)
{
    storage_t *st;
    storage_job_t j;
    int64_t id;
    int changed = 0;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "job", &id) || !(st = api_db(q))) return;
    int ret = srv_job_cancel(q->srv, st, id, &changed, &err);
    if (ret == 0) ret = storage_job_get(st, id, &j, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    if (!changed)
        api_error(q, 409, "conflict", NULL, "job %lld is %s: nothing to cancel", (long long)id,
                  storage_state_name(j.state));
    else
        api_reply_json(q, 200, api_enc_job(&j));
    storage_job_free(&j);
}
