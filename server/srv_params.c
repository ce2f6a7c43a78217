/* srv_params.c: job parameters to and from jobs.params JSON (see srv_params.h). The API validates
 * requests before they become parameters; parsing here guards against rows written by others. */
#include "server/srv_params.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fit/adapt_plan.h"
#include "instrument/scan_limits.h"
#include "instrument/scanfile.h"

srv_strategy_t srv_strategy_default(void)
{
    return (srv_strategy_t){.target_err = FIT_ADAPT_TARGET_ERR,
                            .max_points = FIT_ADAPT_MAX_POINTS,
                            .batch = FIT_ADAPT_BATCH,
                            .start_grid = FIT_ADAPT_START_GRID};
}

json_t *srv_strategy_json(const srv_strategy_t *s)
{
    if (!s->adaptive) return json_pack("{s:s}", "kind", "raster");
    return json_pack("{s:s, s:f, s:i, s:i, s:i}", "kind", "adaptive", "target_err", s->target_err,
                     "max_points", s->max_points, "batch", s->batch, "start_grid",
                     s->start_grid);
}

/* The "strategy" member of the params into *s (a raster when absent or not adaptive). */
static void strategy_parse(json_t *o, srv_strategy_t *s)
{
    *s = srv_strategy_default();
    json_t *kind = json_object_get(o, "kind"), *v;
    if (!json_is_string(kind) || strcmp(json_string_value(kind), "adaptive")) return;
    s->adaptive = 1;
    if ((v = json_object_get(o, "target_err")) && json_is_number(v))
        s->target_err = json_number_value(v);
    if ((v = json_object_get(o, "max_points")) && json_is_integer(v))
        s->max_points = (int)json_integer_value(v);
    if ((v = json_object_get(o, "batch")) && json_is_integer(v))
        s->batch = (int)json_integer_value(v);
    if ((v = json_object_get(o, "start_grid")) && json_is_integer(v))
        s->start_grid = (int)json_integer_value(v);
}

srv_scan_params_t srv_scan_params_default(void)
{
    srv_scan_params_t p = {.seed = SCAN_DEFAULT_SEED, .strategy = srv_strategy_default()};
    snprintf(p.scene, sizeof p.scene, "paperlike");
    return p;
}

char *srv_scan_params_dump(const srv_scan_params_t *p)
{
    json_t *o = json_pack("{s:s, s:I, s:s}", "scene", p->scene, "seed", (json_int_t)p->seed,
                          "setup", p->setup_none ? "none" : "paper");
    if (o && p->strategy.adaptive)
        json_object_set_new(o, "strategy", srv_strategy_json(&p->strategy));
    char *text = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return text;
}

int srv_scan_params_parse(const char *text, srv_scan_params_t *p, err_t *err)
{
    *p = srv_scan_params_default();
    json_t *o = json_loads(text, 0, NULL), *scene, *seed, *setup;
    if (!json_is_object(o)) {
        json_decref(o);
        return err_set(err, -EINVAL, "scan job params: not a JSON object");
    }
    if ((scene = json_object_get(o, "scene")) && json_is_string(scene))
        snprintf(p->scene, sizeof p->scene, "%s", json_string_value(scene));
    if ((seed = json_object_get(o, "seed")) && json_is_integer(seed))
        p->seed = (unsigned long)json_integer_value(seed);
    if ((setup = json_object_get(o, "setup")) && json_is_string(setup))
        p->setup_none = strcmp(json_string_value(setup), "none") == 0;
    strategy_parse(json_object_get(o, "strategy"), &p->strategy);
    json_decref(o);
    return 0;
}

srv_fit_params_t srv_fit_params_default(void)
{
    return (srv_fit_params_t){.r_min = 1,
                              .r_max = 8,
                              .opts = fit_options_default(),
                              .ftest_r = 7,
                              .wiener = 0,
                              .wavelength_um = NAN,
                              .na = NAN,
                              .gain_e_per_dn = NAN,
                              .read_noise_e = NAN};
}

srv_fit_params_t srv_fit_params_auto(int64_t scan_id)
{
    srv_fit_params_t p = srv_fit_params_default();
    p.scan_id = scan_id;
    p.ftest_edges = FIT_EDGE_TOP | FIT_EDGE_LEFT | FIT_EDGE_BOTTOM;
    p.wiener = 1;
    p.promote = 1;
    snprintf(p.by, sizeof p.by, "ipsd");
    snprintf(p.reason, sizeof p.reason, "automatic fit of scan %lld", (long long)scan_id);
    return p;
}

