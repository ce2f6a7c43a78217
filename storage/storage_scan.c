/* storage_scan.c: the scans table: one raster scan around one pixel of interest, from its
 * validation and insert through its states, progress counter, setup (schema 2) and cancel, to
 * paged listing. The job that runs a scan and the scan's frames are in storage_compose.c,
 * storage_job.c and storage_frame.c, which call in here (never the other way). */
#include "storage_int.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan_limits.h" /* a scan's limits (macros only) */

void storage_scan_free(storage_scan_t *sc)
{
    if (!sc) return;
    free(sc->error);
    free(sc->job_params);
    memset(sc, 0, sizeof *sc);
}

void storage_scan_list_free(storage_scan_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->n; i++) storage_scan_free(&l->items[i]);
    free(l->items);
    memset(l, 0, sizeof *l);
}

/* Reads a STG_SCAN_COLS row (item: a storage_scan_t); 0 or -ENOMEM (freed on failure). */
static int read_scan(sqldb_stmt_t *s, void *item)
{
    storage_scan_t *o = item;
    int oom = 0;
    memset(o, 0, sizeof *o);
    o->id = sqldb_col_int64(s, 0);
    o->sensor_id = sqldb_col_int64(s, 1);
    o->poi_col = sqldb_col_int(s, 2);
    o->poi_row = sqldb_col_int(s, 3);
    o->wavelength_um = stg_col_double(s, 4);
    o->na = stg_col_double(s, 5);
    o->spot_radius_um = stg_col_double(s, 6);
    o->area_px = sqldb_col_int(s, 7);
    o->step_um = stg_col_double(s, 8);
    o->sub_px = sqldb_col_int(s, 9);
    o->frames = sqldb_col_int(s, 10);
    o->exposure_us = stg_col_double(s, 11);
    o->points_total = sqldb_col_int(s, 12);
    storage_state_parse((const char *)sqldb_col_text(s, 13), &o->state); /* CHECKed */
    o->points_done = sqldb_col_int(s, 14);
    o->error = stg_col_text(s, 15, &oom);
    o->created_ms = stg_col_id(s, 16);
    o->started_ms = stg_col_id(s, 17);
    o->finished_ms = stg_col_id(s, 18);
    if (oom) storage_scan_free(o);
    return oom ? -ENOMEM : 0;
}

/* Reads a row of the scan list: STG_SCAN_COLS, then STG_SCAN_JOB_PARAMS. */
static int read_scan_listed(sqldb_stmt_t *s, void *item)
{
    storage_scan_t *o = item;
    int oom = 0, ret = read_scan(s, item);
    if (ret) return ret;
    o->job_params = stg_col_text(s, 19, &oom);
    if (oom) storage_scan_free(o);
    return oom ? -ENOMEM : 0;
}

static int positive(double v) { return v > 0 && isfinite(v); }

int stg_check_scan(const storage_scan_t *sc, const storage_sensor_t *sn, err_t *err)
{
    /* a scan's limits are instrument/scan_limits.h's: its macros only (no instrument code is
       linked into storage); the wavelength is stored in um, the limits are in nm */
    int h = (sc->sub_px - 1) / 2;
    if (sc->poi_col < 0 || sc->poi_row < 0 || sc->poi_col >= sn->n_cols ||
        sc->poi_row >= sn->n_rows)
        return err_set(err, -EINVAL, "scan poi: (%d, %d) is outside the %d x %d sensor",
                       sc->poi_col, sc->poi_row, sn->n_cols, sn->n_rows);
    if (!positive(sc->wavelength_um) || sc->wavelength_um > SCAN_WAVELENGTH_NM_MAX * 1e-3)
        return err_set(err, -EINVAL, "scan wavelength_um: %g, need > 0 and <= %g",
                       sc->wavelength_um, SCAN_WAVELENGTH_NM_MAX * 1e-3);
    if (!positive(sc->na) || sc->na > SCAN_NA_MAX)
        return err_set(err, -EINVAL, "scan na: %g, need > 0 and <= %g", sc->na, SCAN_NA_MAX);
    if (!positive(sc->spot_radius_um))
        return err_set(err, -EINVAL, "scan spot_radius_um: need > 0");
    if (sc->area_px < SCAN_AREA_PX_MIN || sc->area_px > SCAN_AREA_PX_MAX || sc->area_px % 2 == 0)
        return err_set(err, -EINVAL, "scan area_px: %d, need an odd number in %d..%d", sc->area_px,
                       SCAN_AREA_PX_MIN, SCAN_AREA_PX_MAX);
    if (!positive(sc->step_um) || sc->step_um > SCAN_STEP_UM_MAX)
        return err_set(err, -EINVAL, "scan step_um: %g, need > 0 and <= %g", sc->step_um,
                       SCAN_STEP_UM_MAX);
    if (sc->sub_px < SCAN_SUB_PX_MIN || sc->sub_px > SCAN_SUB_PX_MAX || sc->sub_px % 2 == 0)
        return err_set(err, -EINVAL, "scan sub_px: %d, need an odd number in %d..%d", sc->sub_px,
                       SCAN_SUB_PX_MIN, SCAN_SUB_PX_MAX);
    if (sc->frames < SCAN_FRAMES_MIN || sc->frames > SCAN_FRAMES_MAX)
        return err_set(err, -EINVAL, "scan frames: %d, need %d..%d", sc->frames, SCAN_FRAMES_MIN,
                       SCAN_FRAMES_MAX);
    if ((int64_t)sc->frames * sc->sub_px * sc->sub_px > SCAN_MAX_POINT_SAMPLES)
        return err_set(err, -EINVAL, "scan frames x sub_px^2: more than %ld samples per point",
                       SCAN_MAX_POINT_SAMPLES);
    if (!positive(sc->exposure_us) || sc->exposure_us > SCAN_EXPOSURE_US_MAX)
        return err_set(err, -EINVAL, "scan exposure_us: %g, need > 0 and <= %g", sc->exposure_us,
                       SCAN_EXPOSURE_US_MAX);
    if (sc->points_total <= 0 || sc->points_total > SCAN_MAX_POINTS)
        return err_set(err, -EINVAL, "scan points_total: %d, need 1..%d", sc->points_total,
                       SCAN_MAX_POINTS);
    if (sc->poi_col - h < 0 || sc->poi_row - h < 0 || sc->poi_col + h >= sn->n_cols ||
        sc->poi_row + h >= sn->n_rows)
        return err_set(err, -EINVAL, "scan sub_px: the %d x %d sub-frame around (%d, %d) leaves "
                       "the sensor", sc->sub_px, sc->sub_px, sc->poi_col, sc->poi_row);
    return 0;
}

