/* storage_job.c: the job queue in the jobs table: enqueue, atomic claim (BEGIN IMMEDIATE makes
 * the select-then-update one step across connections), heartbeat, finish, cancel, listing, and
 * the start-up requeue of jobs a crashed process left running. */
#include "storage_int.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *const kind_names[] = {"scan", "fit", "ptc"};
#define N_KINDS 3

const char *storage_job_kind_name(int kind)
{
    return kind >= 0 && kind < N_KINDS ? kind_names[kind] : NULL;
}

int storage_job_kind_parse(const char *name, storage_job_kind_t *out)
{
    for (int i = 0; name && i < N_KINDS; i++) {
        if (strcmp(name, kind_names[i]) == 0) {
            *out = (storage_job_kind_t)i;
            return 0;
        }
    }
    return -EINVAL;
}

void storage_job_free(storage_job_t *j)
{
    if (!j) return;
    free(j->params);
    free(j->error);
    free(j->fit_ids);
    free(j->bench);
    free(j->claimed_by);
    memset(j, 0, sizeof *j);
}

void storage_job_list_free(storage_job_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->n; i++) storage_job_free(&l->items[i]);
    free(l->items);
    memset(l, 0, sizeof *l);
}

/* Reads a STG_JOB_COLS row (item: a storage_job_t); 0 or -ENOMEM (freed on failure). */
static int read_job(sqldb_stmt_t *s, void *item)
{
    storage_job_t *o = item;
    int oom = 0;
    memset(o, 0, sizeof *o);
    o->id = sqldb_col_int64(s, 0);
    storage_job_kind_parse((const char *)sqldb_col_text(s, 1), &o->kind); /* CHECKed */
    o->params = stg_col_text(s, 2, &oom);
    storage_state_parse((const char *)sqldb_col_text(s, 3), &o->state);
    o->progress = stg_col_double(s, 4);
    o->points_done = sqldb_col_int(s, 5);
    o->error = stg_col_text(s, 6, &oom);
    o->attempts = sqldb_col_int(s, 7);
    o->heartbeat_ms = stg_col_id(s, 8);
    o->created_ms = stg_col_id(s, 9);
    o->started_ms = stg_col_id(s, 10);
    o->finished_ms = stg_col_id(s, 11);
    o->scan_id = stg_col_id(s, 12);
    o->fit_id = stg_col_id(s, 13);
    o->fit_ids = stg_col_text(s, 14, &oom);
    o->bench = stg_col_text(s, 15, &oom);
    o->claimed_by = stg_col_text(s, 16, &oom);
    if (oom) storage_job_free(o);
    return oom ? -ENOMEM : 0;
}

int stg_job_insert(storage_t *st, storage_job_kind_t kind, const char *params_json,
                   int64_t scan_id, int64_t *id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!storage_job_kind_name(kind))
        return err_set(err, -EINVAL, "job kind: %d is not a kind", (int)kind);
    if (!params_json) return err_set(err, -EINVAL, "job params: NULL");
    if (scan_id) {
        storage_scan_t sc;
        if ((ret = stg_scan_load(st, scan_id, &sc, err))) return ret;
        storage_scan_free(&sc);
    }
    if ((ret = stg_stmt(st, STG_JOB_INSERT, &q, err))) return ret;
    stg_bind_text(q, 1, storage_job_kind_name(kind), &rc);
    stg_bind_text(q, 2, params_json, &rc);
    stg_bind_int(q, 3, storage_now_ms(st), &rc);
    stg_bind_id(q, 4, scan_id, &rc);
    /* a job for the instrument belongs to this handle's bench; a fit to anyone */
    stg_bind_text(q, 5, kind == STORAGE_JOB_FIT ? NULL : st->claimant, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "enqueueing a job");
    }
    ret = stg_run(st, q, err, "enqueueing a job");
    if (ret == -EINVAL) return err_set(err, ret, "job params: not valid JSON text");
    if (ret == 0) *id = sqldb_last_insert_id(st->db);
    return ret;
}

int storage_job_enqueue(storage_t *st, storage_job_kind_t kind, const char *params_json,
                        int64_t scan_id, int64_t *id, err_t *err)
{
    if (!st || !id) return err_set(err, -EINVAL, "job enqueue: NULL argument");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_job_insert(st, kind, params_json, scan_id, id, err))) {
        stg_rollback(st);
        return ret;
    }
    return stg_commit(st, err);
}

