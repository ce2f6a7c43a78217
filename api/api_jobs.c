/* api_jobs.c: the job queue: list (filter by kind, state and scan, paginated), get, cancel
 * (queued or running; 409 when the job has ended). */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"

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
    api_reply_json(q, 200, api_enc_job(&j));
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
