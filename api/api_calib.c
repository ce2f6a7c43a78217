/* api_calib.c: the lab's calibration database: the current IPS map of a sensor pixel, its history,
 * one calibration by id, and a search across sensors; each as JSON or CSV (?format=csv or
 * Accept: text/csv; one CSV line per sub-pixel, docs/api.md). */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "api_calib_cache.h"
#include "api_int.h"

/* Replies with calibrations c[0..n) as CSV, or as JSON: one object (single) or a page. */
static void reply_calibs(api_req_t *q, int csv, const storage_calib_t *c, size_t n, int single,
                         int64_t total, long long limit, long long offset)
{
    if (csv) {
        size_t len = 0;
        char *text = api_csv_calibs(c, n, &len);
        if (text)
            api_reply_text(q, 200, "text/csv; charset=utf-8", text, len);
        else
            api_error(q, 500, "internal", NULL, "out of memory");
        return;
    }
    if (single) {
        api_reply_json(q, 200, api_enc_calib(c));
        return;
    }
    json_t *items = json_array();
    for (size_t i = 0; items && i < n; i++)
        json_array_append_new(items, api_enc_calib(&c[i]));
    api_reply_json(q, 200, api_enc_page(items, total, limit, offset));
}

/* Why a pixel has no calibration: the sensor or the pixel does not exist, or it has none. */
static void pixel_not_found(api_req_t *q, storage_t *st, int64_t sensor, int64_t col, int64_t row)
{
    storage_sensor_t sn;
    err_t err = {{0}};
    int ret = storage_sensor_get(st, sensor, &sn, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    if (col < 0 || row < 0 || col >= sn.n_cols || row >= sn.n_rows)
        api_error(q, 404, "not_found", col < 0 || col >= sn.n_cols ? "col" : "row",
                  "pixel (%lld, %lld) is outside sensor %lld (%d x %d)", (long long)col,
                  (long long)row, (long long)sensor, sn.n_cols, sn.n_rows);
    else
        api_error(q, 404, "not_found", NULL,
                  "pixel (%lld, %lld) of sensor %lld has no "
                  "calibration",
                  (long long)col, (long long)row, (long long)sensor);
    storage_sensor_free(&sn);
}

/* The arguments of the sensor-pixel routes (/api/sensors/{id}/pixels/{col}/{row}/...): 1 after
 * replying with an error, -ENOENT for a pixel no int can name (no calibration), else 0. */
static int pixel_args(api_req_t *q, storage_t **st, int *csv, int64_t *sensor, int64_t *col,
                      int64_t *row)
{
    *csv = api_wants_csv(q);
    if (*csv < 0 || api_arg_id(q, 0, "sensor", sensor) || !(*st = api_db(q))) return 1;
    *col = q->arg[1];
    *row = q->arg[2];
    return *col < 0 || *row < 0 || *col > INT32_MAX || *row > INT32_MAX ? -ENOENT : 0;
}

void api_h_pixel_calib(api_req_t *q)
{
    storage_t *st;
    storage_calib_t c;
    int64_t sensor, col, row;
    err_t err = {{0}};
    int csv, ret = pixel_args(q, &st, &csv, &sensor, &col, &row);
    if (ret > 0) return;
    /* JSON replies come from the cache while no calibration was stored since they were read;
     * the generation is read before the query (api_calib_cache.h) */
    uint64_t gen;
    size_t len;
    char *text;
    int cached = ret == 0 && !csv && storage_calib_generation(st, &gen) == 0;
    if (cached && (text = api_calib_cache_get(q->calib_cache, sensor, col, row, gen, &len))) {
        api_reply_shared(q, 200, "application/json", text, len, api_calib_cache_release);
        return;
    }
    if (ret == 0) ret = storage_calib_current(st, sensor, (int)col, (int)row, &c, &err);
    if (ret == -ENOENT) {
        pixel_not_found(q, st, sensor, col, row);
        return;
    }
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    if (cached && (text = api_json_text(api_enc_calib(&c), &len))) {
        api_calib_cache_put(q->calib_cache, sensor, col, row, gen, text, len);
        api_reply_text(q, 200, "application/json", text, len);
    } else {
        reply_calibs(q, csv, &c, 1, 1, 1, 1, 0);
    }
    storage_calib_free(&c);
}

void api_h_pixel_history(api_req_t *q)
{
    storage_t *st;
    storage_calib_list_t l;
    int64_t sensor, col, row;
    err_t err = {{0}};
    int csv, ret = pixel_args(q, &st, &csv, &sensor, &col, &row);
    if (ret > 0) return;
    if (ret == 0) ret = storage_calib_history(st, sensor, (int)col, (int)row, &l, &err);
    if (ret == 0 && l.n == 0) {
        storage_calib_list_free(&l);
        ret = -ENOENT;
    }
    if (ret == -ENOENT) {
        pixel_not_found(q, st, sensor, col, row);
        return;
    }
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    reply_calibs(q, csv, l.items, l.n, 0, (int64_t)l.n, (long long)l.n, 0);
    storage_calib_list_free(&l);
}

void api_h_calib_get(api_req_t *q)
{
    storage_t *st;
    storage_calib_t c;
    int64_t id;
    err_t err = {{0}};
    int csv = api_wants_csv(q);
    if (csv < 0 || api_arg_id(q, 0, "calibration", &id) || !(st = api_db(q))) return;
    int ret = storage_calib_get(st, id, &c, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    reply_calibs(q, csv, &c, 1, 1, 1, 1, 0);
    storage_calib_free(&c);
}

/* The search filter of the query string; -1 after replying. */
static int read_filter(api_req_t *q, storage_calib_filter_t *f)
{
    long long sensor, since, current, cmin, cmax, rmin, rmax;
    *f = storage_calib_filter_default();
    if (api_query_int(q, "sensor", 0, 0, INT64_MAX, &sensor) ||
        api_query_int(q, "since", 0, 0, INT64_MAX, &since) ||
        api_query_int(q, "current", 0, 0, 1, &current) ||
        api_query_int(q, "col_min", -1, -1, INT32_MAX, &cmin) ||
        api_query_int(q, "col_max", -1, -1, INT32_MAX, &cmax) ||
        api_query_int(q, "row_min", -1, -1, INT32_MAX, &rmin) ||
        api_query_int(q, "row_max", -1, -1, INT32_MAX, &rmax))
        return -1;
    f->sensor_id = sensor;
    f->since_ms = since;
    f->current_only = (int)current;
    f->col_min = (int)cmin;
    f->col_max = (int)cmax;
    f->row_min = (int)rmin;
    f->row_max = (int)rmax;
    f->model = api_query(q, "model");
    f->status = api_query(q, "status");
    return 0;
}

void api_h_calibs_search(api_req_t *q)
{
    storage_t *st;
    storage_calib_filter_t f;
    storage_calib_list_t l;
    long long limit, offset;
    err_t err = {{0}};
    int csv = api_wants_csv(q);
    if (csv < 0 || read_filter(q, &f) || api_query_page(q, &limit, &offset) || !(st = api_db(q)))
        return;
    int ret = storage_calib_search(st, &f, (int)limit, (int)offset, &l, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    reply_calibs(q, csv, l.items, l.n, 0, l.total, limit, offset);
    storage_calib_list_free(&l);
}
