/* srv_setup.c: the scan setup as JSON and a pixel's response from the stored points (see
 * srv_setup.h). */
#include "server/srv_setup.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fit/model.h"
#include "fit/noise.h"

/* The doubles of a setup, by name, for both directions. */
#define SETUP_DOUBLES(X)                                                                           \
    X(exposure_us)                                                                                 \
    X(gain)                                                                                        \
    X(pitch_um)                                                                                    \
    X(bias_dn) X(gain_e_per_dn) X(read_noise_e) X(full_scale_dn) X(spot_radius_um) X(imbalance_x)  \
        X(imbalance_y) X(neighbour_fraction) X(peak_dn)

/* NaN (unknown diagnostics) is written as null. */
static json_t *num(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

static json_t *str_or_null(const char *s)
{
    return s && *s ? json_string(s) : json_null();
}

char *srv_setup_dump_provenance(const scan_setup_t *su, const cam_info_t *cam, int setup_none)
{
    char *text = srv_setup_dump(su);
    json_t *o = text ? json_loads(text, 0, NULL) : NULL;
    free(text);
    if (!o) return NULL;
    json_t *c = json_object();
    if (c) {
        json_object_set_new(c, "backend", str_or_null(cam->backend));
        json_object_set_new(c, "id", str_or_null(cam->id));
        json_object_set_new(c, "vendor", str_or_null(cam->vendor));
        json_object_set_new(c, "model", str_or_null(cam->model));
        json_object_set_new(c, "serial", str_or_null(cam->serial));
        json_object_set_new(c, "firmware", str_or_null(cam->firmware));
        json_object_set_new(c, "pixel_format", str_or_null(cam->pixel_format));
        json_object_set_new(c, "bits", cam->bits > 0 ? json_integer(cam->bits) : json_null());
    }
    json_object_set_new(o, "camera", c ? c : json_null());
    json_object_set_new(o, "setup", json_string(setup_none ? "none" : "paper"));
    text = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(o);
    return text;
}

int srv_setup_camera(const char *text, cam_info_t *cam)
{
    json_t *o = json_loads(text, 0, NULL), *c = json_object_get(o, "camera");
    memset(cam, 0, sizeof *cam);
    int ret = json_is_object(c) ? 0 : -ENOENT;
#define STR(f)                                                                                     \
    do {                                                                                           \
        json_t *v_ = json_object_get(c, #f);                                                       \
        if (json_is_string(v_)) snprintf(cam->f, sizeof cam->f, "%s", json_string_value(v_));      \
    } while (0)
    STR(backend);
    STR(id);
    STR(vendor);
    STR(model);
    STR(serial);
    STR(firmware);
    STR(pixel_format);
#undef STR
    cam->bits = (int)json_integer_value(json_object_get(c, "bits"));
    json_decref(o);
    return ret;
}

char *srv_setup_dump(const scan_setup_t *su)
{
    json_t *o = json_pack("{s:[o, o, o], s:i, s:i}", "centre_um", num(su->centre.x_um),
                          num(su->centre.y_um), num(su->centre.z_um), "centre_iterations",
                          su->centre_iterations, "focus_evaluations", su->focus_evaluations);
    if (!o) return NULL;
#define PUT(f) json_object_set_new(o, #f, num(su->f));
    SETUP_DOUBLES(PUT)
#undef PUT
    char *text = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(o);
    return text;
}

/* A number member (null reads as NaN); -EINVAL when missing or of another type. */
static int get_num(json_t *o, const char *key, double *v, err_t *err)
{
    json_t *x = json_object_get(o, key);
    if (json_is_null(x)) {
        *v = NAN;
        return 0;
    }
    if (!json_is_number(x)) return err_set(err, -EINVAL, "scan setup: %s missing", key);
    *v = json_number_value(x);
    return 0;
}

int srv_setup_parse(const char *text, scan_setup_t *su, err_t *err)
{
    json_error_t je;
    json_t *o = json_loads(text, 0, &je), *c = json_object_get(o, "centre_um");
    int ret = 0;
    memset(su, 0, sizeof *su);
    if (!json_is_array(c) || json_array_size(c) != 3) {
        ret = err_set(err, -EINVAL, "scan setup: centre_um missing");
        goto out;
    }
    su->centre.x_um = json_number_value(json_array_get(c, 0));
    su->centre.y_um = json_number_value(json_array_get(c, 1));
    su->centre.z_um = json_number_value(json_array_get(c, 2));
    su->centre_iterations = (int)json_integer_value(json_object_get(o, "centre_iterations"));
    su->focus_evaluations = (int)json_integer_value(json_object_get(o, "focus_evaluations"));
#define GET(f)                                                                                     \
    if (!ret) ret = get_num(o, #f, &su->f, err);
    SETUP_DOUBLES(GET)
#undef GET
out:
    json_decref(o);
    return ret;
}

int srv_pixel_scan(storage_t *st, const storage_scan_t *sc, int dcol, int drow, int all,
                   scanfile_t *out, err_t *err)
{
    char *text = NULL;
    storage_raster_t r = {0};
    scan_setup_t su;
    int h = sc->sub_px / 2, ret;
    memset(out, 0, sizeof *out);
    if (abs(dcol) > h || abs(drow) > h)
        return err_set(err, -EINVAL, "pixel (%+d, %+d) is outside the %dx%d sub-frame", dcol, drow,
                       sc->sub_px, sc->sub_px);
    if ((ret = storage_scan_get_setup(st, sc->id, &text, err))) return ret;
    if (!text)
        return err_set(err, -ENODATA, "scan %lld has not been set up yet (no points)",
                       (long long)sc->id);
    if ((ret = srv_setup_parse(text, &su, err)) ||
        (ret = storage_frame_raster(st, sc->id, dcol, drow, &r, err)))
        goto out;
    /* points strictly inside the pixel (instrument/scan.h), or all of them */
    size_t n = 0;
    double x, y;
    for (size_t i = 0; i < r.n; i++)
        n += all || scan_pixel_coords(&su, dcol, drow, r.stage_x_um[i], r.stage_y_um[i], &x, &y);
    if ((ret = scan_file_new(&su, sc->frames, n, out, err))) goto out;
    for (size_t i = 0, k = 0; i < r.n; i++) {
        int inside = scan_pixel_coords(&su, dcol, drow, r.stage_x_um[i], r.stage_y_um[i], &x, &y);
        if (!(all || inside)) continue;
        out->x_um[k] = x;
        out->y_um[k] = y;
        out->signal_dn[k++] = r.mean_dn[i];
    }
out:
    storage_raster_free(&r);
    free(text);
    return ret;
}

int srv_pixel_scan_text(storage_t *st, const storage_scan_t *sc, int dcol, int drow, int all,
                        json_t *extra, char **text, size_t *len, err_t *err)
{
    scanfile_t sf;
    *text = NULL;
    *len = 0;
    int ret = srv_pixel_scan(st, sc, dcol, drow, all, &sf, err);
    if (ret) return ret;
    FILE *f = open_memstream(text, len);
    if (!f) {
        scanfile_free(&sf);
        return err_set(err, -ENOMEM, "out of memory");
    }
    /* sigma_dn: each point's uncertainty under the automatic fit's noise model (fit/noise.h;
     * eq. 5 of the paper for "paper"), so no client recomputes it; null for a non-finite mean */
    fit_noise_t model = fit_options_default().noise;
    json_t *meta = extra ? json_deep_copy(extra) : json_object(), *sig = meta ? json_array() : NULL;
    for (size_t k = 0; sig && k < sf.scan.n; k++) {
        double s = fit_noise_sigma(model, &sf.scan, sf.scan.signal_dn[k]);
        json_array_append_new(sig, isfinite(s) ? json_real(s) : json_null());
    }
    if (!meta || json_object_set_new(meta, "sigma_dn", sig) /* takes sig, even on failure */ ||
        json_object_set_new(meta, "sigma_model", json_string(fit_noise_name(model))))
        ret = err_set(err, -ENOMEM, "out of memory");
    else
        ret = scanfile_dump(f, &sf.scan, meta, err);
    json_decref(meta);
    if (fclose(f) && ret == 0) ret = err_set(err, -ENOMEM, "out of memory");
    scanfile_free(&sf);
    if (ret) {
        free(*text);
        *text = NULL;
    }
    return ret;
}
