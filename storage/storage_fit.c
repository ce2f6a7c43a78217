/* storage_fit.c: the fits table: the whole result of one fit job (the `ips fit` JSON with the
 * best r, F-test and Wiener baseline) for one sub-frame pixel of a scan or for an uploaded scan
 * file; checked, inserted, read and listed per scan; and its fit_maps row, the map the fit offers
 * as its pixel's calibration (what promoting the fit stores). Storing a fit together with its job
 * link and calibration (storage_fit_put) is in storage_compose.c. */
#include "storage_int.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#ifndef IPSD_VERSION
#define IPSD_VERSION "unknown"
#endif

void storage_fit_free(storage_fit_t *f)
{
    if (!f) return;
    free(f->noise_model);
    free(f->result);
    memset(f, 0, sizeof *f);
}

void storage_fit_list_free(storage_fit_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->n; i++) storage_fit_free(&l->items[i]);
    free(l->items);
    memset(l, 0, sizeof *l);
}

static int read_fit(sqldb_stmt_t *s, void *item)
{
    storage_fit_t *o = item;
    int oom = 0;
    memset(o, 0, sizeof *o);
    o->id = sqldb_col_int64(s, 0);
    o->scan_id = sqldb_col_int64(s, 1);
    o->dcol = sqldb_col_int(s, 2);
    o->drow = sqldb_col_int(s, 3);
    o->noise_model = stg_col_text(s, 4, &oom);
    o->best_r_aic = (int)stg_col_id(s, 5);
    o->best_r_bic = (int)stg_col_id(s, 6);
    o->f_value = stg_col_double(s, 7);
    o->p_value = stg_col_double(s, 8);
    o->result = stg_col_text(s, 9, &oom);
    o->created_ms = stg_col_id(s, 10);
    o->map_sensor_id = stg_col_id(s, 11);
    o->map_col = sqldb_col_int(s, 12);
    o->map_row = sqldb_col_int(s, 13);
    o->map_r = sqldb_col_int(s, 14);
    o->pixel_calib_id = stg_col_id(s, 15);
    o->pixel_calib_fit_id = stg_col_id(s, 16);
    o->map_kind = stg_col_map(s, 17);
    if (oom) storage_fit_free(o);
    return oom ? -ENOMEM : 0;
}

int stg_fit_insert(storage_t *st, const storage_fit_t *f, int64_t *id, err_t *err)
{
    storage_scan_t sc;
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!f->noise_model || !*f->noise_model) return err_set(err, -EINVAL, "fit noise_model: empty");
    if (!f->result) return err_set(err, -EINVAL, "fit result: NULL");
    if (f->best_r_aic < 0 || f->best_r_bic < 0)
        return err_set(err, -EINVAL, "fit best_r: need >= 0 (0: none)");
    int h = 0; /* a fit of an uploaded scan file (no scan) is of its one pixel, (0, 0) */
    if (f->scan_id) {
        if ((ret = stg_scan_load(st, f->scan_id, &sc, err))) return ret;
        h = (sc.sub_px - 1) / 2;
        storage_scan_free(&sc);
    }
    if (abs(f->dcol) > h || abs(f->drow) > h)
        return err_set(err, -EINVAL, "fit pixel: (%d, %d) is outside scan %lld's sub-frame "
                       "(offsets -%d..%d)", f->dcol, f->drow, (long long)f->scan_id, h, h);
    if ((ret = stg_stmt(st, STG_FIT_INSERT, &q, err))) return ret;
    stg_bind_id(q, 1, f->scan_id, &rc);
    stg_bind_int(q, 2, f->dcol, &rc);
    stg_bind_int(q, 3, f->drow, &rc);
    stg_bind_text(q, 4, f->noise_model, &rc);
    stg_bind_id(q, 5, f->best_r_aic, &rc);
    stg_bind_id(q, 6, f->best_r_bic, &rc);
    stg_bind_double(q, 7, f->f_value, &rc);
    stg_bind_double(q, 8, f->p_value, &rc);
    stg_bind_text(q, 9, f->result, &rc);
    stg_bind_int(q, 10, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "storing a fit");
    }
    ret = stg_run(st, q, err, "storing a fit");
    if (ret == -EINVAL) return err_set(err, ret, "fit result: not valid JSON text");
    if (ret == 0) *id = sqldb_last_insert_id(st->db);
    return ret;
}

int stg_fit_set_job(storage_t *st, int64_t fit_id, int64_t job_id, err_t *err)
{
    return stg_run_ids(st, STG_FIT_SET_JOB, fit_id, job_id, err, "recording the fit's job");
}

int storage_fit_get(storage_t *st, int64_t id, storage_fit_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "fit get: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_FIT_GET, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a fit")
                          : stg_error(st, rc, err, "reading a fit");
    if (ret == 0 && read_fit(q, out)) ret = err_set(err, -ENOMEM, "fit get: out of memory");
    stg_reset(q);
    return ret == -ENOENT ? err_set(err, ret, "fit %lld does not exist", (long long)id) : ret;
}

