/* storage_sensor.c: the sensors table: one row per physical sensor (model, serial, array size,
 * pitch, gain, read noise, bias, full scale), created once and read by the scans and
 * calibrations that name it. */
#include "storage_int.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void storage_sensor_free(storage_sensor_t *s)
{
    if (!s) return;
    free(s->model);
    free(s->serial);
    memset(s, 0, sizeof *s);
}

void storage_sensor_list_free(storage_sensor_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->n; i++) storage_sensor_free(&l->items[i]);
    free(l->items);
    memset(l, 0, sizeof *l);
}

/* Reads a STG_SENSOR_COLS row (item: a storage_sensor_t); 0 or -ENOMEM (freed on failure). */
static int read_sensor(sqldb_stmt_t *s, void *item)
{
    storage_sensor_t *o = item;
    int oom = 0;
    memset(o, 0, sizeof *o);
    o->id = sqldb_col_int64(s, 0);
    o->model = stg_col_text(s, 1, &oom);
    o->serial = stg_col_text(s, 2, &oom);
    o->n_cols = sqldb_col_int(s, 3);
    o->n_rows = sqldb_col_int(s, 4);
    o->pitch_um = stg_col_double(s, 5);
    o->gain_e_per_dn = stg_col_double(s, 6);
    o->read_noise_e = stg_col_double(s, 7);
    o->bias_dn = stg_col_double(s, 8);
    o->full_scale_dn = stg_col_double(s, 9);
    o->created_ms = stg_col_id(s, 10);
    if (oom) storage_sensor_free(o);
    return oom ? -ENOMEM : 0;
}

static int check_sensor(const storage_sensor_t *s, err_t *err)
{
    if (!s) return err_set(err, -EINVAL, "sensor: NULL");
    if (!s->model || !*s->model) return err_set(err, -EINVAL, "sensor model: empty");
    if (!s->serial || !*s->serial) return err_set(err, -EINVAL, "sensor serial: empty");
    if (s->n_cols <= 0 || s->n_rows <= 0)
        return err_set(err, -EINVAL, "sensor n_cols/n_rows: %d x %d, need > 0", s->n_cols,
                       s->n_rows);
    if (!(s->pitch_um > 0 && isfinite(s->pitch_um)))
        return err_set(err, -EINVAL, "sensor pitch_um: %g, need > 0", s->pitch_um);
    if (!(s->gain_e_per_dn > 0 && isfinite(s->gain_e_per_dn)))
        return err_set(err, -EINVAL, "sensor gain_e_per_dn: %g, need > 0", s->gain_e_per_dn);
    if (!(s->read_noise_e >= 0 && isfinite(s->read_noise_e)))
        return err_set(err, -EINVAL, "sensor read_noise_e: %g, need >= 0", s->read_noise_e);
    if (!isfinite(s->bias_dn)) return err_set(err, -EINVAL, "sensor bias_dn: not finite");
    if (!(s->full_scale_dn > 0 && isfinite(s->full_scale_dn)))
        return err_set(err, -EINVAL, "sensor full_scale_dn: %g, need > 0", s->full_scale_dn);
    return 0;
}

int storage_sensor_create(storage_t *st, const storage_sensor_t *s, int64_t *id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !id) return err_set(err, -EINVAL, "sensor create: NULL argument");
    if ((ret = check_sensor(s, err)) || (ret = stg_stmt(st, STG_SENSOR_INSERT, &q, err)))
        return ret;
    stg_bind_text(q, 1, s->model, &rc);
    stg_bind_text(q, 2, s->serial, &rc);
    stg_bind_int(q, 3, s->n_cols, &rc);
    stg_bind_int(q, 4, s->n_rows, &rc);
    stg_bind_double(q, 5, s->pitch_um, &rc);
    stg_bind_double(q, 6, s->gain_e_per_dn, &rc);
    stg_bind_double(q, 7, s->read_noise_e, &rc);
    stg_bind_double(q, 8, s->bias_dn, &rc);
    stg_bind_double(q, 9, s->full_scale_dn, &rc);
    stg_bind_int(q, 10, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "sensor create");
    }
    ret = stg_run(st, q, err, "sensor create");
    if (ret == -EEXIST)
        return err_set(err, ret, "sensor model '%s' serial '%s' exists already", s->model,
                       s->serial);
    if (ret == 0) *id = sqldb_last_insert_id(st->db);
    return ret;
}

/* Steps q (bound) for one sensor row into *out; -ENOENT when there is none. Resets q. */
static int sensor_one(storage_t *st, sqldb_stmt_t *q, int rc, storage_sensor_t *out, err_t *err)
{
    int ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a sensor")
                              : stg_error(st, rc, err, "reading a sensor");
    if (ret == 0 && read_sensor(q, out)) ret = err_set(err, -ENOMEM, "sensor: out of memory");
    stg_reset(q);
    return ret;
}

int storage_sensor_get(storage_t *st, int64_t id, storage_sensor_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "sensor get: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_SENSOR_GET, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = sensor_one(st, q, rc, out, err);
    return ret == -ENOENT ? err_set(err, ret, "sensor %lld does not exist", (long long)id) : ret;
}

int storage_sensor_find(storage_t *st, const char *model, const char *serial,
                        storage_sensor_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out || !model || !serial)
        return err_set(err, -EINVAL, "sensor find: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_SENSOR_FIND, &q, err))) return ret;
    stg_bind_text(q, 1, model, &rc);
    stg_bind_text(q, 2, serial, &rc);
    ret = sensor_one(st, q, rc, out, err);
    if (ret == -ENOENT) return err_set(err, ret, "no sensor '%s' serial '%s'", model, serial);
    return ret;
}

int storage_sensor_list(storage_t *st, int limit, int offset, storage_sensor_list_t *out,
                        err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "sensor list: NULL argument");
    memset(out, 0, sizeof *out);
    if (offset < 0) return err_set(err, -EINVAL, "sensor list offset: %d, need >= 0", offset);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_stmt(st, STG_SENSOR_COUNT, &q, err))) goto out;
    if ((ret = stg_count(st, q, rc, &out->total, err, "counting sensors"))) goto out;
    if ((ret = stg_stmt(st, STG_SENSOR_LIST, &q, err))) goto out;
    stg_bind_int(q, 1, limit > 0 ? limit : -1, &rc);
    stg_bind_int(q, 2, offset, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "listing sensors");
        goto out;
    }
    ret = stg_collect(st, q, sizeof *out->items, read_sensor, (void **)&out->items, &out->n, err,
                      "listing sensors");
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_sensor_list_free(out);
    }
    return ret;
}
