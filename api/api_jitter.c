/* api_jitter.c: POST /api/jitter, jitter photometry over stored calibrations (docs/api.md,
 * "Jitter photometry"): the maps (one calibration, a sensor pixel's aperture of current
 * calibrations, or a map in the body), the PSF (Airy or Gaussian), the star's position and the
 * pointing jitter (an rms drawn into a series, or the series itself, with measured fluxes to
 * correct) go to fit/jitter.h; the reply is json/jitterjson.h's document, the `ips jitter` one.
 * Computed in the HTTP thread: bounded by the limits below (at most 5e6 samples x map cells). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fit/airy.h"
#include "fit/jitter.h"
#include "json/jitterjson.h"

#include "api_int.h"

#define MAX_SAMPLES 100000
#define MAX_APERTURE 3 /* half-width: up to 7 x 7 pixels */
#define MAX_MAP_R 64
/* samples x cells of the aperture's maps: the work of one request, 0.2-1 us each for the Airy PSF
 * (1-4 s at the bound), so that no request holds an HTTP thread for long */
#define MAX_WORK 5e6

/* What the request names, and what it owns. */
struct req {
    fit_jitter_setup_t s;
    fit_jitter_pixel_t px[(2 * MAX_APERTURE + 1) * (2 * MAX_APERTURE + 1)];
    storage_calib_t calibs[(2 * MAX_APERTURE + 1) * (2 * MAX_APERTURE + 1)];
    size_t n_calibs;
    double *map; /* an inline map */
    double *dx, *dy, *measured;
    size_t n;
    double spot_radius_um; /* optics of the reference calibration (default Airy PSF) */
};

static void req_free(struct req *r)
{
    for (size_t k = 0; k < r->n_calibs; k++)
        storage_calib_free(&r->calibs[k]);
    free(r->map);
    free(r->dx);
    free(r->dy);
    free(r->measured);
}

/* A JSON array of numbers of length n (n 0: any length up to max, into *n); -1 after replying. */
static int get_array(api_req_t *q, json_t *a, const char *path, size_t max, size_t *n, double **out)
{
    if (!json_is_array(a)) {
        api_error(q, 400, "bad_type", path, "%s must be an array of numbers", path);
        return -1;
    }
    size_t len = json_array_size(a);
    if (len < 1 || len > max || (*n && len != *n)) {
        if (*n)
            api_error(q, 422, "out_of_range", path, "%s must have %zu numbers (got %zu)", path, *n,
                      len);
        else
            api_error(q, 422, "out_of_range", path, "%s must have 1..%zu numbers (got %zu)", path,
                      max, len);
        return -1;
    }
    double *v = malloc(sizeof(double) * len);
    if (!v) {
        api_error(q, 500, "internal", NULL, "out of memory");
        return -1;
    }
    for (size_t k = 0; k < len; k++) {
        json_t *x = json_array_get(a, k);
        if (!json_is_number(x) || !isfinite(json_number_value(x))) {
            api_error(q, 400, "bad_type", path, "%s[%zu] must be a finite number", path, k);
            free(v);
            return -1;
        }
        v[k] = json_number_value(x);
    }
    *n = len;
    *out = v;
    return 0;
}

/* The maps: "calibration_id", or "sensor_id" + "col" + "row" (+ "aperture"), or "map" +
 * "pitch_um". -1 after replying. */
