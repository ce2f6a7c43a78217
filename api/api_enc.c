/* api_enc.c: the JSON form of the stored things (sensors, scans, jobs, fits, calibrations; schemas
 * in docs/api.md and openapi.json) and the CSV form of calibrations. Times are milliseconds since
 * the epoch (null: not yet); unknown numbers are null. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"

json_t *api_num(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}
json_t *api_time(int64_t ms)
{
    return ms ? json_integer(ms) : json_null();
}
static json_t *id_or_null(int64_t id)
{
    return id ? json_integer(id) : json_null();
}
static json_t *str_or_null(const char *s)
{
    return s ? json_string(s) : json_null();
}

static json_t *array(const double *v, size_t n)
{
    json_t *a = json_array();
    for (size_t i = 0; a && v && i < n; i++)
        json_array_append_new(a, api_num(v[i]));
    return a;
}

json_t *api_enc_sensor(const storage_sensor_t *s)
{
    return json_pack("{s:I, s:s, s:s, s:i, s:i, s:f, s:f, s:f, s:f, s:f, s:o}", "id",
                     (json_int_t)s->id, "model", s->model, "serial", s->serial, "n_cols", s->n_cols,
                     "n_rows", s->n_rows, "pitch_um", s->pitch_um, "gain_e_per_dn",
                     s->gain_e_per_dn, "read_noise_e", s->read_noise_e, "bias_dn", s->bias_dn,
                     "full_scale_dn", s->full_scale_dn, "created_ms", api_time(s->created_ms));
}

json_t *api_enc_scan(const storage_scan_t *sc)
{
    int nx = (int)lround(sqrt((double)sc->points_total));
    return json_pack(
        "{s:I, s:I, s:{s:i, s:i}, s:{s:f, s:f, s:f}, s:{s:i, s:f, s:i, s:i, s:i, s:i}, s:f, "
        "s:s, s:i, s:f, s:o, s:o, s:o, s:o}",
        "id", (json_int_t)sc->id, "sensor_id", (json_int_t)sc->sensor_id, "poi", "col", sc->poi_col,
        "row", sc->poi_row, "optics", "wavelength_nm", sc->wavelength_um * 1e3, "na", sc->na,
        "spot_radius_um", sc->spot_radius_um, "raster", "area_px", sc->area_px, "step_um",
        sc->step_um, "sub_px", sc->sub_px, "frames", sc->frames, "points_per_axis", nx,
        "points_total", sc->points_total, "exposure_us", sc->exposure_us, "state",
        storage_state_name(sc->state), "points_done", sc->points_done, "progress",
        sc->points_total ? (double)sc->points_done / sc->points_total : 0.0, "error",
        str_or_null(sc->error), "created_ms", api_time(sc->created_ms), "started_ms",
        api_time(sc->started_ms), "finished_ms", api_time(sc->finished_ms));
}

/* The job's params as JSON, an uploaded scan file summarised (it can be megabytes). */
static json_t *job_params(const char *text)
{
    json_t *p = json_loads(text ? text : "{}", 0, NULL), *scan;
    if (!p) return json_null();
    if ((scan = json_object_get(p, "scan")) && json_is_object(scan)) {
        json_t *x = json_object_get(scan, "x_um");
        json_object_set_new(p, "scan",
                            json_pack("{s:s, s:I}", "source", "upload", "n_points",
                                      (json_int_t)json_array_size(x)));
    }
    return p;
}

json_t *api_enc_job(const storage_job_t *j)
{
    json_t *o = json_pack("{s:I, s:s, s:s, s:f, s:i, s:o, s:i, s:o, s:o, s:o, s:o, s:o, s:o, s:o}", "id",
                     (json_int_t)j->id, "kind", storage_job_kind_name(j->kind), "state",
                     storage_state_name(j->state), "progress", j->progress, "points_done",
                     j->points_done, "error", str_or_null(j->error), "attempts", j->attempts,
                     "heartbeat_ms", api_time(j->heartbeat_ms), "created_ms",
                     api_time(j->created_ms), "started_ms", api_time(j->started_ms), "finished_ms",
                     api_time(j->finished_ms), "scan_id", id_or_null(j->scan_id), "fit_id",
                     id_or_null(j->fit_id), "params", job_params(j->params));
    /* a job of every pixel: the fits it stored, in order (storage reads them from the fits'
     * job_id), beside the request */
    if (o && j->fit_ids) {
        json_t *ids = json_loads(j->fit_ids, 0, NULL);
        json_object_set_new(o, "fit_ids", json_is_array(ids) ? ids : json_array());
        if (!json_is_array(ids)) json_decref(ids);
    }
    if (o) {
        json_object_set_new(o, "bench", str_or_null(j->bench));
        json_object_set_new(o, "claimed_by", str_or_null(j->claimed_by));
    }
    return o;
}

