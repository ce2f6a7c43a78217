/* storage_calib.c: the calibrations table, the lab's database of IPS maps with history: storing
 * a map and superseding the pixel's current one in the same transaction, and reading the current
 * map, a pixel's history and searches across sensors. */
#include "storage_int.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#ifndef IPSD_VERSION
#define IPSD_VERSION "unknown"
#endif

void storage_calib_free(storage_calib_t *c)
{
    if (!c) return;
    free(c->S);
    free(c->S_err);
    free(c->S_res);
    free(c->map_note);
    free(c->status);
    free(c->noise_model);
    free(c->software_version);
    free(c->by);
    free(c->reason);
    memset(c, 0, sizeof *c);
}

void storage_calib_list_free(storage_calib_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->n; i++) storage_calib_free(&l->items[i]);
    free(l->items);
    memset(l, 0, sizeof *l);
}

storage_calib_filter_t storage_calib_filter_default(void)
{
    return (storage_calib_filter_t){.col_min = -1, .col_max = -1, .row_min = -1, .row_max = -1};
}

/* Reads a STG_CALIB_COLS row; 0, -ENOMEM, or -EIO for a map BLOB of the wrong size. */
static int read_calib(sqldb_stmt_t *s, void *item)
{
    storage_calib_t *o = item;
    int oom = 0, bad_s = 0, bad_e = 0;
    memset(o, 0, sizeof *o);
    o->id = sqldb_col_int64(s, 0);
    o->sensor_id = sqldb_col_int64(s, 1);
    o->pixel_col = sqldb_col_int(s, 2);
    o->pixel_row = sqldb_col_int(s, 3);
    o->r = sqldb_col_int(s, 4);
    size_t n = (size_t)o->r * (size_t)o->r;
    o->S = stg_f64_from_blob(sqldb_col_blob(s, 5), (size_t)sqldb_col_bytes(s, 5), n,
                             &bad_s);
    o->S_err = stg_f64_from_blob(sqldb_col_blob(s, 6), (size_t)sqldb_col_bytes(s, 6), n,
                                 &bad_e);
    o->I0 = stg_col_double(s, 7);
    o->chi2_red = stg_col_double(s, 8);
    o->status = stg_col_text(s, 9, &oom);
    o->scan_id = stg_col_id(s, 10);
    o->fit_id = stg_col_id(s, 11);
    o->noise_model = stg_col_text(s, 12, &oom);
    o->wavelength_um = stg_col_double(s, 13);
    o->na = stg_col_double(s, 14);
    o->spot_radius_um = stg_col_double(s, 15);
    o->software_version = stg_col_text(s, 16, &oom);
    o->created_ms = stg_col_id(s, 17);
    o->superseded_by = stg_col_id(s, 18);
    o->supersedes = stg_col_id(s, 19);
    o->by = stg_col_text(s, 20, &oom);
    o->reason = stg_col_text(s, 21, &oom);
    o->map = stg_col_map(s, 22);
    o->S_res = stg_col_f64_or_null(s, 23, n, &bad_e, &oom);
    o->map_note = stg_col_text(s, 24, &oom);
    int ret = bad_s || bad_e ? -EIO : (oom || !o->S || !o->S_err) ? -ENOMEM : 0;
    if (ret) storage_calib_free(o);
    return ret;
}

#define DEFAULT_BY "ipsd"
#define DEFAULT_REASON "no reason given"

int stg_calib_check(storage_t *st, const storage_calib_t *c, err_t *err)
{
    storage_sensor_t sn;
    if (c->by && !*c->by) return err_set(err, -EINVAL, "calibration by: empty");
    if (c->reason && !*c->reason) return err_set(err, -EINVAL, "calibration reason: empty");
    if (c->r < 1 || c->r > 64) return err_set(err, -EINVAL, "calibration r: %d, need 1..64", c->r);
    if (!c->S || !c->S_err) return err_set(err, -EINVAL, "calibration S / S_err: NULL");
    if (!c->status || !*c->status) return err_set(err, -EINVAL, "calibration status: empty");
    if (!c->noise_model || !*c->noise_model)
        return err_set(err, -EINVAL, "calibration noise_model: empty");
    int ret = storage_sensor_get(st, c->sensor_id, &sn, err);
    if (ret) return ret;
    if (c->pixel_col < 0 || c->pixel_row < 0 || c->pixel_col >= sn.n_cols ||
        c->pixel_row >= sn.n_rows)
        ret = err_set(err, -EINVAL, "calibration pixel: (%d, %d) is outside the %d x %d sensor",
                      c->pixel_col, c->pixel_row, sn.n_cols, sn.n_rows);
    storage_sensor_free(&sn);
    return ret;
}

