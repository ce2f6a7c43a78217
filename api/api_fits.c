/* api_fits.c: fits: request a fit of any pixel of a finished scan, or of an uploaded scan file
 * (data measured on other benches, optionally stored as the calibration of a sensor pixel), both
 * answered 202 with the queued job; get a fit with its whole result (the `ips fit` document).
 * A fit's map becomes the calibration only when asked ("promote"; see api_promote.c). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"

#define FIT_OPTION_KEYS                                                                            \
    "r_min", "r_max", "sigma", "ftest", "ftest_r", "wiener", "method", "nonneg", "region",       \
        "margin_um", "fit_geometry", "geometry_r", "gain_e_per_dn", "read_noise_e", "map", \
        "krige", "geometry_model"

#define FIT_PROMOTE_KEYS "promote", "by", "reason"

/* "promote" (def when absent), "by" and "reason": whether the fit's map becomes the pixel's
 * calibration, and its provenance (docs/api.md); -1 after replying. */
static int read_promote(api_req_t *q, json_t *o, int def, srv_fit_params_t *p)
{
    const char *by = NULL, *reason = NULL;
    p->promote = def;
    if (api_get_bool(q, o, "promote", "promote", &p->promote) ||
        api_get_str(q, o, "by", "by", 0, SRV_BY_MAX, &by) ||
        api_get_str(q, o, "reason", "reason", 0, SRV_REASON_MAX, &reason))
        return -1;
    if (by) snprintf(p->by, sizeof p->by, "%s", by);
    if (reason) snprintf(p->reason, sizeof p->reason, "%s", reason);
    return 0;
}

/* region (inside, all, margin) and margin_um (margin only) into p; -1 after replying. */
static int read_region(api_req_t *q, json_t *o, srv_fit_params_t *p)
{
    const char *region = NULL;
    double margin = NAN;
    if (api_get_str(q, o, "region", "region", 0, 16, &region) ||
        api_get_num(q, o, "margin_um", "margin_um", 0, 0, FIT_REGION_MARGIN_MAX, 0, &margin))
        return -1;
    int is_margin = region && strcmp(region, "margin") == 0;
    if (is_margin && !isfinite(margin)) {
        api_error(q, 422, "out_of_range", "margin_um",
                  "region margin needs margin_um, the distance in um from the pixel");
        return -1;
    }
    if (!is_margin && isfinite(margin)) {
        api_error(q, 422, "out_of_range", "margin_um", "margin_um goes with region \"margin\"");
        return -1;
    }
    err_t err = {{0}};
    if (region && fit_region_parse(region, margin, &p->region, &err)) {
        api_error(q, 422, "out_of_range", "region", "%s", err.msg);
        return -1;
    }
    return 0;
}