/* Reads job id (bound as ?1 of STG_JOB_GET) into *out; -ENOENT naming it when unknown. */
static int job_load(storage_t *st, int64_t id, storage_job_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_JOB_GET, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a job")
                          : stg_error(st, rc, err, "reading a job");
    if (ret == 0 && read_job(q, out)) ret = err_set(err, -ENOMEM, "job: out of memory");
    stg_reset(q);
    return ret == -ENOENT ? err_set(err, ret, "job %lld does not exist", (long long)id) : ret;
}

int storage_job_get(storage_t *st, int64_t id, storage_job_t *out, err_t *err)
{
    if (!st || !out) return err_set(err, -EINVAL, "job get: NULL argument");
    return job_load(st, id, out, err);
}

/* Inside the claim transaction: the id of the oldest queued job of the kinds (a mask of
 * STORAGE_JOB_BIT), 0 if none. */
static int next_queued(storage_t *st, unsigned kinds, int64_t *id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_JOB_NEXT, &q, err))) return ret;
    for (int k = 0; k < N_KINDS; k++)
        stg_bind_text(q, k + 1, kinds & STORAGE_JOB_BIT(k) ? kind_names[k] : NULL, &rc);
    stg_bind_text(q, 4, st->claimant, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "finding a queued job")
                          : stg_error(st, rc, err, "finding a queued job");
    *id = ret == 0 ? sqldb_col_int64(q, 0) : 0;
    stg_reset(q);
    return ret == -ENOENT ? 0 : ret;
}

int storage_job_claim(storage_t *st, storage_job_kind_t kind, storage_job_t *out, err_t *err)
{
    if (!storage_job_kind_name(kind)) {
        if (out) memset(out, 0, sizeof *out);
        return err_set(err, -EINVAL, "job kind: %d is not a kind", (int)kind);
    }
    return storage_job_claim_kinds(st, STORAGE_JOB_BIT(kind), out, err);
}

int storage_job_claim_kinds(storage_t *st, unsigned kinds, storage_job_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int64_t id = 0;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "job claim: NULL argument");
    memset(out, 0, sizeof *out);
    if (kinds == 0 || kinds >= STORAGE_JOB_BIT(N_KINDS))
        return err_set(err, -EINVAL, "job kinds: %#x names no kind or an unknown one", kinds);
    /* BEGIN IMMEDIATE: no other connection can claim between our SELECT and our UPDATE */
    if ((ret = stg_begin_write(st, err))) return ret;
    if ((ret = next_queued(st, kinds, &id, err)) || id == 0) goto out;
    if ((ret = stg_stmt(st, STG_JOB_START, &q, err))) goto out;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_int(q, 2, storage_now_ms(st), &rc);
    stg_bind_text(q, 3, st->claimant, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "claiming a job");
        goto out;
    }
    if ((ret = stg_run(st, q, err, "claiming a job"))) goto out;
    ret = job_load(st, id, out, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_job_free(out);
    }
    return ret;
}

/* Why an update of a running job changed nothing: -ENOENT, -ECANCELED or -ESTALE. */
static int not_running(storage_t *st, int64_t id, const char *what, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_JOB_STATE, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, what) : stg_error(st, rc, err, what);
    if (ret == -ENOENT) {
        err_set(err, ret, "%s: job %lld does not exist", what, (long long)id);
    } else if (ret == 0) {
        const char *state = sqldb_col_text(q, 0), *by = sqldb_col_text(q, 3);
        int cancelled = state && strcmp(state, "cancelled") == 0;
        int running = state && strcmp(state, "running") == 0;
        if (running && (by ? !st->claimant || strcmp(by, st->claimant) : st->claimant != NULL))
            ret = err_set(err, -ESTALE, "%s: job %lld was taken over by %s (its lease ran out)",
                          what, (long long)id, by ? by : "an unnamed ipsd");
        else
            ret = err_set(err, cancelled ? -ECANCELED : -ESTALE,
                          "%s: job %lld is %s, not running", what, (long long)id,
                          state ? state : "?");
    }
    stg_reset(q);
    return ret;
}