static int read_maps(api_req_t *q, json_t *o, struct req *r)
{
    long long cid = 0, sid = 0, col = -1, row = -1, ap = 0;
    json_t *map;
    if (api_get_int(q, o, "calibration_id", "calibration_id", 0, 1, INT64_MAX, &cid) ||
        api_get_int(q, o, "sensor_id", "sensor_id", 0, 1, INT64_MAX, &sid) ||
        api_get_int(q, o, "col", "col", 0, 0, INT32_MAX, &col) ||
        api_get_int(q, o, "row", "row", 0, 0, INT32_MAX, &row) ||
        api_get_int(q, o, "aperture", "aperture", 0, 0, MAX_APERTURE, &ap) ||
        api_get_obj(q, o, "map", "map", &map))
        return -1;
    int given = (cid > 0) + (sid > 0) + (map != NULL);
    if (given != 1) {
        api_error(q, 422, "missing", "calibration_id",
                  "name the maps with exactly one of calibration_id, sensor_id (with col and "
                  "row) or map");
        return -1;
    }
    err_t err = {{0}};
    storage_t *st = NULL;
    if (map) {
        long long rr = 0;
        size_t n = 0;
        double pitch = 0;
        if (api_get_int(q, map, "r", "map.r", 1, 1, MAX_MAP_R, &rr) ||
            api_get_num(q, o, "pitch_um", "pitch_um", 1, 0, 1e4, 1, &pitch))
            return -1;
        n = (size_t)(rr * rr);
        json_t *S = json_object_get(map, "S");
        if (!S) {
            api_error(q, 422, "missing", "map.S", "map.S is required");
            return -1;
        }
        if (get_array(q, S, "map.S", n, &n, &r->map)) return -1;
        r->px[0] = (fit_jitter_pixel_t){0, 0, (int)rr, r->map};
        r->s.n_pixels = 1;
        r->s.pitch_um = pitch;
        r->spot_radius_um = NAN;
        return 0;
    }
    if (!(st = api_db(q))) return -1;
    storage_calib_t c;
    int ret;
    if (cid > 0) {
        ret = storage_calib_get(st, cid, &c, &err);
        if (ret) {
            api_error_rc(q, ret, "calibration_id", err.msg);
            return -1;
        }
        sid = c.sensor_id;
        r->calibs[r->n_calibs++] = c;
        r->px[0] = (fit_jitter_pixel_t){0, 0, c.r, c.S};
        r->s.n_pixels = 1;
        r->spot_radius_um = c.spot_radius_um;
    }
    storage_sensor_t sn;
    ret = storage_sensor_get(st, sid, &sn, &err);
    if (ret) {
        api_error_rc(q, ret, "sensor_id", err.msg);
        return -1;
    }
    r->s.pitch_um = sn.pitch_um;
    if (cid > 0) {
        storage_sensor_free(&sn);
        return 0;
    }
    if (col < 0 || row < 0 || col >= sn.n_cols || row >= sn.n_rows) {
        api_error(q, 422, "out_of_range", col < 0 || col >= sn.n_cols ? "col" : "row",
                  "col and row must name a pixel of sensor %lld (%d x %d)", (long long)sid,
                  sn.n_cols, sn.n_rows);
        storage_sensor_free(&sn);
        return -1;
    }
    /* the aperture: every pixel's current calibration, flat where it has none (but the
     * reference pixel must have one) */
    r->spot_radius_um = NAN;
    for (long long dr = -ap; dr <= ap; dr++)
        for (long long dc = -ap; dc <= ap; dc++) {
            long long pc = col + dc, pr = row + dr;
            if (pc < 0 || pr < 0 || pc >= sn.n_cols || pr >= sn.n_rows) continue;
            fit_jitter_pixel_t *px = &r->px[r->s.n_pixels++];
            *px = (fit_jitter_pixel_t){(int)dc, (int)dr, 0, NULL};
            ret = storage_calib_current(st, sid, (int)pc, (int)pr, &c, &err);
            if (ret == 0) {
                r->calibs[r->n_calibs++] = c;
                px->r = c.r;
                px->S = c.S;
                if (dc == 0 && dr == 0) r->spot_radius_um = c.spot_radius_um;
            } else if (ret != -ENOENT || (dc == 0 && dr == 0)) {
                if (ret == -ENOENT)
                    api_error(q, 404, "not_found", NULL,
                              "pixel (%lld, %lld) of sensor %lld has no calibration", col, row,
                              (long long)sid);
                else
                    api_error_rc(q, ret, NULL, err.msg);
                storage_sensor_free(&sn);
                return -1;
            }
        }
    storage_sensor_free(&sn);
    return 0;
}

/* "psf": {"kind", "radius_um" | "wavelength_nm" + "na" (Airy), "sigma_um" (Gaussian)}; absent:
 * the Airy spot of the calibration's optics. -1 after replying. */