/* Reads the fit options shared by both requests into p; -1 after replying. */
static int read_options(api_req_t *q, json_t *o, srv_fit_params_t *p)
{
    long long r_min = p->r_min, r_max = p->r_max, ftest_r = p->ftest_r, geometry_r = 0;
    const char *sigma = NULL, *method = NULL, *map = NULL, *gmodel = NULL;
    json_t *ftest = json_object_get(o, "ftest");
    if (api_get_int(q, o, "r_min", "r_min", 0, 1, 32, &r_min) ||
        api_get_int(q, o, "r_max", "r_max", 0, 1, 32, &r_max) ||
        api_get_str(q, o, "sigma", "sigma", 0, 16, &sigma) ||
        api_get_int(q, o, "ftest_r", "ftest_r", 0, 1, 32, &ftest_r) ||
        api_get_bool(q, o, "wiener", "wiener", &p->wiener) ||
        api_get_str(q, o, "method", "method", 0, 16, &method) ||
        api_get_bool(q, o, "nonneg", "nonneg", &p->opts.nonneg) || read_region(q, o, p) ||
        api_get_bool(q, o, "fit_geometry", "fit_geometry", &p->fit_geometry) ||
        api_get_bool(q, o, "krige", "krige", &p->krige) ||
        api_get_int(q, o, "geometry_r", "geometry_r", 0, 1, 32, &geometry_r) ||
        /* sigma's constants (eq. 5), overriding the sensor's photon transfer and the scan's */
        api_get_num(q, o, "gain_e_per_dn", "gain_e_per_dn", 0, 0, 1e6, 1, &p->gain_e_per_dn) ||
        api_get_num(q, o, "read_noise_e", "read_noise_e", 0, 0, 1e6, 0, &p->read_noise_e) ||
        api_get_str(q, o, "map", "map", 0, 16, &map) ||
        api_get_str(q, o, "geometry_model", "geometry_model", 0, 16, &gmodel))
        return -1;
    if (gmodel && strcmp(gmodel, "kriged") && strcmp(gmodel, "map")) {
        api_error(q, 422, "out_of_range", "geometry_model",
                  "geometry_model must be kriged or map (got '%s')", gmodel);
        return -1;
    }
    if (gmodel && !p->fit_geometry) {
        api_error(q, 422, "invalid", "geometry_model",
                  "geometry_model goes with \"fit_geometry\": true");
        return -1;
    }
    p->geometry_map_only = gmodel && strcmp(gmodel, "map") == 0;
    /* without "map", ipsd's --calibration-map (the kriged map unless told otherwise) */
    int which = map ? storage_map_parse(map) : srv_config(q->srv)->calibration_map;
    if (which < 0) {
        api_error(q, 422, "out_of_range", "map", "map must be " STORAGE_MAP_WORDS " (got '%s')",
                  map);
        return -1;
    }
    p->map = (storage_map_t)which;
    if (p->map == STORAGE_MAP_KRIGED) p->krige = 1; /* the map it stores is the kriged one */
    if (geometry_r && !p->fit_geometry) {
        api_error(q, 422, "invalid", "geometry_r", "geometry_r goes with \"fit_geometry\": true");
        return -1;
    }
    p->geometry_r = (int)geometry_r;
    /* ipsd's cap on r (--max-fit-r): with the points' cap it bounds a fit's memory */
    long long cap = srv_config(q->srv)->max_fit_r;
    int has_ftest = ftest && !json_is_null(ftest);
    const char *over = r_max > cap                 ? "r_max"
                       : ftest_r > cap && has_ftest ? "ftest_r"
                       : geometry_r > cap           ? "geometry_r"
                                                    : NULL;
    if (over) {
        api_error(q, 422, "out_of_range", over,
                  "%s is more than ipsd's limit of %lld (--max-fit-r)", over, cap);
        return -1;
    }
    if (r_min > r_max) {
        api_error(q, 422, "out_of_range", "r_min", "r_min (%lld) must not exceed r_max (%lld)",
                  r_min, r_max);
        return -1;
    }
    if (sigma && fit_noise_parse(sigma, &p->opts.noise)) {
        api_error(q, 422, "out_of_range", "sigma", "sigma must be paper or shot+read (got '%s')",
                  sigma);
        return -1;
    }
    static const char *const methods[] = {"linear", "lm", "both"};
    int m = method ? -1 : (int)p->opts.method;
    for (int i = 0; method && i < 3; i++)
        if (strcmp(method, methods[i]) == 0) m = i;
    if (m < 0) {
        api_error(q, 422, "out_of_range", "method", "method must be linear, lm or both (got '%s')",
                  method);
        return -1;
    }
    p->opts.method = (fit_method_t)m;
    if (ftest && !json_is_null(ftest)) {
        err_t err = {{0}};
        if (!json_is_string(ftest)) {
            api_error(q, 400, "bad_type", "ftest",
                      "ftest must be a string like \"top,left,bottom\""
                      " or null");
            return -1;
        }
        if (fit_edges_parse(json_string_value(ftest), &p->ftest_edges, &err) || !p->ftest_edges) {
            api_error(q, 422, "out_of_range", "ftest", "ftest: %s",
                      err.msg[0] ? err.msg : "name at least one of top, left, bottom, right");
            return -1;
        }
    }
    p->r_min = (int)r_min;
    p->r_max = (int)r_max;
    p->ftest_r = (int)ftest_r;
    return 0;
}

/* {"job": ...} of a queued job, 202. */
static void reply_job(api_req_t *q, storage_t *st, int64_t job_id)
{
    storage_job_t j;
    err_t err = {{0}};
    int ret = storage_job_get(st, job_id, &j, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    api_reply_json(q, 202, json_pack("{s:o}", "job", api_enc_job(&j)));
    char loc[64];
    snprintf(loc, sizeof loc, "/api/jobs/%lld", (long long)job_id);
    if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_LOCATION, loc);
    storage_job_free(&j);
}