void srv_fit_params_free(srv_fit_params_t *p)
{
    if (!p) return;
    json_decref(p->scan_file);
    p->scan_file = NULL;
}

const char *srv_edges_text(unsigned edges, char *buf, size_t n)
{
    static const char *const names[] = {"top", "left", "bottom", "right"};
    size_t at = 0;
    buf[0] = 0;
    for (int i = 0; i < 4; i++)
        if (edges & (1u << i))
            at += (size_t)snprintf(buf + at, at < n ? n - at : 0, "%s%s", at ? "," : "", names[i]);
    return buf;
}

static const char *const methods[] = {"linear", "lm", "both"};

char *srv_fit_params_dump(const srv_fit_params_t *p)
{
    char edges[64];
    json_t *o = json_pack("{s:i, s:i, s:i, s:i, s:s, s:s, s:b, s:i, s:b}", "dcol", p->dcol, "drow",
                          p->drow, "r_min", p->r_min, "r_max", p->r_max, "sigma",
                          fit_noise_name(p->opts.noise), "method", methods[p->opts.method],
                          "nonneg", p->opts.nonneg, "ftest_r", p->ftest_r, "wiener", p->wiener);
    if (!o) return NULL;
    json_object_set_new(o, "ftest",
                        p->ftest_edges
                            ? json_string(srv_edges_text(p->ftest_edges, edges, sizeof edges))
                            : json_null());
    if (p->scan_id) json_object_set_new(o, "scan_id", json_integer(p->scan_id));
    if (p->scan_file) json_object_set(o, "scan", p->scan_file);
    if (p->sensor_id) {
        json_object_set_new(o, "sensor_id", json_integer(p->sensor_id));
        json_object_set_new(o, "pixel",
                            json_pack("{s:i, s:i}", "col", p->pixel_col, "row", p->pixel_row));
    }
    if (isfinite(p->wavelength_um))
        json_object_set_new(o, "wavelength_um", json_real(p->wavelength_um));
    if (isfinite(p->na)) json_object_set_new(o, "na", json_real(p->na));
    json_object_set_new(o, "promote", json_boolean(p->promote));
    if (p->by[0]) json_object_set_new(o, "by", json_string(p->by));
    if (p->reason[0]) json_object_set_new(o, "reason", json_string(p->reason));
    json_object_set_new(o, "region", json_string(fit_region_name(p->region.kind)));
    if (p->fit_geometry) {
        json_object_set_new(o, "fit_geometry", json_true());
        if (p->geometry_r) json_object_set_new(o, "geometry_r", json_integer(p->geometry_r));
        if (p->geometry_map_only) json_object_set_new(o, "geometry_model", json_string("map"));
    }
    if (p->region.kind == FIT_REGION_MARGIN)
        json_object_set_new(o, "margin_um", json_real(p->region.margin_um));
    if (p->all_pixels) json_object_set_new(o, "pixels", json_string("all"));
    if (p->krige) json_object_set_new(o, "krige", json_true());
    /* always written: a job stored without it (before the kriged map became the default) meant
     * the recommended map, and still does when it runs (srv_fit_params_parse) */
    json_object_set_new(o, "map", json_string(storage_map_name(p->map)));
    if (isfinite(p->gain_e_per_dn))
        json_object_set_new(o, "gain_e_per_dn", json_real(p->gain_e_per_dn));
    if (isfinite(p->read_noise_e))
        json_object_set_new(o, "read_noise_e", json_real(p->read_noise_e));
    char *text = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(o);
    return text;
}

/* Integer member into *v when present. */
static void opt_int(json_t *o, const char *key, int *v)
{
    json_t *x = json_object_get(o, key);
    if (json_is_integer(x)) *v = (int)json_integer_value(x);
}

/* The string members: sigma, method, ftest. */
static int parse_words(json_t *o, srv_fit_params_t *p, err_t *err)
{
    const char *sigma = json_string_value(json_object_get(o, "sigma"));
    const char *method = json_string_value(json_object_get(o, "method"));
    const char *ftest = json_string_value(json_object_get(o, "ftest"));
    if (sigma && fit_noise_parse(sigma, &p->opts.noise))
        return err_set(err, -EINVAL, "fit job params: sigma '%s' unknown", sigma);
    for (int m = 0; method && m < 3; m++)
        if (strcmp(method, methods[m]) == 0) p->opts.method = (fit_method_t)m;
    if (ftest && fit_edges_parse(ftest, &p->ftest_edges, err)) return -EINVAL;
    return 0;
}

