/* storage_frame.c: the frames of a scan, one row per raster point: storing a point together with
 * the scan's progress (one transaction, so a crash loses at most the point in flight), reading a
 * point back, where to resume, the raster of one sub-frame pixel that the fit needs, and every
 * point's whole mean frame (a scan file with its sub-frame). */
#include "storage_int.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/le.h"

void storage_frame_free(storage_frame_t *f)
{
    if (!f) return;
    free(f->raw);
    free(f->mean);
    free(f->timestamps_ns);
    free(f->camera_frame_ids);
    memset(f, 0, sizeof *f);
}

double storage_frame_bytes(int frames, int sub_px)
{
    double m2 = (double)sub_px * sub_px;
    return m2 * frames * sizeof(uint16_t) + m2 * sizeof(double); /* raw + mean blobs */
}

void storage_raster_free(storage_raster_t *r)
{
    if (!r) return;
    free(r->point_index);
    free(r->stage_x_um);
    free(r->stage_y_um);
    free(r->exposure_us);
    free(r->mean_dn);
    memset(r, 0, sizeof *r);
}

static int check_frame(const storage_frame_t *f, err_t *err)
{
    if (!f) return err_set(err, -EINVAL, "frame: NULL");
    if (!f->raw || !f->mean) return err_set(err, -EINVAL, "frame: raw or mean is NULL");
    if (f->frames <= 0 || f->sub_px <= 0)
        return err_set(err, -EINVAL, "frame frames/sub_px: %d/%d, need > 0", f->frames, f->sub_px);
    if (f->point_index < 0)
        return err_set(err, -EINVAL, "frame point_index: %d, need >= 0", f->point_index);
    if (!isfinite(f->stage_x_um) || !isfinite(f->stage_y_um) || !isfinite(f->stage_z_um))
        return err_set(err, -EINVAL, "frame stage position: not finite");
    if (!(f->exposure_us > 0 && isfinite(f->exposure_us)))
        return err_set(err, -EINVAL, "frame exposure_us: %g, need > 0", f->exposure_us);
    return 0;
}

/* Inside the write transaction: the scan must be running and agree with the frame's shape. */
static int check_against_scan(storage_t *st, const storage_frame_t *f, err_t *err)
{
    storage_scan_t sc;
    int ret = stg_scan_load(st, f->scan_id, &sc, err);
    if (ret) return ret;
    if (sc.state == STORAGE_CANCELLED)
        ret = err_set(err, -ECANCELED, "scan %lld was cancelled", (long long)sc.id);
    else if (sc.state != STORAGE_RUNNING)
        ret = err_set(err, -ESTALE, "scan %lld is %s, not running", (long long)sc.id,
                      storage_state_name(sc.state));
    else if (f->frames != sc.frames || f->sub_px != sc.sub_px)
        ret = err_set(err, -EINVAL,
                      "frame shape: %d frames of %d x %d, scan %lld has %d of %d x %d", f->frames,
                      f->sub_px, f->sub_px, (long long)sc.id, sc.frames, sc.sub_px, sc.sub_px);
    else if (f->point_index >= sc.points_total)
        ret = err_set(err, -EINVAL, "frame point_index: %d, scan %lld has %d points",
                      f->point_index, (long long)sc.id, sc.points_total);
    storage_scan_free(&sc);
    return ret;
}

/* k 64-bit integers as a little-endian BLOB bound to parameter i (NULL: bound as NULL). */
static void bind_u64s(sqldb_stmt_t *q, int i, const uint64_t *v, size_t k, int *rc)
{
    if (*rc != SQLDB_OK) return;
    if (!v) {
        *rc = sqldb_bind_null(q, i);
        return;
    }
    unsigned char *b = malloc(k ? k * 8 : 1);
    if (!b) {
        *rc = SQLDB_NOMEM;
        return;
    }
    for (size_t j = 0; j < k; j++) le_put_u64(b + 8 * j, v[j]);
    *rc = sqldb_bind_blob(q, i, b, k * 8);
    free(b);
}

/* Column i as k 64-bit integers (*out NULL when the column is NULL or not k long: not recorded);
 * nonzero when out of memory. */
