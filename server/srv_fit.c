/* srv_fit.c: the fit a fit job runs (see srv_fit.h): the fit pipeline of fit/pipeline.h, the one
 * `ips fit` runs, watched through the job's stop flag (before each step and inside its long
 * loops) and progress, and what is the server's own:
 * the result document (json/fitjson.h, failed parts as {"error": "..."}) and the recommended map
 * that becomes the calibration. */
#include "server/srv_fit.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "fit/krige.h"
#include "fit/pipeline.h"
#include "json/fitjson.h"

void srv_fit_out_free(srv_fit_out_t *o)
{
    if (!o) return;
    json_decref(o->result);
    free(o->S);
    free(o->S_err);
    free(o->S_res);
    memset(o, 0, sizeof *o);
}

/* The pipeline's watch over the job's hooks (fit_watch_t's params is the srv_fit_hooks_t). */
static int watch_stop(const fit_step_t *next, void *params)
{
    (void)next;
    const srv_fit_hooks_t *h = params;
    return h->stop && atomic_load(h->stop);
}

/* Inside the fit's long loops (fit/stop.h): the stop flag a cancel or the shutdown sets directly,
 * so a fit stops within a fraction of one r; then the caller's poll. */
static int watch_poll(void *params)
{
    const srv_fit_hooks_t *h = params;
    if (h->stop && atomic_load_explicit(h->stop, memory_order_relaxed)) return 1;
    return h->poll && h->poll(h->user);
}

/* The same at a named place of the fit (fit/stop.h's sites): the caller's poll_at, else poll. */
static int watch_poll_at(void *params, const char *site)
{
    const srv_fit_hooks_t *h = params;
    if (!h->poll_at) return watch_poll(params);
    if (h->stop && atomic_load_explicit(h->stop, memory_order_relaxed)) return 1;
    return h->poll_at(h->user, site);
}

static void watch_progress(int done, int total, const fit_step_t *step, void *params)
{
    (void)step;
    const srv_fit_hooks_t *h = params;
    if (h->progress) h->progress((double)done / total, h->user);
}

/* A failed optional part in the document: {"error": "..."}. */
static json_t *part_error(const fit_part_t *part)
{
    return json_pack("{s:s}", "error", part->err.msg);
}

/* The `ips fit` document of a run: the sweep, the parts asked for, the timing. */
static json_t *document(const fit_scan_t *scan, const srv_fit_params_t *p,
                        const fit_pipeline_t *pl, double t0)
{
    json_t *root = fitjson_sweep(&pl->sweep, pl->n_region, &p->opts, scan->full_scale_dn);
    if (!root) return NULL;
    if (fitjson_add_region(root, &pl->region, scan->n)) {
        json_decref(root);
        return NULL;
    }
    const fit_part_t *ft = &pl->ftest_part, *wi = &pl->wiener_part, *ge = &pl->geometry_part;
    if (ge->asked)
        json_object_set_new(root, "geometry",
                            ge->rc ? part_error(ge) : fitjson_geometry(&pl->geometry));
    if (ft->asked)
        json_object_set_new(root, "ftest", ft->rc ? part_error(ft) : fitjson_ftest(&pl->ftest));
    if (wi->asked)
        json_object_set_new(root, "wiener", wi->rc ? part_error(wi) : fitjson_wiener(&pl->wiener));
    json_object_set_new(root, "timing_ms",
                        json_pack("{s:f, s:f, s:f, s:f}", "sweep", pl->sweep_ms, "ftest",
                                  pl->ftest_part.ms, "wiener", pl->wiener_part.ms, "total",
                                  clock_mono_ms() - t0));
    if (ge->asked)
        json_object_set_new(json_object_get(root, "timing_ms"), "geometry",
                            json_real(ge->ms));
    if (p->krige) {
        const fit_kriged_t *k = pl->sweep.kriged;
        json_object_set_new(root, "kriged_map",
                            fitjson_kriged(k, pl->kriged_error));
        if (k) json_object_set_new(json_object_get(root, "timing_ms"), "krige", json_real(k->ms));
    }
    return root;
}

/* Copies the recommended map of the sweep (fit/recommend.h) into out (nothing when it has
 * none), or the shrunk map (fit/shrink.h) or the kriged map (fit/krige.h) when map asks for it
 * and the sweep has it: the map a calibration stores. I0, chi2_red and the status are the
 * recommended fit's either way. The resolution error S_res is the shrinkage's, of the r grid the
 * recommended and the shrunk map share (NULL without one); the kriged map has none: its S_err is
 * already its whole error against the truth's mean per fine cell (docs/numerics.md). */