int srv_fit_params_parse(const char *text, srv_fit_params_t *p, err_t *err)
{
    *p = srv_fit_params_default();
    json_t *o = json_loads(text, 0, NULL), *x;
    int ret = 0;
    if (!json_is_object(o)) {
        ret = err_set(err, -EINVAL, "fit job params: not a JSON object");
        goto out;
    }
    p->scan_id = json_integer_value(json_object_get(o, "scan_id"));
    p->sensor_id = json_integer_value(json_object_get(o, "sensor_id"));
    opt_int(o, "dcol", &p->dcol);
    opt_int(o, "drow", &p->drow);
    opt_int(o, "r_min", &p->r_min);
    opt_int(o, "r_max", &p->r_max);
    opt_int(o, "ftest_r", &p->ftest_r);
    opt_int(json_object_get(o, "pixel"), "col", &p->pixel_col);
    opt_int(json_object_get(o, "pixel"), "row", &p->pixel_row);
    p->wiener = json_is_true(json_object_get(o, "wiener"));
    p->fit_geometry = json_is_true(json_object_get(o, "fit_geometry"));
    p->krige = json_is_true(json_object_get(o, "krige"));
    p->all_pixels = (x = json_object_get(o, "pixels")) && json_is_string(x) &&
                    strcmp(json_string_value(x), "all") == 0;
    int map = storage_map_parse(json_string_value(json_object_get(o, "map")));
    p->map = map < 0 ? STORAGE_MAP_RECOMMENDED : (storage_map_t)map;
    if (p->map == STORAGE_MAP_KRIGED) p->krige = 1;
    if ((x = json_object_get(o, "geometry_r")) && json_is_integer(x))
        p->geometry_r = (int)json_integer_value(x);
    if ((x = json_object_get(o, "geometry_model")) && json_is_string(x))
        p->geometry_map_only = strcmp(json_string_value(x), "map") == 0;
    p->opts.nonneg = json_is_true(json_object_get(o, "nonneg"));
    if ((x = json_object_get(o, "wavelength_um")) && json_is_number(x))
        p->wavelength_um = json_number_value(x);
    if ((x = json_object_get(o, "na")) && json_is_number(x)) p->na = json_number_value(x);
    if ((x = json_object_get(o, "gain_e_per_dn")) && json_is_number(x))
        p->gain_e_per_dn = json_number_value(x);
    if ((x = json_object_get(o, "read_noise_e")) && json_is_number(x))
        p->read_noise_e = json_number_value(x);
    p->promote = (x = json_object_get(o, "promote")) ? json_is_true(x) : 1;
    if ((x = json_object_get(o, "by")) && json_is_string(x))
        snprintf(p->by, sizeof p->by, "%s", json_string_value(x));
    if ((x = json_object_get(o, "reason")) && json_is_string(x))
        snprintf(p->reason, sizeof p->reason, "%s", json_string_value(x));
    if ((ret = parse_words(o, p, err))) goto out;
    const char *region = json_string_value(json_object_get(o, "region"));
    x = json_object_get(o, "margin_um");
    if (region && (ret = fit_region_parse(region, json_is_number(x) ? json_number_value(x) : NAN,
                                          &p->region, err)))
        goto out;
    if ((x = json_object_get(o, "scan"))) p->scan_file = json_incref(x);
    if (!p->scan_id && !p->scan_file)
        ret = err_set(err, -EINVAL, "fit job params: neither scan_id nor scan");
out:
    json_decref(o);
    return ret;
}

int srv_upload_check(json_t *scan, double *pitch_um, size_t *n_points, const char **field,
                     err_t *err)
{
    scanfile_t sf;
    *field = NULL;
    char *text = json_dumps(scan, JSON_COMPACT | JSON_REAL_PRECISION(17));
    if (!text) return err_set(err, -ENOMEM, "out of memory");
    int ret = scanfile_parse(text, strlen(text), &sf, field, err);
    free(text);
    if (ret) return ret;
    *pitch_um = sf.scan.pitch_um;
    *n_points = sf.scan.n;
    scanfile_free(&sf);
    return 0;
}