static int col_u64s(sqldb_stmt_t *q, int i, size_t k, uint64_t **out)
{
    *out = NULL;
    const unsigned char *b = sqldb_col_blob(q, i);
    if (!b || (size_t)sqldb_col_bytes(q, i) != k * 8) return 0;
    if (!(*out = malloc(k ? k * sizeof **out : 1))) return 1;
    for (size_t j = 0; j < k; j++) (*out)[j] = le_get_u64(b + 8 * j);
    return 0;
}

/* The two statements of a point: the frame row, then the scan's progress. */
static int insert_point(storage_t *st, const storage_frame_t *f, const unsigned char *mean,
                        size_t mean_bytes, const unsigned char *raw, size_t raw_bytes, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_FRAME_INSERT, &q, err))) return ret;
    stg_bind_int(q, 1, f->scan_id, &rc);
    stg_bind_int(q, 2, f->point_index, &rc);
    stg_bind_double(q, 3, f->stage_x_um, &rc);
    stg_bind_double(q, 4, f->stage_y_um, &rc);
    stg_bind_double(q, 5, f->stage_z_um, &rc);
    stg_bind_double(q, 6, f->exposure_us, &rc);
    stg_bind_int(q, 7, storage_now_ms(st), &rc);
    stg_bind_blob(q, 8, mean, mean_bytes, &rc);
    stg_bind_blob(q, 9, raw, raw_bytes, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, "storing a frame");
    }
    ret = stg_run(st, q, err, "storing a frame");
    if (ret == -EEXIST)
        return err_set(err, ret, "scan %lld point %d is stored already", (long long)f->scan_id,
                       f->point_index);
    if (ret == 0 && (f->timestamps_ns || f->camera_frame_ids)) {
        if ((ret = stg_stmt(st, STG_FRAME_TIMES_INSERT, &q, err))) return ret;
        stg_bind_int(q, 1, f->scan_id, &rc);
        stg_bind_int(q, 2, f->point_index, &rc);
        bind_u64s(q, 3, (const uint64_t *)f->timestamps_ns, (size_t)f->frames, &rc);
        bind_u64s(q, 4, f->camera_frame_ids, (size_t)f->frames, &rc);
        if (rc != SQLDB_OK) {
            stg_reset(q);
            return stg_error(st, rc, err, "storing a frame's times");
        }
        ret = stg_run(st, q, err, "storing a frame's times");
    }
    return ret ? ret : stg_scan_add_point(st, f->scan_id, err);
}

/* The frame times of a point into out (left NULL when none are stored). */
static int read_times(storage_t *st, storage_frame_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, STG_FRAME_TIMES_GET, &q, err))) return ret;
    stg_bind_int(q, 1, out->scan_id, &rc);
    stg_bind_int(q, 2, out->point_index, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a frame's times")
                          : stg_error(st, rc, err, "reading a frame's times");
    if (ret == 0 && (col_u64s(q, 0, (size_t)out->frames, (uint64_t **)&out->timestamps_ns) ||
                     col_u64s(q, 1, (size_t)out->frames, &out->camera_frame_ids)))
        ret = err_set(err, -ENOMEM, "frame get: out of memory");
    stg_reset(q);
    return ret == -ENOENT ? 0 : ret;
}

