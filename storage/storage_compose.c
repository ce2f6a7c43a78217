/* storage_compose.c: the writes that span tables, each one transaction composed of the per-table
 * steps of the other files (stg_*_insert, stg_job_set_fit, ...): a scan with the job that runs it,
 * a fit with its job link (and the job's end), the map it offers and (when asked) its
 * calibration, the promotion of a stored fit's map to its pixel's calibration, the resume of
 * a failed scan with its job, and a photon-transfer measurement with its job's end. Nothing
 * calls into this file from storage/, so the table files never call each other both ways
 * (docs/schema.md, "The code"). */
#include "storage_int.h"

#include <errno.h>

int storage_scan_submit(storage_t *st, const storage_scan_t *sc, const char *params_json,
                        int64_t *scan_id, int64_t *job_id, err_t *err)
{
    if (!st || !sc || !params_json || !scan_id || !job_id)
        return err_set(err, -EINVAL, "scan submit: NULL argument");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_scan_insert(st, sc, scan_id, err)) ||
        (ret = stg_job_insert(st, STORAGE_JOB_SCAN, params_json, *scan_id, job_id, err))) {
        stg_rollback(st);
        return ret;
    }
    return stg_commit(st, err);
}

int storage_scan_finish(storage_t *st, int64_t scan_id, int64_t job_id, const char *fit_params_json,
                        int64_t *fit_job_id, err_t *err)
{
    if (!st || !fit_params_json || !fit_job_id)
        return err_set(err, -EINVAL, "scan finish: NULL argument");
    *fit_job_id = 0;
    storage_scan_t sc;
    int64_t fits = 0, fid = 0;
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_scan_load(st, scan_id, &sc, err))) goto out;
    int was_done = sc.state == STORAGE_DONE;
    storage_scan_free(&sc);
    if (!was_done)
        ret = storage_scan_set_state(st, scan_id, STORAGE_DONE, NULL, err);
    else
        ret = stg_job_count(st, STORAGE_JOB_FIT, scan_id, &fits, err);
    if (ret == 0 && fits == 0)
        ret = stg_job_insert(st, STORAGE_JOB_FIT, fit_params_json, scan_id, &fid, err);
    if (ret == 0) ret = stg_job_finish(st, job_id, STORAGE_DONE, NULL, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        return ret;
    }
    *fit_job_id = fid;
    return 0;
}

/* The rows of one stored fit, inside the caller's transaction: the fit, the map it offers and
 * (promote) its calibration. */
static int fit_rows(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                    int promote, int64_t *fid, int64_t *cid, err_t *err)
{
    int ret = stg_fit_insert(st, fit, fid, err);
    if (ret || !calib) return ret;
    storage_calib_t c = *calib; /* shallow: only the two ids change */
    c.fit_id = *fid;
    if (!c.scan_id) c.scan_id = fit->scan_id;
    if ((ret = stg_calib_check(st, &c, err)) || (ret = stg_fit_map_insert(st, *fid, &c, err)))
        return ret;
    return promote ? stg_calib_insert(st, &c, cid, err) : 0;
}

/* Links a job and the fit it stored, both ways, inside the caller's transaction: the job's
 * fit_id (-ENOENT: no such job) and the fit's job_id (how a job of every pixel lists its fits). */
static int link_job(storage_t *st, int64_t job_id, int64_t fid, err_t *err)
{
    int ret = stg_job_set_fit(st, job_id, fid, err);
    return ret ? ret : stg_fit_set_job(st, fid, job_id, err);
}

/* Ends the transaction of a fit store: commit when ret is 0, else roll back; the ids out on
 * success. */
static int fit_rows_end(storage_t *st, int ret, int64_t fid, int64_t cid, int64_t *fit_id,
                        int64_t *calib_id, err_t *err)
{
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        return ret;
    }
    if (fit_id) *fit_id = fid;
    if (calib_id) *calib_id = cid;
    return 0;
}

/* storage_fit_store, and with done the job's end too (storage_fit_store_done). */
static int fit_store(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                     int promote, int64_t job_id, int done, int64_t *fit_id, int64_t *calib_id,
                     err_t *err)
{
    int64_t fid = 0, cid = 0;
    if (!st || !fit) return err_set(err, -EINVAL, "fit put: NULL argument");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    /* first the job's end: a job no longer running (cancelled meanwhile) stores nothing */
    if (done) ret = stg_job_finish(st, job_id, STORAGE_DONE, NULL, err);
    if (!ret) ret = fit_rows(st, fit, calib, promote, &fid, &cid, err);
    if (!ret && job_id > 0) ret = link_job(st, job_id, fid, err);
    return fit_rows_end(st, ret, fid, cid, fit_id, calib_id, err);
}