static int read_psf(api_req_t *q, json_t *o, struct req *r)
{
    json_t *p;
    if (api_get_obj(q, o, "psf", "psf", &p)) return -1;
    if (!p) {
        if (!(r->spot_radius_um > 0)) {
            api_error(q, 422, "missing", "psf",
                      "psf is required: the map has no optics to take the Airy spot from");
            return -1;
        }
        r->s.psf = (fit_psf_t){FIT_PSF_AIRY, r->spot_radius_um};
        return 0;
    }
    static const char *const keys[] = {"kind", "radius_um", "wavelength_nm",
                                       "na",   "sigma_um",  NULL};
    const char *kind = "airy";
    double R = NAN, wl = NAN, na = NAN, sigma = NAN;
    err_t err = {{0}};
    if (api_no_unknown(q, p, "psf.", keys) || api_get_str(q, p, "kind", "psf.kind", 0, 16, &kind) ||
        api_get_num(q, p, "radius_um", "psf.radius_um", 0, 0, 1e5, 1, &R) ||
        api_get_num(q, p, "wavelength_nm", "psf.wavelength_nm", 0, 0, 1e6, 1, &wl) ||
        api_get_num(q, p, "na", "psf.na", 0, 0, 1.5, 1, &na) ||
        api_get_num(q, p, "sigma_um", "psf.sigma_um", 0, 0, 1e5, 1, &sigma))
        return -1;
    if (jitterjson_psf_parse(kind, &r->s.psf.kind, &err)) {
        api_error(q, 422, "bad_value", "psf.kind", "%s", err.msg);
        return -1;
    }
    if (r->s.psf.kind == FIT_PSF_GAUSS) {
        if (!(sigma > 0)) {
            api_error(q, 422, "missing", "psf.sigma_um", "psf.sigma_um is required for gauss");
            return -1;
        }
        r->s.psf.width_um = sigma;
        return 0;
    }
    if (!(R > 0) && wl > 0 && na > 0) R = fit_spot_radius_um(wl / 1000, na); /* eq. 1 */
    if (!(R > 0)) R = r->spot_radius_um;
    if (!(R > 0)) {
        api_error(q, 422, "missing", "psf.radius_um",
                  "psf.radius_um (or wavelength_nm and na) is required for airy");
        return -1;
    }
    r->s.psf.width_um = R;
    return 0;
}

/* "jitter": {"rms_um", "samples", "seed"} or {"dx_um", "dy_um"}, and "measured". */
static int read_jitter(api_req_t *q, json_t *o, struct req *r)
{
    json_t *j;
    if (api_get_obj(q, o, "jitter", "jitter", &j)) return -1;
    if (!j) {
        api_error(q, 422, "missing", "jitter", "jitter is required");
        return -1;
    }
    static const char *const keys[] = {"rms_um", "samples", "seed", "dx_um", "dy_um", NULL};
    if (api_no_unknown(q, j, "jitter.", keys)) return -1;
    json_t *ax = json_object_get(j, "dx_um"), *ay = json_object_get(j, "dy_um");
    if (ax || ay) {
        if (!ax || !ay) {
            api_error(q, 422, "missing", ax ? "jitter.dy_um" : "jitter.dx_um",
                      "jitter.dx_um and jitter.dy_um go together");
            return -1;
        }
        size_t n = 0;
        if (get_array(q, ax, "jitter.dx_um", MAX_SAMPLES, &n, &r->dx) ||
            get_array(q, ay, "jitter.dy_um", MAX_SAMPLES, &n, &r->dy))
            return -1;
        r->n = n;
        json_t *m = json_object_get(o, "measured");
        if (m && get_array(q, m, "measured", MAX_SAMPLES, &n, &r->measured)) return -1;
        return 0;
    }
    double rms = NAN;
    long long n = 1000, seed = 1;
    if (api_get_num(q, j, "rms_um", "jitter.rms_um", 1, 0, 1e4, 0, &rms) ||
        api_get_int(q, j, "samples", "jitter.samples", 0, 1, MAX_SAMPLES, &n) ||
        api_get_int(q, j, "seed", "jitter.seed", 0, 0, UINT32_MAX, &seed))
        return -1;
    if (json_object_get(o, "measured")) {
        api_error(q, 422, "bad_value", "measured",
                  "measured fluxes need the jitter series they were taken with (dx_um, dy_um)");
        return -1;
    }
    r->n = (size_t)n;
    r->dx = malloc(sizeof(double) * r->n);
    r->dy = malloc(sizeof(double) * r->n);
    err_t err = {{0}};
    if (!r->dx || !r->dy || fit_jitter_draw(rms, r->n, (unsigned long)seed, r->dx, r->dy, &err)) {
        api_error(q, 500, "internal", NULL, "%s", r->dx && r->dy ? err.msg : "out of memory");
        return -1;
    }
    return 0;
}