int storage_job_heartbeat(storage_t *st, int64_t id, double progress, int points_done,
                          err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st) return err_set(err, -EINVAL, "job heartbeat: NULL handle");
    if (!(progress >= 0 && progress <= 1))
        return err_set(err, -EINVAL, "job progress: %g, need 0..1", progress);
    if (points_done < 0)
        return err_set(err, -EINVAL, "job points_done: %d, need >= 0", points_done);
    if ((ret = stg_stmt(st, STG_JOB_HEARTBEAT, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_int(q, 2, storage_now_ms(st), &rc);
    stg_bind_double(q, 3, progress, &rc);
    stg_bind_int(q, 4, points_done, &rc);
    stg_bind_text(q, 5, st->claimant, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "job heartbeat");
    }
    if ((ret = stg_run(st, q, err, "job heartbeat"))) return ret;
    return sqldb_changes(st->db) ? 0 : not_running(st, id, "job heartbeat", err);
}

int storage_job_finish(storage_t *st, int64_t id, storage_state_t state, const char *error,
                       err_t *err)
{
    if (!st) return err_set(err, -EINVAL, "job finish: NULL handle");
    return stg_job_finish(st, id, state, error, err);
}

int stg_job_finish(storage_t *st, int64_t id, storage_state_t state, const char *error,
                   err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (state != STORAGE_DONE && state != STORAGE_FAILED)
        return err_set(err, -EINVAL, "job finish state: need done or failed");
    if ((ret = stg_stmt(st, STG_JOB_FINISH, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_text(q, 2, storage_state_name(state), &rc);
    stg_bind_text(q, 3, error, &rc);
    stg_bind_int(q, 4, storage_now_ms(st), &rc);
    stg_bind_text(q, 5, st->claimant, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "job finish");
    }
    if ((ret = stg_run(st, q, err, "job finish"))) return ret;
    return sqldb_changes(st->db) ? 0 : not_running(st, id, "job finish", err);
}

int storage_job_release(storage_t *st, int64_t id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st) return err_set(err, -EINVAL, "job release: NULL handle");
    if ((ret = stg_stmt(st, STG_JOB_RELEASE, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_text(q, 2, st->claimant, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "job release");
    }
    if ((ret = stg_run(st, q, err, "job release"))) return ret;
    return sqldb_changes(st->db) ? 0 : not_running(st, id, "job release", err);
}

int stg_job_step(storage_t *st, int64_t id, int from, double progress, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_JOB_STEP, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_int(q, 2, from, &rc);
    stg_bind_int(q, 3, from + 1, &rc);
    stg_bind_double(q, 4, progress, &rc);
    stg_bind_int(q, 5, storage_now_ms(st), &rc);
    stg_bind_text(q, 6, st->claimant, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "job step");
    }
    if ((ret = stg_run(st, q, err, "job step"))) return ret;
    if (sqldb_changes(st->db)) return 0;
    ret = not_running(st, id, "job step", err);
    /* running, but at another count: this unit was stored by an earlier run */
    if (ret == -ESTALE && strstr(err ? err->msg : "", "is running"))
        return err_set(err, -ESTALE, "job step: job %lld has not done exactly %d units",
                       (long long)id, from);
    return ret;
}

int stg_job_set_fit(storage_t *st, int64_t job_id, int64_t fit_id, err_t *err)
{
    int ret = stg_run_ids(st, STG_JOB_SET_FIT, job_id, fit_id, err, "linking the job to its fit");
    if (ret == 0 && sqldb_changes(st->db) == 0)
        return err_set(err, -ENOENT, "job %lld does not exist", (long long)job_id);
    return ret;
}

/* Inside the cancel transaction, after the job changed: cancels its scan if it has one. */
static int cancel_scan_of(storage_t *st, int64_t id, err_t *err)
{
    storage_job_t job;
    int ret = job_load(st, id, &job, err);
    if (ret) return ret;
    int64_t scan_id = job.kind == STORAGE_JOB_SCAN ? job.scan_id : 0;
    storage_job_free(&job);
    return scan_id ? stg_scan_cancel(st, scan_id, err) : 0;
}

int storage_job_cancel(storage_t *st, int64_t id, int *changed, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !changed) return err_set(err, -EINVAL, "job cancel: NULL argument");
    *changed = 0;
    if ((ret = stg_begin_write(st, err))) return ret;
    if ((ret = stg_stmt(st, STG_JOB_CANCEL, &q, err))) goto out;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_int(q, 2, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "job cancel");
        goto out;
    }
    if ((ret = stg_run(st, q, err, "job cancel"))) goto out;
    if (sqldb_changes(st->db)) {
        *changed = 1;
        ret = cancel_scan_of(st, id, err);
    } else {
        ret = not_running(st, id, "job cancel", err);
        if (ret == -ECANCELED || ret == -ESTALE) ret = 0; /* ended already: nothing to do */
    }
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        *changed = 0;
    }
    return ret;
}

static void bind_job_filter(sqldb_stmt_t *q, int kind, int state, int64_t scan_id, int *rc)
{
    stg_bind_text(q, 1, kind == STORAGE_ANY ? NULL : storage_job_kind_name(kind), rc);
    stg_bind_text(q, 2, state == STORAGE_ANY ? NULL : storage_state_name(state), rc);
    stg_bind_id(q, 3, scan_id, rc);
}