/* Single row: steps bound q expecting one integer (0 when there is no row). */
static int one_id(storage_t *st, sqldb_stmt_t *q, int rc, int64_t *v, err_t *err, const char *what)
{
    int ret = rc == SQLDB_OK ? stg_row(st, q, err, what) : stg_error(st, rc, err, what);
    *v = ret == 0 ? sqldb_col_int64(q, 0) : 0;
    stg_reset(q);
    return ret == -ENOENT ? 0 : ret;
}

int stg_calib_current_ids(storage_t *st, int64_t sensor_id, int pixel_col, int pixel_row,
                          int64_t *id, int64_t *fit_id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    *id = *fit_id = 0;
    if ((ret = stg_stmt(st, STG_CALIB_CURRENT_ID, &q, err))) return ret;
    stg_bind_int(q, 1, sensor_id, &rc);
    stg_bind_int(q, 2, pixel_col, &rc);
    stg_bind_int(q, 3, pixel_row, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "finding the current calibration")
                          : stg_error(st, rc, err, "finding the current calibration");
    if (ret == 0) {
        *id = sqldb_col_int64(q, 0);
        *fit_id = stg_col_id(q, 1);
    }
    stg_reset(q);
    return ret == -ENOENT ? 0 : ret;
}

/* Inside the write transaction: finds the current calibration of the pixel (*old, 0: none),
 * reserves the new id, points the old row to it and inserts the new row. superseded_by is a
 * DEFERRED foreign key, so the old row may name the new id before the new row exists; the partial
 * unique index calibrations_current allows one current row per pixel at every step. */
static int supersede(storage_t *st, const storage_calib_t *c, int64_t *old, int64_t *new_id,
                     err_t *err)
{
    sqldb_stmt_t *q;
    int64_t old_fit;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_calib_current_ids(st, c->sensor_id, c->pixel_col, c->pixel_row, old, &old_fit,
                                     err)))
        return ret;
    if ((ret = stg_stmt(st, STG_CALIB_NEXT_ID, &q, err)) ||
        (ret = one_id(st, q, SQLDB_OK, new_id, err, "reserving a calibration id")))
        return ret;
    if (!*old) return 0;
    if ((ret = stg_stmt(st, STG_CALIB_SUPERSEDE, &q, err))) return ret;
    stg_bind_int(q, 1, *old, &rc);
    stg_bind_int(q, 2, *new_id, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "superseding a calibration");
    }
    return stg_run(st, q, err, "superseding a calibration");
}

int stg_calib_insert(storage_t *st, const storage_calib_t *c, int64_t *id, err_t *err)
{
    sqldb_stmt_t *q;
    int64_t new_id = 0, old = 0;
    int ret = stg_calib_check(st, c, err), rc = SQLDB_OK;
    if (ret || (ret = supersede(st, c, &old, &new_id, err))) return ret;
    unsigned char *s = NULL, *e = NULL, *res = NULL;
    if ((ret = stg_stmt(st, STG_CALIB_INSERT, &q, err))) goto out;
    stg_bind_int(q, 1, new_id, &rc);
    if (stg_bind_map(q, c, &s, &e, &rc)) {
        stg_reset(q);
        ret = err_set(err, -ENOMEM, "calibration: out of memory");
        goto out;
    }
    stg_bind_id(q, 11, c->scan_id, &rc);
    stg_bind_id(q, 12, c->fit_id, &rc);
    stg_bind_text(q, 13, c->noise_model, &rc);
    stg_bind_double(q, 14, c->wavelength_um, &rc);
    stg_bind_double(q, 15, c->na, &rc);
    stg_bind_double(q, 16, c->spot_radius_um, &rc);
    stg_bind_text(q, 17, c->software_version ? c->software_version : IPSD_VERSION, &rc);
    stg_bind_int(q, 18, storage_now_ms(st), &rc);
    stg_bind_id(q, 19, old, &rc);
    stg_bind_text(q, 20, c->by ? c->by : DEFAULT_BY, &rc);
    stg_bind_text(q, 21, c->reason ? c->reason : DEFAULT_REASON, &rc);
    stg_bind_text(q, 22, storage_map_name(c->map), &rc);
    if (stg_bind_f64_or_null(q, 23, c->S_res, (size_t)c->r * (size_t)c->r, &res, &rc)) {
        stg_reset(q);
        ret = err_set(err, -ENOMEM, "calibration: out of memory");
        goto out;
    }
    stg_bind_text(q, 24, c->map_note && c->map_note[0] ? c->map_note : NULL, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "storing a calibration");
        goto out;
    }
    ret = stg_run(st, q, err, "storing a calibration");
    if (ret == -ENOENT)
        err_set(err, ret, "calibration: scan %lld or fit %lld does not exist",
                (long long)c->scan_id, (long long)c->fit_id);
    if (ret == 0) {
        *id = new_id;
        stg_gate_calib_written(st); /* the generation is odd until the transaction ends */
    }