int stg_scan_insert(storage_t *st, const storage_scan_t *sc, int64_t *id, err_t *err)
{
    sqldb_stmt_t *q;
    storage_sensor_t sn;
    int ret = storage_sensor_get(st, sc->sensor_id, &sn, err), rc = SQLDB_OK;
    if (ret) return ret;
    ret = stg_check_scan(sc, &sn, err);
    storage_sensor_free(&sn);
    if (ret || (ret = stg_stmt(st, STG_SCAN_INSERT, &q, err))) return ret;
    stg_bind_int(q, 1, sc->sensor_id, &rc);
    stg_bind_int(q, 2, sc->poi_col, &rc);
    stg_bind_int(q, 3, sc->poi_row, &rc);
    stg_bind_double(q, 4, sc->wavelength_um, &rc);
    stg_bind_double(q, 5, sc->na, &rc);
    stg_bind_double(q, 6, sc->spot_radius_um, &rc);
    stg_bind_int(q, 7, sc->area_px, &rc);
    stg_bind_double(q, 8, sc->step_um, &rc);
    stg_bind_int(q, 9, sc->sub_px, &rc);
    stg_bind_int(q, 10, sc->frames, &rc);
    stg_bind_double(q, 11, sc->exposure_us, &rc);
    stg_bind_int(q, 12, sc->points_total, &rc);
    stg_bind_int(q, 13, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "scan create");
    }
    if ((ret = stg_run(st, q, err, "scan create"))) return ret;
    *id = sqldb_last_insert_id(st->db);
    return 0;
}

int storage_scan_create(storage_t *st, const storage_scan_t *sc, int64_t *id, err_t *err)
{
    if (!st || !sc || !id) return err_set(err, -EINVAL, "scan create: NULL argument");
    int ret = stg_begin_write(st, err);
    if (ret) return ret;
    if ((ret = stg_scan_insert(st, sc, id, err))) {
        stg_rollback(st);
        return ret;
    }
    return stg_commit(st, err);
}

int stg_scan_load(storage_t *st, int64_t id, storage_scan_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_SCAN_GET, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a scan")
                          : stg_error(st, rc, err, "reading a scan");
    if (ret == 0 && read_scan(q, out)) ret = err_set(err, -ENOMEM, "scan: out of memory");
    stg_reset(q);
    return ret == -ENOENT ? err_set(err, ret, "scan %lld does not exist", (long long)id) : ret;
}

int storage_scan_get(storage_t *st, int64_t id, storage_scan_t *out, err_t *err)
{
    if (!st || !out) return err_set(err, -EINVAL, "scan get: NULL argument");
    return stg_scan_load(st, id, out, err);
}

static void bind_scan_filter(sqldb_stmt_t *q, int64_t sensor_id, int state, int *rc)
{
    stg_bind_id(q, 1, sensor_id, rc);
    stg_bind_text(q, 2, state == STORAGE_ANY ? NULL : storage_state_name(state), rc);
}