int storage_fit_store(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                      int promote, int64_t job_id, int64_t *fit_id, int64_t *calib_id, err_t *err)
{
    return fit_store(st, fit, calib, promote, job_id, 0, fit_id, calib_id, err);
}

int storage_fit_store_done(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                           int promote, int64_t job_id, int64_t *fit_id, int64_t *calib_id,
                           err_t *err)
{
    if (job_id <= 0) return err_set(err, -EINVAL, "fit store: no job to end");
    return fit_store(st, fit, calib, promote, job_id, 1, fit_id, calib_id, err);
}

int storage_fit_store_unit(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                           int promote, int64_t job_id, int done_before, int total,
                           int64_t *fit_id, int64_t *calib_id, err_t *err)
{
    int64_t fid = 0, cid = 0;
    if (!st || !fit) return err_set(err, -EINVAL, "fit store unit: NULL argument");
    if (job_id <= 0 || done_before < 0 || done_before >= total)
        return err_set(err, -EINVAL, "fit store unit: job %lld unit %d of %d", (long long)job_id,
                       done_before + 1, total);
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    /* first the job's count: a job cancelled meanwhile, or whose unit is stored already (an
     * earlier run's), stores nothing */
    ret = stg_job_step(st, job_id, done_before, (double)(done_before + 1) / total, err);
    if (!ret && done_before + 1 == total)
        ret = stg_job_finish(st, job_id, STORAGE_DONE, NULL, err);
    if (!ret) ret = fit_rows(st, fit, calib, promote, &fid, &cid, err);
    if (!ret) ret = link_job(st, job_id, fid, err);
    return fit_rows_end(st, ret, fid, cid, fit_id, calib_id, err);
}

int storage_fit_put(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                    int64_t job_id, int64_t *fit_id, int64_t *calib_id, err_t *err)
{
    return storage_fit_store(st, fit, calib, 1, job_id, fit_id, calib_id, err);
}

int storage_calib_promote(storage_t *st, int64_t fit_id, const char *by, const char *reason,
                          int64_t *calib_id, err_t *err)
{
    storage_calib_t c;
    int64_t cur = 0, cur_fit = 0, id = 0;
    if (!st || !calib_id) return err_set(err, -EINVAL, "calibration promote: NULL argument");
    *calib_id = 0;
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_fit_map_load(st, fit_id, &c, err))) {
        stg_rollback(st);
        return ret;
    }
    /* the check and the write in one transaction: two promotes of one fit store one row */
    ret = stg_calib_current_ids(st, c.sensor_id, c.pixel_col, c.pixel_row, &cur, &cur_fit, err);
    if (ret == 0 && cur && cur_fit == fit_id) {
        id = cur;
        ret = err_set(err, -EALREADY,
                      "fit %lld is already the current calibration (#%lld) of sensor %lld pixel "
                      "(%d, %d)",
                      (long long)fit_id, (long long)cur, (long long)c.sensor_id, c.pixel_col,
                      c.pixel_row);
    }
    c.by = (char *)by; /* borrowed: cleared before the free below */
    c.reason = (char *)reason;
    if (ret == 0) ret = stg_calib_insert(st, &c, &id, err);
    c.by = c.reason = NULL;
    storage_calib_free(&c);
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) stg_rollback(st);
    if (ret == 0 || ret == -EALREADY) *calib_id = id;
    return ret;
}

int storage_scan_resume(storage_t *st, int64_t id, int64_t *job_id, err_t *err)
{
    if (!st || !job_id) return err_set(err, -EINVAL, "scan resume: NULL argument");
    *job_id = 0;
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_scan_resume(st, id, err)) || (ret = stg_job_resume(st, id, job_id, err))) {
        stg_rollback(st);
        *job_id = 0;
        return ret;
    }
    return stg_commit(st, err);
}

int storage_ptc_store_done(storage_t *st, const storage_ptc_t *p, int64_t *id, err_t *err)
{
    if (!st || !p || !id) return err_set(err, -EINVAL, "ptc store: NULL argument");
    if (p->job_id <= 0) return err_set(err, -EINVAL, "ptc store: no job");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    /* the job's end first: a job cancelled meanwhile stores nothing */
    if ((ret = stg_job_finish(st, p->job_id, STORAGE_DONE, NULL, err)) ||
        (ret = storage_ptc_put(st, p, id, err))) {
        stg_rollback(st);
        return ret;
    }
    return stg_commit(st, err);
}