static int keep_map(const fit_sweep_t *sw, storage_map_t map, srv_fit_out_t *out, err_t *err)
{
    if (!sw->recommended_r) return 0;
    const fit_result_t *f = &sw->fits[sw->recommended_r - sw->r_min];
    if (!f->S || !f->S_err) return 0;
    const fit_shrunk_t *sh = map == STORAGE_MAP_SHRUNK ? sw->shrunk : NULL;
    const fit_kriged_t *kr = map == STORAGE_MAP_KRIGED ? sw->kriged : NULL;
    int r = kr ? kr->grid : f->r;
    size_t n = (size_t)r * r;
    out->S = malloc(n * sizeof(double));
    out->S_err = malloc(n * sizeof(double));
    if (!out->S || !out->S_err) return err_set(err, -ENOMEM, "out of memory");
    memcpy(out->S, kr ? kr->S : sh ? sh->S : f->S, n * sizeof(double));
    memcpy(out->S_err, kr ? kr->S_err : sh ? sh->S_err : f->S_err, n * sizeof(double));
    out->r = r;
    out->map = kr ? STORAGE_MAP_KRIGED : sh ? STORAGE_MAP_SHRUNK : STORAGE_MAP_RECOMMENDED;
    if (!kr && sw->shrunk && sw->shrunk->r == f->r && sw->shrunk->S_res) { /* either map's grid */
        if (!(out->S_res = malloc(n * sizeof(double))))
            return err_set(err, -ENOMEM, "out of memory");
        memcpy(out->S_res, sw->shrunk->S_res, n * sizeof(double));
    }
    out->I0 = f->I0;
    out->chi2_red = f->chi2_red;
    out->status = fit_status_name(f->flags);
    return 0;
}

/* The document's stored_map: which map the fit offers as its pixel's calibration, its grid, and
 * when it is not the map the request asked for (no kriged map: no signal, too few points), why,
 * in one sentence. */
static int stored_map(json_t *doc, storage_map_t asked, srv_fit_out_t *out,
                      const char *kriged_error)
{
    json_t *o = json_pack("{s:s, s:i}", "map", storage_map_name(out->map), "r", out->r);
    if (!o) return -1;
    if (asked != out->map) {
        snprintf(out->map_note, sizeof out->map_note,
                 "No %s map could be made (%s), so the calibration is the recommended r = %d "
                 "map.", storage_map_name(asked),
                 asked == STORAGE_MAP_KRIGED && kriged_error[0] ? kriged_error
                                                                : "the sweep has none",
                 out->r);
        json_object_set_new(o, "why", json_string(out->map_note));
    }
    return json_object_set_new(doc, "stored_map", o);
}

int srv_fit_run(const fit_scan_t *scan, const srv_fit_params_t *p, const srv_fit_hooks_t *hooks,
                srv_fit_out_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    out->f_value = out->p_value = NAN;
    if (scan->n == 0) return err_set(err, -EINVAL, "the scan has no points inside the pixel");
    fit_pipeline_opts_t po = {.r_min = p->r_min, .r_max = p->r_max, .fit = p->opts,
                              .ftest_edges = p->ftest_edges, .ftest_r = p->ftest_r,
                              .wiener = p->wiener, .region = p->region,
                              .fit_geometry = p->fit_geometry, .geometry_r = p->geometry_r,
                              .geometry_map_only = p->geometry_map_only,
                              .krige = p->krige};
    fit_watch_t watch = {.stop = watch_stop, .progress = watch_progress, .params = (void *)hooks,
                         .poll = watch_poll, .poll_at = watch_poll_at};
    fit_pipeline_t pl;
    double t0 = clock_mono_ms();
    int ret = fit_pipeline_run(scan, &po, hooks ? &watch : NULL, &pl, err);
    if (ret) return ret;
    if (pl.n_region == 0) {
        char m[40] = "";
        if (p->region.kind == FIT_REGION_MARGIN)
            snprintf(m, sizeof m, " (%g um)", p->region.margin_um);
        fit_pipeline_free(&pl);
        return err_set(err, -EINVAL, "the scan has no points in the region %s%s of the pixel",
                       fit_region_name(p->region.kind), m);
    }
    out->best_aic = pl.sweep.best_aic;
    out->best_bic = pl.sweep.best_bic;
    if (pl.ftest_part.asked && pl.ftest_part.rc == 0) {
        out->f_value = pl.ftest.F;
        out->p_value = pl.ftest.p_value;
    }
    ret = keep_map(&pl.sweep, p->map, out, err);
    if (ret == 0 && !(out->result = document(scan, p, &pl, t0)))
        ret = err_set(err, -ENOMEM, "out of memory encoding the fit");
    if (ret == 0 && out->r && stored_map(out->result, p->map, out, pl.kriged_error))
        ret = err_set(err, -ENOMEM, "out of memory encoding the fit");
    fit_pipeline_free(&pl);
    return ret;
}