int storage_scan_list(storage_t *st, int64_t sensor_id, int state, int limit, int offset,
                      storage_scan_list_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "scan list: NULL argument");
    memset(out, 0, sizeof *out);
    if (state != STORAGE_ANY && !storage_state_name(state))
        return err_set(err, -EINVAL, "scan list state: %d is not a state", state);
    if (offset < 0) return err_set(err, -EINVAL, "scan list offset: %d, need >= 0", offset);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_stmt(st, STG_SCAN_COUNT, &q, err))) goto out;
    bind_scan_filter(q, sensor_id, state, &rc);
    if ((ret = stg_count(st, q, rc, &out->total, err, "counting scans"))) goto out;
    if ((ret = stg_stmt(st, STG_SCAN_LIST, &q, err))) goto out;
    bind_scan_filter(q, sensor_id, state, &rc);
    stg_bind_int(q, 3, limit > 0 ? limit : -1, &rc);
    stg_bind_int(q, 4, offset, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "listing scans");
        goto out;
    }
    ret = stg_collect(st, q, sizeof *out->items, read_scan_listed, (void **)&out->items, &out->n,
                      err, "listing scans");
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_scan_list_free(out);
    }
    return ret;
}

int storage_scan_set_state(storage_t *st, int64_t id, storage_state_t state, const char *error,
                           err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st) return err_set(err, -EINVAL, "scan set state: NULL handle");
    if (!storage_state_name(state))
        return err_set(err, -EINVAL, "scan state: %d is not a state", (int)state);
    if ((ret = stg_stmt(st, STG_SCAN_SET_STATE, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_text(q, 2, storage_state_name(state), &rc);
    stg_bind_text(q, 3, error, &rc);
    stg_bind_int(q, 4, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "scan set state");
    }
    if ((ret = stg_run(st, q, err, "scan set state"))) return ret;
    if (sqldb_changes(st->db) == 0)
        return err_set(err, -ENOENT, "scan %lld does not exist", (long long)id);
    return 0;
}

int stg_scan_resume(storage_t *st, int64_t id, err_t *err)
{
    storage_scan_t sc;
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_scan_load(st, id, &sc, err))) return ret;
    storage_state_t state = sc.state;
    storage_scan_free(&sc);
    if (state != STORAGE_FAILED)
        return err_set(err, -ESTALE, "scan %lld is %s, not failed: nothing to resume",
                       (long long)id, storage_state_name(state));
    if ((ret = stg_stmt(st, STG_SCAN_RESUME, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "resuming a scan");
    }
    return stg_run(st, q, err, "resuming a scan");
}

/* ---- the scan's setup (schema 2) ---------------------------------------------------------- */

int storage_scan_set_setup(storage_t *st, int64_t id, const char *json, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !json) return err_set(err, -EINVAL, "scan setup: NULL argument");
    if ((ret = stg_stmt(st, STG_SCAN_SET_SETUP, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_text(q, 2, json, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "storing a scan setup");
    }
    ret = stg_run(st, q, err, "storing a scan setup");
    if (ret == -EINVAL) return err_set(err, ret, "scan setup: not valid JSON text");
    if (ret == 0 && sqldb_changes(st->db) == 0)
        ret = err_set(err, -ENOENT, "scan %lld does not exist", (long long)id);
    return ret;
}

int storage_scan_set_points_total(storage_t *st, int64_t id, int total, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st) return err_set(err, -EINVAL, "scan points_total: NULL argument");
    if (total <= 0 || total > SCAN_MAX_POINTS)
        return err_set(err, -EINVAL, "scan points_total: %d, need 1..%d", total, SCAN_MAX_POINTS);
    if ((ret = stg_stmt(st, STG_SCAN_SET_TOTAL, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_int(q, 2, total, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "storing a scan's points_total");
    }
    ret = stg_run(st, q, err, "storing a scan's points_total");
    if (ret || sqldb_changes(st->db) > 0) return ret;
    storage_scan_t sc; /* nothing changed: an unknown scan, or more points stored */
    if ((ret = storage_scan_get(st, id, &sc, err))) return ret;
    ret = err_set(err, -EINVAL, "scan %lld points_total: %d, below its %d points stored",
                  (long long)id, total, sc.points_done);
    storage_scan_free(&sc);
    return ret;
}

int storage_scan_get_setup(storage_t *st, int64_t id, char **json, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK, oom = 0;
    if (!st || !json) return err_set(err, -EINVAL, "scan setup: NULL argument");
    *json = NULL;
    if ((ret = stg_stmt(st, STG_SCAN_GET_SETUP, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a scan setup")
                          : stg_error(st, rc, err, "reading a scan setup");
    if (ret == 0) *json = stg_col_text(q, 0, &oom);
    stg_reset(q);
    if (oom) return err_set(err, -ENOMEM, "scan setup: out of memory");
    return ret == -ENOENT ? err_set(err, ret, "scan %lld does not exist", (long long)id) : ret;
}

/* ---- changes made inside other files' transactions ---------------------------------------- */

int stg_scan_add_point(storage_t *st, int64_t id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_SCAN_ADD_POINT, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "updating scan progress");
    }
    return stg_run(st, q, err, "updating scan progress");
}

int stg_scan_cancel(storage_t *st, int64_t id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_SCAN_CANCEL, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    stg_bind_int(q, 2, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "cancelling the scan");
    }
    return stg_run(st, q, err, "cancelling the scan");
}
