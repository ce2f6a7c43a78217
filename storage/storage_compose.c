/* storage_compose.c: the writes that span tables, each one transaction composed of the per-table
 * steps of the other files (stg_*_insert, stg_job_set_fit): a scan with the job that runs it, and
 * a fit with its job link and calibration. Nothing calls into this file from storage/, so the
 * table files never call each other both ways (docs/schema.md, "The code"). */
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

int storage_fit_put(storage_t *st, const storage_fit_t *fit, const storage_calib_t *calib,
                    int64_t job_id, int64_t *fit_id, int64_t *calib_id, err_t *err)
{
    int64_t fid = 0, cid = 0;
    if (!st || !fit) return err_set(err, -EINVAL, "fit put: NULL argument");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_fit_insert(st, fit, &fid, err))) goto out;
    if (job_id > 0 && (ret = stg_job_set_fit(st, job_id, fid, err))) goto out;
    if (calib) {
        storage_calib_t c = *calib; /* shallow: only the two ids change */
        c.fit_id = fid;
        if (!c.scan_id) c.scan_id = fit->scan_id;
        ret = stg_calib_insert(st, &c, &cid, err);
    }
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        return ret;
    }
    if (fit_id) *fit_id = fid;
    if (calib_id) *calib_id = cid;
    return 0;
}