int storage_fit_list(storage_t *st, int64_t scan_id, int limit, int offset, storage_fit_list_t *out,
                     err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "fit list: NULL argument");
    memset(out, 0, sizeof *out);
    if (offset < 0) return err_set(err, -EINVAL, "fit list offset: %d, need >= 0", offset);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_stmt(st, STG_FIT_COUNT, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    if ((ret = stg_count(st, q, rc, &out->total, err, "counting fits"))) goto out;
    if ((ret = stg_stmt(st, STG_FIT_LIST, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    stg_bind_int(q, 2, limit > 0 ? limit : -1, &rc);
    stg_bind_int(q, 3, offset, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "listing fits");
        goto out;
    }
    ret = stg_collect(st, q, sizeof *out->items, read_fit, (void **)&out->items, &out->n, err,
                      "listing fits");
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_fit_list_free(out);
    }
    return ret;
}

/* ---- the map a fit offers (fit_maps) ------------------------------------------------------ */

int stg_fit_map_insert(storage_t *st, int64_t fit_id, const storage_calib_t *c, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    unsigned char *s = NULL, *e = NULL, *res = NULL;
    if ((ret = stg_stmt(st, STG_FIT_MAP_INSERT, &q, err))) goto out;
    stg_bind_int(q, 1, fit_id, &rc);
    if (stg_bind_map(q, c, &s, &e, &rc)) {
        stg_reset(q);
        ret = err_set(err, -ENOMEM, "fit map: out of memory");
        goto out;
    }
    stg_bind_double(q, 11, c->wavelength_um, &rc);
    stg_bind_double(q, 12, c->na, &rc);
    stg_bind_double(q, 13, c->spot_radius_um, &rc);
    stg_bind_text(q, 14, c->software_version ? c->software_version : IPSD_VERSION, &rc);
    stg_bind_text(q, 15, storage_map_name(c->map), &rc);
    if (stg_bind_f64_or_null(q, 16, c->S_res, (size_t)c->r * (size_t)c->r, &res, &rc)) {
        stg_reset(q);
        ret = err_set(err, -ENOMEM, "fit map: out of memory");
        goto out;
    }
    stg_bind_text(q, 17, c->map_note && c->map_note[0] ? c->map_note : NULL, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "storing a fit's map");
        goto out;
    }
    ret = stg_run(st, q, err, "storing a fit's map");
out:
    free(s);
    free(e);
    free(res);
    return ret;
}

/* storage_calib_free's work on what stg_fit_map_load fills (storage_fit.c does not call into
 * storage_calib.c: docs/schema.md, "The code") */
static void map_free(storage_calib_t *c)
{
    free(c->S);
    free(c->S_err);
    free(c->S_res);
    free(c->map_note);
    free(c->status);
    free(c->noise_model);
    free(c->software_version);
    memset(c, 0, sizeof *c);
}

int stg_fit_map_load(storage_t *st, int64_t fit_id, storage_calib_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK, oom = 0, bad_s = 0, bad_e = 0;
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_FIT_MAP_GET, &q, err))) return ret;
    stg_bind_int(q, 1, fit_id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a fit's map")
                          : stg_error(st, rc, err, "reading a fit's map");
    if (ret == -ENOENT) ret = err_set(err, ret, "fit %lld does not exist", (long long)fit_id);
    if (ret == 0 && sqldb_col_null(q, 0))
        ret = err_set(err, -ENODATA,
                      "fit %lld has no map to store as a calibration (no admissible map, or a "
                      "fit of an uploaded scan file without a sensor pixel)",
                      (long long)fit_id);
    if (ret == 0) {
        out->fit_id = sqldb_col_int64(q, 0);
        out->sensor_id = sqldb_col_int64(q, 1);
        out->pixel_col = sqldb_col_int(q, 2);
        out->pixel_row = sqldb_col_int(q, 3);
        out->r = sqldb_col_int(q, 4);
        size_t n = (size_t)out->r * (size_t)out->r;
        out->S = stg_f64_from_blob(sqldb_col_blob(q, 5), (size_t)sqldb_col_bytes(q, 5),
                                   n, &bad_s);
        out->S_err = stg_f64_from_blob(sqldb_col_blob(q, 6),
                                       (size_t)sqldb_col_bytes(q, 6), n, &bad_e);
        out->I0 = stg_col_double(q, 7);
        out->chi2_red = stg_col_double(q, 8);
        out->status = stg_col_text(q, 9, &oom);
        out->scan_id = stg_col_id(q, 10);
        out->noise_model = stg_col_text(q, 11, &oom);
        out->wavelength_um = stg_col_double(q, 12);
        out->na = stg_col_double(q, 13);
        out->spot_radius_um = stg_col_double(q, 14);
        out->software_version = stg_col_text(q, 15, &oom);
        out->map = stg_col_map(q, 16);
        out->S_res = stg_col_f64_or_null(q, 17, n, &bad_e, &oom);
        out->map_note = stg_col_text(q, 18, &oom);
        if (bad_s || bad_e)
            ret = err_set(err, -EIO, "fit %lld's map: BLOB of the wrong size", (long long)fit_id);
        else if (oom || !out->S || !out->S_err)
            ret = err_set(err, -ENOMEM, "fit %lld's map: out of memory", (long long)fit_id);
    }
    stg_reset(q);
    if (ret) map_free(out);
    return ret;
}