int stg_job_count(storage_t *st, storage_job_kind_t kind, int64_t scan_id, int64_t *n, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_JOB_COUNT, &q, err))) return ret;
    bind_job_filter(q, kind, STORAGE_ANY, scan_id, &rc);
    return stg_count(st, q, rc, n, err, "counting jobs");
}

int storage_job_list(storage_t *st, int kind, int state, int64_t scan_id, int limit, int offset,
                     storage_job_list_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "job list: NULL argument");
    memset(out, 0, sizeof *out);
    if (kind != STORAGE_ANY && !storage_job_kind_name(kind))
        return err_set(err, -EINVAL, "job list kind: %d is not a kind", kind);
    if (state != STORAGE_ANY && !storage_state_name(state))
        return err_set(err, -EINVAL, "job list state: %d is not a state", state);
    if (offset < 0) return err_set(err, -EINVAL, "job list offset: %d, need >= 0", offset);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_stmt(st, STG_JOB_COUNT, &q, err))) goto out;
    bind_job_filter(q, kind, state, scan_id, &rc);
    if ((ret = stg_count(st, q, rc, &out->total, err, "counting jobs"))) goto out;
    if ((ret = stg_stmt(st, STG_JOB_LIST, &q, err))) goto out;
    bind_job_filter(q, kind, state, scan_id, &rc);
    stg_bind_int(q, 4, limit > 0 ? limit : -1, &rc);
    stg_bind_int(q, 5, offset, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "listing jobs");
        goto out;
    }
    ret = stg_collect(st, q, sizeof *out->items, read_job, (void **)&out->items, &out->n, err,
                      "listing jobs");
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_job_list_free(out);
    }
    return ret;
}

/* Runs one of the two requeue statements (bound: stale-before time, max attempts, now, the
 * claimant whose jobs they are or NULL). */
static int requeue_step(storage_t *st, enum stg_id id, int64_t before, int max_attempts,
                        const char *claimant, int *count, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, id, &q, err))) return ret;
    stg_bind_int(q, 1, before, &rc);
    if (id == STG_JOB_ABANDON) {
        stg_bind_int(q, 2, max_attempts, &rc);
        stg_bind_int(q, 3, storage_now_ms(st), &rc);
        stg_bind_text(q, 4, claimant, &rc);
    } else {
        stg_bind_text(q, 2, claimant, &rc);
    }
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "requeueing stale jobs");
    }
    if ((ret = stg_run(st, q, err, "requeueing stale jobs"))) return ret;
    *count = sqldb_changes(st->db);
    return 0;
}

int storage_job_requeue_stale(storage_t *st, int64_t stale_ms, int max_attempts, int *requeued,
                              int *failed, err_t *err)
{
    return storage_job_requeue_claimed(st, NULL, stale_ms, max_attempts, requeued, failed, err);
}

int storage_job_requeue_claimed(storage_t *st, const char *claimant, int64_t stale_ms,
                                int max_attempts, int *requeued, int *failed, err_t *err)
{
    int n_requeued = 0, n_failed = 0;
    if (!st || stale_ms < 0)
        return err_set(err, -EINVAL, "job requeue: need a handle and stale_ms >= 0");
    int64_t before = storage_now_ms(st) - stale_ms;
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    /* first fail those out of attempts, then requeue the rest */
    if ((ret = requeue_step(st, STG_JOB_ABANDON, before, max_attempts, claimant, &n_failed,
                            err)) ||
        (ret = requeue_step(st, STG_JOB_REQUEUE, before, max_attempts, claimant, &n_requeued,
                            err))) {
        stg_rollback(st);
        return ret;
    }
    if ((ret = stg_commit(st, err))) return ret;
    if (requeued) *requeued = n_requeued;
    if (failed) *failed = n_failed;
    return 0;
}

int stg_job_resume(storage_t *st, int64_t scan_id, int64_t *job_id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_JOB_RESUME, &q, err))) return ret;
    stg_bind_int(q, 1, scan_id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "resuming a scan job")
                          : stg_error(st, rc, err, "resuming a scan job");
    if (ret == 0) {
        *job_id = sqldb_col_int64(q, 0);
        rc = sqldb_step(q); /* RETURNING: the update is complete when the step says done */
        if (rc != SQLDB_DONE) ret = stg_error(st, rc, err, "resuming a scan job");
    }
    stg_reset(q);
    return ret == -ENOENT ? err_set(err, -ESTALE, "scan %lld: its scan job is not failed",
                                    (long long)scan_id)
                          : ret;
}