static void submit(api_req_t *q, storage_t *st, srv_fit_params_t *p)
{
    int64_t job_id;
    err_t err = {{0}};
    int ret = srv_fit_submit(q->srv, st, p, &job_id, &err);
    if (ret)
        api_error_rc(q, ret, NULL, err.msg);
    else
        reply_job(q, st, job_id);
}

/* "pixels": "all" (every pixel the scan's raster covers, server/srv_fitall.c) instead of
 * dcol / drow; -1 after replying. */
static int read_pixels(api_req_t *q, json_t *o, srv_fit_params_t *p)
{
    const char *pixels = NULL;
    if (api_get_str(q, o, "pixels", "pixels", 0, 16, &pixels)) return -1;
    if (!pixels) return 0;
    if (strcmp(pixels, "all") != 0) {
        api_error(q, 422, "out_of_range", "pixels",
                  "pixels must be \"all\" (every pixel the raster covers; got '%s')", pixels);
        return -1;
    }
    const char *with = json_object_get(o, "dcol")   ? "dcol"
                       : json_object_get(o, "drow") ? "drow"
                                                    : NULL;
    if (with) {
        api_error(q, 422, "invalid", with, "%s names one pixel: it does not go with \"pixels\"",
                  with);
        return -1;
    }
    p->all_pixels = 1;
    return 0;
}

void api_h_scan_fit_create(api_req_t *q)
{
    static const char *const keys[] = {"dcol",          "drow",           "pixels",
                                       FIT_OPTION_KEYS, FIT_PROMOTE_KEYS, NULL};
    srv_fit_params_t p = srv_fit_params_default();
    storage_scan_t sc;
    storage_t *st;
    int64_t id;
    long long dcol = 0, drow = 0;
    err_t err = {{0}};
    json_t *o = api_body_object(q);
    if (!o || api_arg_id(q, 0, "scan", &id) || !(st = api_db(q))) goto out;
    int ret = storage_scan_get(st, id, &sc, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        goto out;
    }
    int h = sc.sub_px / 2;
    if (api_no_unknown(q, o, "", keys) == 0 &&
        api_get_int(q, o, "dcol", "dcol", 0, -h, h, &dcol) == 0 &&
        api_get_int(q, o, "drow", "drow", 0, -h, h, &drow) == 0 && read_pixels(q, o, &p) == 0 &&
        read_options(q, o, &p) == 0 && read_promote(q, o, 0, &p) == 0) {
        if (sc.state != STORAGE_DONE) {
            api_error(q, 409, "conflict", NULL, "scan %lld is %s: only a done scan can be fitted",
                      (long long)id, storage_state_name(sc.state));
        } else {
            p.scan_id = id;
            p.dcol = (int)dcol;
            p.drow = (int)drow;
            submit(q, st, &p);
        }
    }
    storage_scan_free(&sc);
out:
    json_decref(o);
}

/* The uploaded scan file, checked as `ips fit` reads it: its pitch into *pitch; -1 after
 * replying. */
static int read_upload(api_req_t *q, json_t *o, double *pitch)
{
    json_t *scan;
    const char *field = NULL;
    size_t n = 0;
    err_t err = {{0}};
    if (api_get_obj(q, o, "scan", "scan", &scan)) return -1;
    if (!scan) {
        api_error(q, 422, "missing", "scan", "scan (a scan file object) or scan_fits (a FITS scan cube) is required");
        return -1;
    }
    int ret = srv_upload_check(scan, pitch, &n, &field, &err);
    if (ret == 0 && n == 0) ret = err_set(&err, -EINVAL, "the scan has no points");
    int cap = srv_config(q->srv)->max_fit_points;
    if (ret == 0 && n > (size_t)cap) { /* the points' cap (--max-fit-points): bounds its memory */
        api_error(q, 413, "payload_too_large", "scan.x_um",
                  "scan: %zu points is more than ipsd's limit of %d (--max-fit-points)", n, cap);
        return -1;
    }
    char path[64];
    snprintf(path, sizeof path, "scan.%s", field ? field : "x_um");
    if (ret) api_error(q, ret == -ENOMEM ? 500 : 422, "invalid", path, "scan: %s", err.msg);
    return ret ? -1 : 0;
}

