/* storage_ptc.c: the ptc table: photon-transfer measurements of a sensor (EMVA 1288), every one
 * kept, newest first when read (the sensor's history of measured gain and read noise). */
#include "storage_int.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void storage_ptc_free(storage_ptc_t *p)
{
    if (!p) return;
    free(p->result);
    memset(p, 0, sizeof *p);
}

void storage_ptc_list_free(storage_ptc_list_t *l)
{
    if (!l) return;
    for (size_t i = 0; i < l->n; i++)
        storage_ptc_free(&l->items[i]);
    free(l->items);
    memset(l, 0, sizeof *l);
}

/* Reads a STG_PTC_COLS row (item: a storage_ptc_t); 0 or -ENOMEM (freed on failure). */
static int read_ptc(sqldb_stmt_t *s, void *item)
{
    storage_ptc_t *o = item;
    int oom = 0;
    memset(o, 0, sizeof *o);
    o->id = sqldb_col_int64(s, 0);
    o->sensor_id = sqldb_col_int64(s, 1);
    o->gain_e_per_dn = stg_col_double(s, 2);
    o->read_noise_e = stg_col_double(s, 3);
    o->dark_dn = stg_col_double(s, 4);
    o->saturation_dn = stg_col_double(s, 5);
    o->linearity_error_pct = stg_col_double(s, 6);
    o->result = stg_col_text(s, 7, &oom);
    o->job_id = stg_col_id(s, 8);
    o->created_ms = stg_col_id(s, 9);
    if (oom) storage_ptc_free(o);
    return oom ? -ENOMEM : 0;
}

int storage_ptc_put(storage_t *st, const storage_ptc_t *p, int64_t *id, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !p || !id || !p->result) return err_set(err, -EINVAL, "ptc put: NULL argument");
    if (!(p->gain_e_per_dn > 0 && isfinite(p->gain_e_per_dn)))
        return err_set(err, -EINVAL, "ptc gain_e_per_dn: %g, need > 0", p->gain_e_per_dn);
    if (!(p->read_noise_e >= 0 && isfinite(p->read_noise_e)))
        return err_set(err, -EINVAL, "ptc read_noise_e: %g, need >= 0", p->read_noise_e);
    if ((ret = stg_stmt(st, STG_PTC_INSERT, &q, err))) return ret;
    stg_bind_int(q, 1, p->sensor_id, &rc);
    stg_bind_double(q, 2, p->gain_e_per_dn, &rc);
    stg_bind_double(q, 3, p->read_noise_e, &rc);
    stg_bind_double(q, 4, p->dark_dn, &rc);
    stg_bind_double(q, 5, p->saturation_dn, &rc);
    stg_bind_double(q, 6, p->linearity_error_pct, &rc);
    stg_bind_text(q, 7, p->result, &rc);
    stg_bind_id(q, 8, p->job_id, &rc);
    stg_bind_int(q, 9, storage_now_ms(st), &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "ptc put");
    }
    ret = stg_run(st, q, err, "ptc put");
    if (ret == 0) *id = sqldb_last_insert_id(st->db);
    return ret;
}

int storage_ptc_history(storage_t *st, int64_t sensor_id, int limit, storage_ptc_list_t *out,
                        err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "ptc history: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_PTC_HISTORY, &q, err))) return ret;
    stg_bind_int(q, 1, sensor_id, &rc);
    stg_bind_int(q, 2, limit > 0 ? limit : -1, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "ptc history");
    }
    ret = stg_collect(st, q, sizeof *out->items, read_ptc, (void **)&out->items, &out->n, err,
                      "ptc history");
    if (ret) storage_ptc_list_free(out);
    return ret;
}

int storage_ptc_get(storage_t *st, int64_t id, storage_ptc_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "ptc get: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_stmt(st, STG_PTC_GET, &q, err))) return ret;
    stg_bind_int(q, 1, id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a ptc measurement")
                          : stg_error(st, rc, err, "reading a ptc measurement");
    if (ret == 0 && read_ptc(q, out)) ret = err_set(err, -ENOMEM, "ptc: out of memory");
    stg_reset(q);
    return ret == -ENOENT
               ? err_set(err, ret, "photon-transfer measurement %lld does not exist", (long long)id)
               : ret;
}