json_t *api_enc_fit(const storage_fit_t *f, int with_result)
{
    json_t *result = with_result && f->result ? json_loads(f->result, JSON_DECODE_ANY, NULL) : NULL;
    json_t *o =
        json_pack("{s:I, s:o, s:i, s:i, s:s, s:{s:o, s:o}, s:o, s:o, s:o}", "id", (json_int_t)f->id,
                  "scan_id", id_or_null(f->scan_id), "dcol", f->dcol, "drow", f->drow,
                  "noise_model", f->noise_model, "best_r", "aic", id_or_null(f->best_r_aic), "bic",
                  id_or_null(f->best_r_bic), "f_value", api_num(f->f_value), "p_value",
                  api_num(f->p_value), "created_ms", api_time(f->created_ms));
    /* the map the fit offers as its pixel's calibration, and whether it is that calibration */
    json_t *cal = json_null();
    if (f->map_sensor_id)
        cal =
            json_pack("{s:I, s:{s:i, s:i}, s:i, s:b, s:o}", "sensor_id",
                      (json_int_t)f->map_sensor_id, "pixel", "col", f->map_col, "row", f->map_row,
                      "r", f->map_r, "current", f->pixel_calib_id && f->pixel_calib_fit_id == f->id,
                      "current_calibration_id", id_or_null(f->pixel_calib_id));
    if (f->map_sensor_id && cal)
        json_object_set_new(cal, "map", json_string(storage_map_name((storage_map_t)f->map_kind)));
    if (o)
        json_object_set_new(o, "calibration", cal);
    else
        json_decref(cal);
    if (o && with_result)
        json_object_set_new(o, "result", result ? result : json_null());
    else
        json_decref(result);
    return o;
}

json_t *api_enc_calib(const storage_calib_t *c)
{
    size_t n = (size_t)c->r * c->r;
    return json_pack(
        "{s:I, s:I, s:{s:i, s:i}, s:i, s:o, s:o, s:o, s:o, s:s, s:o, s:o, s:s, "
        "s:{s:o, s:o, s:o}, s:s, s:o, s:o, s:b, s:o, s:o, s:o, s:s, s:o, s:o}",
        "id", (json_int_t)c->id, "sensor_id", (json_int_t)c->sensor_id, "pixel", "col",
        c->pixel_col, "row", c->pixel_row, "r", c->r, "S", array(c->S, n), "S_err",
        array(c->S_err, n), "I0", api_num(c->I0), "chi2_red", api_num(c->chi2_red), "status",
        c->status, "scan_id", id_or_null(c->scan_id), "fit_id", id_or_null(c->fit_id),
        "noise_model", c->noise_model, "optics", "wavelength_nm", api_num(c->wavelength_um * 1e3),
        "na", api_num(c->na), "spot_radius_um", api_num(c->spot_radius_um), "software_version",
        c->software_version ? c->software_version : "", "created_ms", api_time(c->created_ms),
        "superseded_by", id_or_null(c->superseded_by), "current", !c->superseded_by, "supersedes",
        id_or_null(c->supersedes), "by", str_or_null(c->by), "reason", str_or_null(c->reason),
        "map", storage_map_name(c->map), "S_res",
        c->S_res ? array(c->S_res, n) : json_null(), "map_note", str_or_null(c->map_note));
}

json_t *api_enc_page(json_t *items, int64_t total, long long limit, long long offset)
{
    return json_pack("{s:o, s:I, s:I, s:I}", "items", items, "total", (json_int_t)total, "limit",
                     (json_int_t)limit, "offset", (json_int_t)offset);
}

/* Appends printf output to a growing buffer; returns -1 when out of memory. */
static int put(char **buf, size_t *len, size_t *cap, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static int put(char **buf, size_t *len, size_t *cap, const char *fmt, ...)
{
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = vsnprintf(*buf + *len, *cap - *len, fmt, ap);
        va_end(ap);
        if (n < 0) return -1;
        if ((size_t)n < *cap - *len) {
            *len += (size_t)n;
            return 0;
        }
        size_t cap2 = 2 * *cap + (size_t)n;
        char *b = realloc(*buf, cap2);
        if (!b) return -1;
        *buf = b;
        *cap = cap2;
    }
}

#define CSV_HEADER                                                                                 \
    "calibration_id,sensor_id,pixel_col,pixel_row,r,i,j,S,S_err,status,current,created_ms,S_res\n"

char *api_csv_calibs(const storage_calib_t *c, size_t n, size_t *len)
{
    size_t cap = 4096;
    char *buf = malloc(cap);
    *len = 0;
    if (!buf || put(&buf, len, &cap, CSV_HEADER)) goto oom;
    for (size_t k = 0; k < n; k++)
        for (int j = 0; j < c[k].r; j++)
            for (int i = 0; i < c[k].r; i++)
                if (put(&buf, len, &cap, "%lld,%lld,%d,%d,%d,%d,%d,%.17g,%.17g,%s,%d,%lld,",
                        (long long)c[k].id, (long long)c[k].sensor_id, c[k].pixel_col,
                        c[k].pixel_row, c[k].r, i, j, c[k].S[j * c[k].r + i],
                        c[k].S_err[j * c[k].r + i], c[k].status, !c[k].superseded_by,
                        (long long)c[k].created_ms) ||
                    /* S_res last (an addition): empty when not known */
                    (c[k].S_res ? put(&buf, len, &cap, "%.17g\n", c[k].S_res[j * c[k].r + i])
                                : put(&buf, len, &cap, "\n")))
                    goto oom;
    return buf;
oom:
    free(buf);
    return NULL;
}