out:
    free(s);
    free(e);
    free(res);
    return ret;
}

int storage_calib_put(storage_t *st, const storage_calib_t *c, int64_t *id, err_t *err)
{
    if (!st || !c || !id) return err_set(err, -EINVAL, "calibration put: NULL argument");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_calib_insert(st, c, id, err))) {
        stg_rollback(st);
        return ret;
    }
    return stg_commit(st, err);
}

/* Runs a bound single-calibration query into *out. */
static int calib_one(storage_t *st, sqldb_stmt_t *q, int rc, storage_calib_t *out, err_t *err)
{
    int ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a calibration")
                              : stg_error(st, rc, err, "reading a calibration");
    if (ret == 0 && (ret = read_calib(q, out)))
        err_set(err, ret, "reading a calibration: %s",
                ret == -EIO ? "map BLOB of the wrong size" : "out of memory");
    stg_reset(q);
    return ret;
}

int storage_calib_get(storage_t *st, int64_t id, storage_calib_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "calibration get: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_CALIB_GET, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = calib_one(st, q, rc, out, err);
    return ret == -ENOENT ? err_set(err, ret, "calibration %lld does not exist", (long long)id)
                          : ret;
}

int storage_calib_current(storage_t *st, int64_t sensor_id, int pixel_col, int pixel_row,
                          storage_calib_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "calibration current: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_CALIB_CURRENT, &q, err))) return ret;
    stg_bind_int(q, 1, sensor_id, &rc);
    stg_bind_int(q, 2, pixel_col, &rc);
    stg_bind_int(q, 3, pixel_row, &rc);
    ret = calib_one(st, q, rc, out, err);
    if (ret == -ENOENT)
        err_set(err, ret, "sensor %lld pixel (%d, %d) has no calibration", (long long)sensor_id,
                pixel_col, pixel_row);
    return ret;
}

int storage_calib_history(storage_t *st, int64_t sensor_id, int pixel_col, int pixel_row,
                          storage_calib_list_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "calibration history: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_CALIB_HISTORY, &q, err))) return ret;
    stg_bind_int(q, 1, sensor_id, &rc);
    stg_bind_int(q, 2, pixel_col, &rc);
    stg_bind_int(q, 3, pixel_row, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "reading calibration history");
    }
    ret = stg_collect(st, q, sizeof *out->items, read_calib, (void **)&out->items, &out->n, err,
                      "reading calibration history");
    if (ret) storage_calib_list_free(out);
    else out->total = (int64_t)out->n;
    return ret;
}

static void bind_calib_filter(sqldb_stmt_t *q, const storage_calib_filter_t *f, int *rc)
{
    stg_bind_id(q, 1, f->sensor_id, rc);
    stg_bind_text(q, 2, f->model, rc);
    int bounds[4] = {f->col_min, f->col_max, f->row_min, f->row_max};
    for (int i = 0; i < 4; i++) {
        if (bounds[i] < 0) {
            if (*rc == SQLDB_OK) *rc = sqldb_bind_null(q, 3 + i);
        } else {
            stg_bind_int(q, 3 + i, bounds[i], rc);
        }
    }
    stg_bind_id(q, 7, f->since_ms, rc);
    stg_bind_text(q, 8, f->status, rc);
    stg_bind_int(q, 9, f->current_only ? 1 : 0, rc);
}

int storage_calib_search(storage_t *st, const storage_calib_filter_t *f, int limit, int offset,
                         storage_calib_list_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !f || !out) return err_set(err, -EINVAL, "calibration search: NULL argument");
    memset(out, 0, sizeof *out);
    if (offset < 0)
        return err_set(err, -EINVAL, "calibration search offset: %d, need >= 0", offset);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_stmt(st, STG_CALIB_COUNT, &q, err))) goto out;
    bind_calib_filter(q, f, &rc);
    if ((ret = stg_count(st, q, rc, &out->total, err, "counting calibrations"))) goto out;
    if ((ret = stg_stmt(st, STG_CALIB_SEARCH, &q, err))) goto out;
    bind_calib_filter(q, f, &rc);
    stg_bind_int(q, 10, limit > 0 ? limit : -1, &rc);
    stg_bind_int(q, 11, offset, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "searching calibrations");
        goto out;
    }
    ret = stg_collect(st, q, sizeof *out->items, read_calib, (void **)&out->items, &out->n, err,
                      "searching calibrations");
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_calib_list_free(out);
    }
    return ret;
}