void api_h_jitter(api_req_t *q)
{
    json_t *o = api_body_object(q);
    if (!o) return;
    static const char *const keys[] = {
        "calibration_id", "sensor_id", "col",      "row",     "aperture", "map", "pitch_um", "psf",
        "position_um",    "jitter",    "measured", "samples", NULL};
    struct req r = {0};
    r.s.pixels = r.px;
    json_t *pos;
    int samples = 0;
    if (api_no_unknown(q, o, "", keys) || read_maps(q, o, &r) || read_psf(q, o, &r) ||
        read_jitter(q, o, &r) || api_get_obj(q, o, "position_um", "position_um", &pos) ||
        api_get_bool(q, o, "samples", "samples", &samples))
        goto out;
    r.s.x0_um = r.s.y0_um = r.s.pitch_um / 2;
    if (pos && (api_get_num(q, pos, "x", "position_um.x", 0, -1e4, 1e4, 0, &r.s.x0_um) ||
                api_get_num(q, pos, "y", "position_um.y", 0, -1e4, 1e4, 0, &r.s.y0_um)))
        goto out;
    double work = 0;
    for (size_t p = 0; p < r.s.n_pixels; p++)
        work += r.px[p].S ? (double)r.px[p].r * r.px[p].r : 1;
    if (work * (double)r.n > MAX_WORK) {
        api_error(q, 422, "out_of_range", "jitter.samples",
                  "%zu samples on %g map cells is too much work for one request (samples x "
                  "cells at most %g)",
                  r.n, work, MAX_WORK);
        goto out;
    }
    /* the Airy integrals' own cost: it grows with the spot's rings that the pixel's edge lines
     * cross (a tiny spot: thousands), which samples x cells does not see */
    double evals = fit_jitter_cost(&r.s, r.dx, r.dy, r.n), cap = srv_config(q->srv)->max_jitter_evals;
    if (evals > cap) {
        double reach = fit_jitter_reach(r.dx, r.dy, r.n);
        api_error(q, 422, "out_of_range", "jitter.samples",
                  "%zu samples of an Airy spot of radius %.3g um reaching %.3g um (%.3g spot "
                  "radii) from the nominal position need about %.3g radial evaluations, more "
                  "than one request may do (%.3g, ipsd --max-jitter-evals): fewer samples, a "
                  "smaller jitter or a larger spot",
                  r.n, r.s.psf.width_um, reach, reach / r.s.psf.width_um, evals, cap);
        goto out;
    }
    json_t *doc;
    err_t err = {{0}};
    int ret = jitterjson_run(&r.s, r.dx, r.dy, r.n, r.measured, samples, &doc, &err);
    if (ret == -ENOMEM) {
        api_error(q, 500, "internal", NULL, "%s", err.msg);
    } else if (ret) {
        api_error(q, 422, ret == -ERANGE ? "out_of_range" : "bad_value", NULL, "%s", err.msg);
    } else {
        json_t *ids = json_array();
        for (size_t k = 0; ids && k < r.n_calibs; k++)
            json_array_append_new(ids, json_integer(r.calibs[k].id));
        json_object_set_new(doc, "calibration_ids", ids ? ids : json_null());
        api_reply_json(q, 200, doc);
    }
out:
    req_free(&r);
    json_decref(o);
}