/* The optional calibration target of an upload: sensor_id, pixel {col, row}, optics. */
static int read_target(api_req_t *q, json_t *o, storage_t *st, double pitch, srv_fit_params_t *p)
{
    static const char *const pixel_keys[] = {"col", "row", NULL};
    static const char *const optics_keys[] = {"wavelength_nm", "na", NULL};
    long long sensor_id = 0, col = 0, row = 0;
    double nm = NAN, na = NAN;
    json_t *pixel, *optics;
    storage_sensor_t sn;
    if (api_get_int(q, o, "sensor_id", "sensor_id", 0, 1, INT64_MAX, &sensor_id) ||
        api_get_obj(q, o, "pixel", "pixel", &pixel) ||
        api_get_obj(q, o, "optics", "optics", &optics) ||
        (optics &&
         (api_no_unknown(q, optics, "optics.", optics_keys) ||
          api_get_num(q, optics, "wavelength_nm", "optics.wavelength_nm", 0, 0, 1e5, 1, &nm) ||
          api_get_num(q, optics, "na", "optics.na", 0, 0, 1.7, 1, &na))))
        return -1;
    if (!sensor_id != !pixel) {
        api_error(q, 422, "missing", sensor_id ? "pixel" : "sensor_id",
                  "sensor_id and pixel {col, row} go together (the calibration's target)");
        return -1;
    }
    p->wavelength_um = nm * 1e-3;
    p->na = na;
    if (!sensor_id) return 0;
    if (api_no_unknown(q, pixel, "pixel.", pixel_keys) ||
        api_get_int(q, pixel, "col", "pixel.col", 1, 0, 1000000, &col) ||
        api_get_int(q, pixel, "row", "pixel.row", 1, 0, 1000000, &row))
        return -1;
    err_t err = {{0}};
    int ret = storage_sensor_get(st, sensor_id, &sn, &err);
    if (ret) {
        api_error_rc(q, ret == -ENOENT ? -EINVAL : ret, "sensor_id", err.msg);
        return -1;
    }
    const char *f = col >= sn.n_cols ? "pixel.col" : row >= sn.n_rows ? "pixel.row" : NULL;
    if (f)
        api_error(q, 422, "out_of_range", f, "pixel (%lld, %lld) is outside the %d x %d sensor",
                  col, row, sn.n_cols, sn.n_rows);
    else if (pitch != sn.pitch_um)
        api_error(q, 422, "invalid", "scan.pitch_um",
                  "scan.pitch_um (%g) is not the sensor's "
                  "pitch (%g)",
                  pitch, sn.pitch_um);
    storage_sensor_free(&sn);
    if (q->resp) return -1;
    p->sensor_id = sensor_id;
    p->pixel_col = (int)col;
    p->pixel_row = (int)row;
    return 0;
}

void api_h_fit_upload(api_req_t *q)
{
    static const char *const keys[] = {"scan",          "scan_fits",      "sensor_id", "pixel",
                                       "optics",        FIT_OPTION_KEYS, FIT_PROMOTE_KEYS, NULL};
    srv_fit_params_t p = srv_fit_params_default();
    storage_t *st;
    double pitch = 0;
    json_t *o = api_body_object(q);
    if (o && api_no_unknown(q, o, "", keys) == 0 && api_fits_cube_scan(q, o) == 0 &&
        read_options(q, o, &p) == 0 &&
        read_upload(q, o, &pitch) == 0 && (st = api_db(q)) &&
        read_target(q, o, st, pitch, &p) == 0 && read_promote(q, o, p.sensor_id > 0, &p) == 0) {
        if (p.promote && !p.sensor_id) {
            api_error(q, 422, "missing", "sensor_id",
                      "promote needs sensor_id and pixel {col, row} (the calibration's target)");
            goto out;
        }
        p.scan_file = json_incref(json_object_get(o, "scan"));
        submit(q, st, &p);
    }
out:
    srv_fit_params_free(&p);
    json_decref(o);
}

void api_h_fit_get(api_req_t *q)
{
    storage_t *st;
    storage_fit_t f;
    int64_t id;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "fit", &id) || !(st = api_db(q))) return;
    int ret = storage_fit_get(st, id, &f, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    api_reply_json(q, 200, api_enc_fit(&f, 1));
    storage_fit_free(&f);
}