int storage_frame_put(storage_t *st, const storage_frame_t *f, err_t *err)
{
    unsigned char *mean = NULL, *raw = NULL;
    if (!st) return err_set(err, -EINVAL, "frame put: NULL handle");
    int ret = check_frame(f, err);
    if (ret || (ret = stg_begin_write(st, err))) return ret;
    /* the shape is checked against the scan before the arrays are read */
    if ((ret = check_against_scan(st, f, err))) goto out;
    size_t m2 = (size_t)f->sub_px * (size_t)f->sub_px, k = (size_t)f->frames;
    mean = stg_blob_from_f64(f->mean, m2);
    raw = stg_blob_from_u16(f->raw, k * m2);
    if (!mean || !raw) {
        ret = err_set(err, -ENOMEM, "frame put: out of memory");
        goto out;
    }
    ret = insert_point(st, f, mean, m2 * 8, raw, k * m2 * 2, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    else stg_rollback(st);
    free(mean);
    free(raw);
    return ret;
}

/* Decodes the row of STG_FRAME_GET into *out, whose frames/sub_px are set. */
static int read_frame(sqldb_stmt_t *q, storage_frame_t *out, err_t *err)
{
    size_t m2 = (size_t)out->sub_px * (size_t)out->sub_px;
    int bad_mean = 0, bad_raw = 0;
    out->stage_x_um = stg_col_double(q, 0);
    out->stage_y_um = stg_col_double(q, 1);
    out->stage_z_um = stg_col_double(q, 2);
    out->exposure_us = stg_col_double(q, 3);
    out->captured_ms = stg_col_id(q, 4);
    out->mean = stg_f64_from_blob(sqldb_col_blob(q, 5), (size_t)sqldb_col_bytes(q, 5), m2,
                                  &bad_mean);
    out->raw = stg_u16_from_blob(sqldb_col_blob(q, 6), (size_t)sqldb_col_bytes(q, 6),
                                 (size_t)out->frames * m2, &bad_raw);
    if (bad_mean || bad_raw)
        return err_set(err, -EIO, "scan %lld point %d: stored frame size does not match the scan",
                       (long long)out->scan_id, out->point_index);
    if (!out->mean || !out->raw) return err_set(err, -ENOMEM, "frame get: out of memory");
    out->raw_first = 0;
    out->raw_count = out->frames;
    return 0;
}

/* Decodes the row of STG_FRAME_HEAD into *out (frames/sub_px and raw_first/raw_count set), the
 * raw frames wanted read from the blob by its row id. */
static int read_frame_part(storage_t *st, sqldb_stmt_t *q, storage_frame_t *out, err_t *err)
{
    size_t m2 = (size_t)out->sub_px * (size_t)out->sub_px;
    size_t n = (size_t)out->raw_count * m2, off = (size_t)out->raw_first * m2 * 2;
    int bad_mean = 0;
    out->stage_x_um = stg_col_double(q, 0);
    out->stage_y_um = stg_col_double(q, 1);
    out->stage_z_um = stg_col_double(q, 2);
    out->exposure_us = stg_col_double(q, 3);
    out->captured_ms = stg_col_id(q, 4);
    out->mean = stg_f64_from_blob(sqldb_col_blob(q, 5), (size_t)sqldb_col_bytes(q, 5), m2,
                                  &bad_mean);
    int64_t rowid = sqldb_col_int64(q, 6), raw_bytes = sqldb_col_int64(q, 7);
    if (bad_mean || raw_bytes != (int64_t)((size_t)out->frames * m2 * 2))
        return err_set(err, -EIO, "scan %lld point %d: stored frame size does not match the scan",
                       (long long)out->scan_id, out->point_index);
    unsigned char *bytes = malloc(n ? n * 2 : 1);
    out->raw = malloc(n ? n * sizeof *out->raw : 1);
    if (!out->mean || !out->raw || !bytes) {
        free(bytes);
        return err_set(err, -ENOMEM, "frame get: out of memory");
    }
    int rc = n ? sqldb_blob_read(st->db, "frames", "raw", rowid, off, n * 2, bytes) : SQLDB_OK;
    for (size_t i = 0; rc == SQLDB_OK && i < n; i++)
        out->raw[i] = le_get_u16(bytes + 2 * i);
    free(bytes);
    return rc == SQLDB_OK ? 0 : stg_error(st, rc, err, "reading a frame's raw frames");
}

int storage_frame_get(storage_t *st, int64_t scan_id, int point_index, storage_frame_t *out,
                      err_t *err)
{
    sqldb_stmt_t *q;
    storage_scan_t sc;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "frame get: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_scan_load(st, scan_id, &sc, err))) goto out;
    out->scan_id = scan_id;
    out->point_index = point_index;
    out->frames = sc.frames;
    out->sub_px = sc.sub_px;
    storage_scan_free(&sc);
    if ((ret = stg_stmt(st, STG_FRAME_GET, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    stg_bind_int(q, 2, point_index, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a frame")
                          : stg_error(st, rc, err, "reading a frame");
    if (ret == -ENOENT)
        err_set(err, ret, "scan %lld has no point %d", (long long)scan_id, point_index);
    if (ret == 0) ret = read_frame(q, out, err);
    stg_reset(q);
    if (ret == 0) ret = read_times(st, out, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_frame_free(out);
    }
    return ret;
}

int storage_frame_get_part(storage_t *st, int64_t scan_id, int point_index, int first, int count,
                           storage_frame_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    storage_scan_t sc;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "frame get: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_scan_load(st, scan_id, &sc, err))) goto out;
    out->scan_id = scan_id;
    out->point_index = point_index;
    out->frames = sc.frames;
    out->sub_px = sc.sub_px;
    storage_scan_free(&sc);
    if (first < 0 || count < 0 || first > out->frames || count > out->frames - first) {
        ret = err_set(err, -ERANGE, "raw frames %d..%d: scan %lld has frames 0..%d", first,
                      first + count - 1, (long long)scan_id, out->frames - 1);
        goto out;
    }
    out->raw_first = first;
    out->raw_count = count;
    if ((ret = stg_stmt(st, STG_FRAME_HEAD, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    stg_bind_int(q, 2, point_index, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "reading a frame")
                          : stg_error(st, rc, err, "reading a frame");
    if (ret == -ENOENT)
        err_set(err, ret, "scan %lld has no point %d", (long long)scan_id, point_index);
    if (ret == 0) ret = read_frame_part(st, q, out, err);
    stg_reset(q);
    if (ret == 0) ret = read_times(st, out, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_frame_free(out);
    }
    return ret;
}

int storage_frame_last(storage_t *st, int64_t scan_id, int *last, int *count, err_t *err)
{
    sqldb_stmt_t *q;
    storage_scan_t sc;
    int ret, rc = SQLDB_OK;
    if (!st || !last || !count) return err_set(err, -EINVAL, "frame last: NULL argument");
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_scan_load(st, scan_id, &sc, err))) goto out;
    storage_scan_free(&sc);
    if ((ret = stg_stmt(st, STG_FRAME_LAST, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    ret = rc == SQLDB_OK ? stg_row(st, q, err, "finding the last point")
                          : stg_error(st, rc, err, "finding the last point");
    if (ret == 0) {
        *last = sqldb_col_int(q, 0);
        *count = sqldb_col_int(q, 1);
    }
    stg_reset(q);
out:
    if (ret == 0) return stg_commit(st, err);
    stg_rollback(st);
    return ret;
}

static int raster_alloc(storage_raster_t *r, size_t cap)
{
    int *pi = realloc(r->point_index, cap * sizeof *pi);
    if (pi) r->point_index = pi;
    double **arrays[] = {&r->stage_x_um, &r->stage_y_um, &r->exposure_us, &r->mean_dn};
    int ok = pi != NULL;
    for (size_t a = 0; a < sizeof arrays / sizeof arrays[0]; a++) {
        double *grown = realloc(*arrays[a], cap * sizeof **arrays[a]);
        if (grown) *arrays[a] = grown;
        ok = ok && grown;
    }
    return ok ? 0 : -ENOMEM;
}

/* Reads the rows of STG_FRAME_RASTER (bound) into *out and resets q. */
static int raster_rows(storage_t *st, sqldb_stmt_t *q, storage_raster_t *out, err_t *err)
{
    size_t cap = 0;
    int rc, ret = 0;
    while ((rc = sqldb_step(q)) == SQLDB_ROW) {
        if (out->n == cap && raster_alloc(out, cap = cap ? 2 * cap : 256)) {
            ret = err_set(err, -ENOMEM, "raster: out of memory");
            break;
        }
        if (sqldb_col_bytes(q, 4) != 8) {
            ret = err_set(err, -EIO, "raster: point %d has a mean frame of the wrong size",
                          sqldb_col_int(q, 0));
            break;
        }
        out->point_index[out->n] = sqldb_col_int(q, 0);
        out->stage_x_um[out->n] = stg_col_double(q, 1);
        out->stage_y_um[out->n] = stg_col_double(q, 2);
        out->exposure_us[out->n] = stg_col_double(q, 3);
        out->mean_dn[out->n] = le_get_f64(sqldb_col_blob(q, 4));
        out->n++;
    }
    if (ret == 0 && rc != SQLDB_DONE) ret = stg_error(st, rc, err, "reading the raster");
    stg_reset(q);
    return ret;
}

int storage_frame_raster(storage_t *st, int64_t scan_id, int dcol, int drow,
                         storage_raster_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    storage_scan_t sc;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "raster: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_scan_load(st, scan_id, &sc, err))) goto out;
    int h = (sc.sub_px - 1) / 2, m = sc.sub_px;
    storage_scan_free(&sc);
    if (dcol < -h || dcol > h || drow < -h || drow > h) {
        ret = err_set(err, -EINVAL, "raster pixel: (%d, %d) is outside the %d x %d sub-frame "
                      "(offsets -%d..%d)", dcol, drow, m, m, h, h);
        goto out;
    }
    /* byte offset (1-based, for substr) of sub-frame pixel (dcol + h, drow + h), row-major */
    int64_t offset = ((int64_t)(drow + h) * m + (dcol + h)) * 8 + 1;
    if ((ret = stg_stmt(st, STG_FRAME_RASTER, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    stg_bind_int(q, 2, offset, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "reading the raster");
        goto out;
    }
    ret = raster_rows(st, q, out, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_raster_free(out);
    }
    return ret;
}

void storage_means_free(storage_means_t *m)
{
    if (!m) return;
    free(m->point_index);
    free(m->stage_x_um);
    free(m->stage_y_um);
    free(m->mean_dn);
    memset(m, 0, sizeof *m);
}

/* Room for cap points of mm means each in *m. */
static int means_alloc(storage_means_t *m, size_t cap, size_t mm)
{
    int *pi = realloc(m->point_index, cap * sizeof *pi);
    if (pi) m->point_index = pi;
    double *x = realloc(m->stage_x_um, cap * sizeof *x);
    if (x) m->stage_x_um = x;
    double *y = realloc(m->stage_y_um, cap * sizeof *y);
    if (y) m->stage_y_um = y;
    double *dn = realloc(m->mean_dn, cap * mm * sizeof *dn);
    if (dn) m->mean_dn = dn;
    return pi && x && y && dn ? 0 : -ENOMEM;
}

/* Reads the rows of STG_FRAME_MEANS (bound) into *out (frames of mm means) and resets q. */
static int means_rows(storage_t *st, sqldb_stmt_t *q, storage_means_t *out, size_t mm, err_t *err)
{
    size_t cap = 0;
    int rc, ret = 0;
    while ((rc = sqldb_step(q)) == SQLDB_ROW) {
        if (out->n == cap && means_alloc(out, cap = cap ? 2 * cap : 256, mm)) {
            ret = err_set(err, -ENOMEM, "means: out of memory");
            break;
        }
        if ((size_t)sqldb_col_bytes(q, 3) != mm * 8) {
            ret = err_set(err, -EIO, "means: point %d has a mean frame of the wrong size",
                          sqldb_col_int(q, 0));
            break;
        }
        const unsigned char *b = sqldb_col_blob(q, 3);
        out->point_index[out->n] = sqldb_col_int(q, 0);
        out->stage_x_um[out->n] = stg_col_double(q, 1);
        out->stage_y_um[out->n] = stg_col_double(q, 2);
        for (size_t i = 0; i < mm; i++)
            out->mean_dn[out->n * mm + i] = le_get_f64(b + 8 * i);
        out->n++;
    }
    if (ret == 0 && rc != SQLDB_DONE) ret = stg_error(st, rc, err, "reading the means");
    stg_reset(q);
    return ret;
}

int storage_frame_means(storage_t *st, int64_t scan_id, storage_means_t *out, err_t *err)
{
    sqldb_stmt_t *q;
    storage_scan_t sc;
    int ret, rc = SQLDB_OK;
    if (!st || !out) return err_set(err, -EINVAL, "means: NULL argument");
    memset(out, 0, sizeof *out);
    if ((ret = stg_begin_read(st, err))) return ret;
    if ((ret = stg_scan_load(st, scan_id, &sc, err))) goto out;
    out->sub_px = sc.sub_px;
    storage_scan_free(&sc);
    if ((ret = stg_stmt(st, STG_FRAME_MEANS, &q, err))) goto out;
    stg_bind_int(q, 1, scan_id, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        ret = stg_error(st, rc, err, "reading the means");
        goto out;
    }
    ret = means_rows(st, q, out, (size_t)out->sub_px * out->sub_px, err);
out:
    if (ret == 0) ret = stg_commit(st, err);
    if (ret) {
        stg_rollback(st);
        storage_means_free(out);
    }
    return ret;
}
