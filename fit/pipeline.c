/* pipeline.c: the fit job as one call (pipeline.h): the sweep over r and the choice of the best r
 * (section IV: AIC = N ln(chi2/N) + 2p, BIC = N ln(chi2/N) + p ln N, the smallest among the fits
 * that have a map), then the F-test, the Wiener baseline and the interpolated best-AIC map, with
 * the watch consulted before and told after every step (and its poll inside the steps' loops). The F-test reuses the sweep's fit at
 * ftest_r as its H1 when the sweep has it and fitted it by the linear path, which is how H1 must
 * be fitted (model.h); otherwise it fits its own. With fit_geometry, the geometry fit
 * (geometry.h) runs first and, when it can be used, every later step sees the scan with the
 * fitted spot radius and positions. */
#include "fit/pipeline.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "fit/interp.h"
#include "fit/gslerr.h"
#include "fit/recommend.h"
#include "fit/krige.h"
#include "fit/shrink.h"
#include "parfor.h"

fit_pipeline_opts_t fit_pipeline_opts_default(void)
{
    return (fit_pipeline_opts_t){.r_min = 1, .r_max = 8, .fit = fit_options_default(),
                                 .ftest_r = 7};
}

const char *fit_step_name(fit_step_kind_t kind)
{
    switch (kind) {
    case FIT_STEP_SWEEP: return "sweep";
    case FIT_STEP_FTEST: return "ftest";
    case FIT_STEP_WIENER: return "wiener";
    case FIT_STEP_INTERP: return "interp";
    case FIT_STEP_GEOMETRY: return "geometry";
    }
    return "unknown";
}

/* The options, checked before any step runs. */
static int check_opts(const fit_scan_t *scan, const fit_pipeline_opts_t *o, err_t *err)
{
    if (o->r_min < 1 || o->r_max > FIT_R_MAX || o->r_min > o->r_max)
        return err_set(err, -EINVAL,
                       "r range must satisfy 1 <= r_min <= r_max <= %d (got r_min %d, r_max %d)",
                       FIT_R_MAX, o->r_min, o->r_max);
    if ((unsigned)o->fit.noise > FIT_NOISE_SHOT_READ)
        return err_set(err, -EINVAL, "unknown noise model %d", (int)o->fit.noise);
    if ((unsigned)o->fit.method > FIT_BOTH)
        return err_set(err, -EINVAL, "unknown fit method %d", (int)o->fit.method);
    unsigned all_edges = FIT_EDGE_TOP | FIT_EDGE_LEFT | FIT_EDGE_BOTTOM | FIT_EDGE_RIGHT;
    if (o->ftest_edges & ~all_edges)
        return err_set(err, -EINVAL, "ftest_edges has unknown edge bits (0x%x)", o->ftest_edges);
    if (o->ftest_edges && (o->ftest_r < 1 || o->ftest_r > FIT_R_MAX))
        return err_set(err, -EINVAL, "ftest_r must be between 1 and %d (got %d)", FIT_R_MAX,
                       o->ftest_r);
    if (o->fit_geometry && (o->geometry_r < 0 || o->geometry_r > FIT_R_MAX))
        return err_set(err, -EINVAL, "geometry_r must be between 1 and %d (got %d)", FIT_R_MAX,
                       o->geometry_r);
    if (o->interp_n < 0 || o->interp_n > FIT_INTERP_MAX)
        return err_set(err, -EINVAL, "interp_n must be between 0 and %d (got %d)",
                       FIT_INTERP_MAX, o->interp_n);
    if ((unsigned)o->region.kind > FIT_REGION_MARGIN ||
        (o->region.kind == FIT_REGION_MARGIN &&
         !(o->region.margin_um >= 0 && o->region.margin_um <= FIT_REGION_MARGIN_MAX)))
        return err_set(err, -EINVAL, "region must be inside, all or margin 0..%g um",
                       FIT_REGION_MARGIN_MAX);
    if (o->threads < 0 || o->threads > FIT_THREADS_MAX)
        return err_set(err, -EINVAL, "threads must be between 0 and %d (got %d)",
                       FIT_THREADS_MAX, o->threads);
    if ((unsigned)o->wiener_method > FIT_WIENER_NSR_FIXED)
        return err_set(err, -EINVAL, "unknown Wiener nsr method %d", (int)o->wiener_method);
    return fit_scan_check(scan, err);
}

/* One run in progress. */
struct run {
    const fit_scan_t *scan;  /* the region's points: what the sweep and the F-test fit */
    const fit_scan_t *whole; /* every point: what Wiener deconvolves */
    const fit_pipeline_opts_t *o;
    const fit_watch_t *watch;
    fit_pipeline_t *out;
    int done, total;
    double best_aic, best_bic; /* the smallest AIC / BIC so far among fits with a map */
    fit_scan_t geo_scan;       /* the region's points as the fitted geometry says */
    fit_scan_t geo_whole;      /* every point as it says (for Wiener) */
    double *geo_xy;            /* their positions, owned */
};

/* Before a step: asks the watch whether to stop. */
static int step_begin(struct run *rn, fit_step_kind_t kind, int r, fit_step_t *step, err_t *err)
{
    *step = (fit_step_t){.kind = kind, .r = r, .index = rn->done, .total = rn->total};
    const fit_watch_t *w = rn->watch;
    if (!w || !w->stop || !w->stop(step, w->params)) return 0;
    switch (kind) {
    case FIT_STEP_SWEEP: return err_set(err, -ECANCELED, "fit stopped before r = %d", r);
    case FIT_STEP_FTEST: return err_set(err, -ECANCELED, "fit stopped before the F-test");
    case FIT_STEP_WIENER:
        return err_set(err, -ECANCELED, "fit stopped before the Wiener baseline");
    case FIT_STEP_INTERP:
        return err_set(err, -ECANCELED, "fit stopped before the interpolation");
    case FIT_STEP_GEOMETRY:
        return err_set(err, -ECANCELED, "fit stopped before the geometry fit");
    }
    return err_set(err, -ECANCELED, "fit stopped");
}

/* After a step: tells the watch. */
static void step_end(struct run *rn, const fit_step_t *step)
{
    rn->done++;
    const fit_watch_t *w = rn->watch;
    if (w && w->progress) w->progress(rn->done, rn->total, step, w->params);
}

/* The fit at r, a candidate for the best r when it has a map. */
static int sweep_step(struct run *rn, int r, err_t *err)
{
    fit_sweep_t *sw = &rn->out->sweep;
    fit_result_t *f = &sw->fits[r - sw->r_min];
    int rc = fit_map(rn->scan, r, &rn->o->fit, f, err);
    if (rc || !f->S) return rc; /* no map: not a candidate */
    if (f->aic < rn->best_aic) rn->best_aic = f->aic, sw->best_aic = r;
    if (f->bic < rn->best_bic) rn->best_bic = f->bic, sw->best_bic = r;
    return 0;
}

/* The sweep without a watch, on opts.threads threads (one included): the r run from the largest
 * down, so that the longest fits start first and the threads finish together, and so that the
 * largest fit's buffers are allocated first and every smaller one reuses their memory (one
 * thread on the 41 x 41 raster, r = 1..16: peak RSS 30.5 -> 24.5 MB, fewer fresh pages). */
struct par_sweep {
    struct run *rn;
    fit_design_cache_t *cache[FIT_THREADS_MAX]; /* per thread; 0 is the run's own */
    int rc[FIT_R_MAX + 1];                       /* per r: fit_map's return, 1 when not run */
    err_t err[FIT_R_MAX + 1];
};

static int par_sweep_body(int i, int thread, void *ctx)
{
    struct par_sweep *ps = ctx;
    const fit_pipeline_opts_t *o = ps->rn->o;
    fit_sweep_t *sw = &ps->rn->out->sweep;
    int r = o->r_max - i;
    fit_options_t fo = o->fit;
    if (thread > 0 && !ps->cache[thread]) ps->cache[thread] = fit_design_cache_new();
    if (thread > 0) fo.design_cache = ps->cache[thread]; /* NULL: the fit builds its own */
    ps->rc[r] = fit_map(ps->rn->scan, r, &fo, &sw->fits[r - sw->r_min], &ps->err[r]);
    return ps->rc[r];
}

/* Runs the sweep's fits on opts.threads threads, then picks the best r in increasing r as the
 * one-thread loop does. A failure is reported for the smallest r that failed. */
static int sweep_threads(struct run *rn, err_t *err)
{
    const fit_pipeline_opts_t *o = rn->o;
    fit_sweep_t *sw = &rn->out->sweep;
    struct par_sweep *ps = calloc(1, sizeof *ps);
    if (!ps) return err_set(err, -ENOMEM, "out of memory");
    ps->rn = rn;
    for (int r = 0; r <= FIT_R_MAX; r++) ps->rc[r] = 1;
    int nr = o->r_max - o->r_min + 1, rc = 0;
    double t = clock_mono_ms();
    fit_parfor(nr, o->threads, par_sweep_body, ps);
    rn->out->sweep_ms += clock_mono_ms() - t;
    for (int r = o->r_min; r <= o->r_max && !rc; r++) {
        fit_result_t *f = &sw->fits[r - sw->r_min];
        if (ps->rc[r] < 0) {
            rc = ps->rc[r];
            if (err) *err = ps->err[r];
        } else if (ps->rc[r] == 0 && f->S) {
            if (f->aic < rn->best_aic) rn->best_aic = f->aic, sw->best_aic = r;
            if (f->bic < rn->best_bic) rn->best_bic = f->bic, sw->best_bic = r;
        }
    }
    for (int t2 = 1; t2 < FIT_THREADS_MAX; t2++) fit_design_cache_free(ps->cache[t2]);
    free(ps);
    rn->done += nr;
    return rc;
}

static void ftest_step(struct run *rn)
{
    const fit_pipeline_opts_t *o = rn->o;
    fit_pipeline_t *out = rn->out;
    const fit_sweep_t *sw = &out->sweep;
    fit_part_t *p = &out->ftest_part;
    if (o->fit.method == FIT_LINEAR && o->ftest_r >= sw->r_min && o->ftest_r <= sw->r_max)
        p->rc = fit_ftest_with_h1(rn->scan, &sw->fits[o->ftest_r - sw->r_min], o->ftest_edges,
                                  &o->fit, &out->ftest, &p->err);
    else
        p->rc = fit_ftest_run(rn->scan, o->ftest_r, o->ftest_edges, &o->fit, &out->ftest, &p->err);
}

static void wiener_step(struct run *rn)
{
    fit_part_t *p = &rn->out->wiener_part;
    fit_wiener_opts_t wo = {.method = rn->o->wiener_nsr > 0 ? FIT_WIENER_NSR_FIXED
                                                            : rn->o->wiener_method,
                            .nsr = rn->o->wiener_nsr, .crop = 1, .stop = rn->o->fit.stop};
    p->rc = fit_wiener_run_opts(rn->whole, &wo, &rn->out->wiener, &p->err);
}

/* The geometry fit; when it can be used, every later step runs on the scan it describes. */
static void geometry_step(struct run *rn)
{
    fit_part_t *p = &rn->out->geometry_part;
    fit_geometry_t *g = &rn->out->geometry;
    int r = rn->o->geometry_r;
    const fit_scan_t *scan = rn->scan;
    /* r asked, or picked from the data (geometry.h: the smallest BIC over increasing r) */
    if ((p->rc = r ? fit_geometry_run(scan, r, &rn->o->fit, g, &p->err)
                   : fit_geometry_pick(scan, &rn->o->fit, g, &p->err)))
        return;
    r = g->r;
    if (!rn->o->geometry_map_only && !(g->flags & FIT_GEOMETRY_UNUSABLE)) {
        /* refined under the kriged model; where that fails, the r x r fit's geometry stays and
         * the document says why (kriged_error) */
        fit_geometry_t rg = *g;
        err_t ke;
        int krc = fit_geometry_krige(scan, &rg, &rn->o->fit, g, &ke);
        if (krc == -ECANCELED || krc == -ENOMEM) {
            p->rc = err_set(&p->err, krc, "%s", ke.msg);
            return;
        }
        if (krc || (g->flags & FIT_GEOMETRY_UNUSABLE)) {
            unsigned bad = g->flags;
            *g = rg;
            if (krc) snprintf(g->kriged_error, sizeof g->kriged_error, "%s", ke.msg);
            else
                snprintf(g->kriged_error, sizeof g->kriged_error,
                         "the kriged refinement was %s; the r x r map's geometry is kept",
                         fit_geometry_status(bad));
        }
    }
    if (g->flags & FIT_GEOMETRY_UNUSABLE) { /* poor_fit alone: used, and said in its status */
        p->rc = err_set(&p->err, -EDOM,
                        "geometry fit at r = %d: %s (R %.4g um, dx %.4g um, dy %.4g um after %d "
                        "iterations); the written geometry is used",
                        r, fit_geometry_status(g->flags), g->R_um, g->dx_um, g->dy_um,
                        g->iterations);
        return;
    }
    size_t n = scan->n, nw = rn->whole->n;
    rn->geo_xy = malloc(sizeof(double) * 2 * (n + nw + 1));
    if (!rn->geo_xy) {
        p->rc = err_set(&p->err, -ENOMEM, "geometry: out of memory");
        return;
    }
    /* the region was chosen on the written positions; the Wiener baseline, which takes every
     * point, gets the fitted geometry too (its kernel radius and its grid) */
    double *x = rn->geo_xy, *y = x + n, *xw = y + n, *yw = xw + nw;
    fit_geometry_apply(scan, g, x, y, &rn->geo_scan);
    fit_geometry_apply(rn->whole, g, xw, yw, &rn->geo_whole);
    rn->scan = &rn->geo_scan;
    rn->whole = &rn->geo_whole;
}

/* The best-AIC map on an n x n grid; none (interp_r 0) when no fit has a map. */
static void interp_step(struct run *rn)
{
    fit_pipeline_t *out = rn->out;
    const fit_sweep_t *sw = &out->sweep;
    fit_part_t *p = &out->interp_part;
    int r = sw->best_aic, n = rn->o->interp_n;
    out->interp_n = n;
    if (!r) return;
    out->interp = malloc(sizeof(double) * (size_t)n * (size_t)n);
    if (!out->interp) {
        p->rc = err_set(&p->err, -ENOMEM, "interp: out of memory for a %d x %d grid", n, n);
        return;
    }
    p->rc = fit_interp_bicubic(sw->fits[r - sw->r_min].S, r, n, out->interp, &p->err);
    if (p->rc) {
        free(out->interp);
        out->interp = NULL;
        return;
    }
    out->interp_r = r;
}

/* Runs an optional part as one step, timed into its fit_part_t. A part stopped inside (its rc
 * -ECANCELED) stops the run: it is not a failed part. */
static int part_step(struct run *rn, fit_step_kind_t kind, int r, fit_part_t *p,
                     void (*body)(struct run *), err_t *err)
{
    fit_step_t step;
    int rc = step_begin(rn, kind, r, &step, err);
    if (rc) return rc;
    p->asked = 1;
    double t = clock_mono_ms();
    body(rn);
    p->ms = clock_mono_ms() - t;
    if (p->rc == -ECANCELED)
        return err_set(err, -ECANCELED, "fit stopped during the %s", fit_step_name(kind));
    step_end(rn, &step);
    return 0;
}

/* The recommended map shrunk toward r - 1 (shrink.h) into sw->shrunk, when there is one. */
static int keep_shrunk(struct run *rn, fit_sweep_t *sw, double noise_scale, err_t *err)
{
    fit_shrunk_t s;
    int rc = fit_shrink_recommended(rn->scan, &rn->o->fit, sw, noise_scale, &s, err);
    if (rc || s.r == 0) return rc;
    if (!(sw->shrunk = malloc(sizeof *sw->shrunk))) {
        fit_shrunk_free(&s);
        return err_set(err, -ENOMEM, "out of memory");
    }
    *sw->shrunk = s;
    return 0;
}

/* The kriged map with the sweep's prior (krige.h, fit_krige_prior_for_sweep) into sw->kriged;
 * a scan it cannot serve (too many points, no signal) leaves it NULL with the reason in
 * rn->out->kriged_error. */
static int keep_kriged(struct run *rn, fit_sweep_t *sw, err_t *err)
{
    fit_kriged_t k;
    err_t e;
    fit_krige_prior_t pr = fit_krige_prior_for_sweep(sw);
    int rc = fit_krige_with(rn->scan, &pr, &rn->o->fit, &k, &e);
    if (rc == -EINVAL || rc == -EDOM) {
        snprintf(rn->out->kriged_error, sizeof rn->out->kriged_error, "%s", e.msg);
        return 0;
    }
    if (rc) return err_set(err, rc, "%s", e.msg);
    /* a mixture that cannot be had leaves the map without it (mix_n 0) */
    if (rn->o->krige_mix && (rc = fit_krige_mix(rn->scan, &k, &rn->o->fit, &e)) &&
        (rc == -ENOMEM || rc == -ECANCELED)) {
        fit_kriged_free(&k);
        return err_set(err, rc, "%s", e.msg);
    }
    if (!(sw->kriged = malloc(sizeof *sw->kriged))) {
        fit_kriged_free(&k);
        return err_set(err, -ENOMEM, "out of memory");
    }
    *sw->kriged = k;
    return 0;
}

static int run_steps(struct run *rn, err_t *err)
{
    const fit_pipeline_opts_t *o = rn->o;
    fit_pipeline_t *out = rn->out;
    fit_sweep_t *sw = &out->sweep;
    sw->fits = calloc((size_t)(o->r_max - o->r_min + 1), sizeof *sw->fits);
    if (!sw->fits) return err_set(err, -ENOMEM, "out of memory");
    if (o->fit_geometry) {
        int rc = part_step(rn, FIT_STEP_GEOMETRY, o->geometry_r, &out->geometry_part,
                           geometry_step, err);
        if (rc) return rc;
    }
    const fit_watch_t *w = rn->watch;
    int watched = w && (w->progress || w->stop || w->poll || w->poll_at);
    int by_parfor = o->threads >= 1 && o->r_max > o->r_min && !watched;
    if (by_parfor) {
        int rc = sweep_threads(rn, err);
        if (rc) return rc;
    }
    for (int r = by_parfor ? o->r_max + 1 : o->r_min; r <= o->r_max; r++) {
        fit_step_t step;
        int rc = step_begin(rn, FIT_STEP_SWEEP, r, &step, err);
        if (rc) return rc;
        double t = clock_mono_ms();
        if ((rc = sweep_step(rn, r, err))) return rc;
        out->sweep_ms += clock_mono_ms() - t;
        step_end(rn, &step);
    }
    fit_recommendation_t rec;
    fit_recommend(sw, NULL, &rec);
    sw->recommended_r = rec.r;
    sw->range_edge = rec.range_edge;
    memcpy(sw->recommended_reason, rec.reason, sizeof sw->recommended_reason);
    int rc = keep_shrunk(rn, sw, rec.noise_scale, err);
    if (rc == 0 && o->krige && rec.r > 0) rc = keep_kriged(rn, sw, err);
    else if (rc == 0 && o->krige)
        snprintf(rn->out->kriged_error, sizeof rn->out->kriged_error,
                 "no recommended r: no fit has a map to trust");
    if (rc) return rc;
    if (o->ftest_edges)
        rc = part_step(rn, FIT_STEP_FTEST, o->ftest_r, &out->ftest_part, ftest_step, err);
    if (rc == 0 && o->wiener)
        rc = part_step(rn, FIT_STEP_WIENER, 0, &out->wiener_part, wiener_step, err);
    if (rc == 0 && o->interp_n)
        rc = part_step(rn, FIT_STEP_INTERP, sw->best_aic, &out->interp_part, interp_step, err);
    return rc;
}

int fit_pipeline_run(const fit_scan_t *scan, const fit_pipeline_opts_t *opts,
                     const fit_watch_t *watch, fit_pipeline_t *out, err_t *err)
{
    fit_gsl_policy();
    memset(out, 0, sizeof *out);
    fit_pipeline_opts_t o = opts ? *opts : fit_pipeline_opts_default();
    if (watch && watch->poll) /* every step's long loops poll the watch (stop.h) */
        o.fit.stop = (fit_stop_t){.poll = watch->poll, .arg = watch->params,
                                  .poll_at = watch->poll_at};
    int rc = check_opts(scan, &o, err);
    if (rc) return rc;
    double t0 = clock_mono_ms();
    fit_scan_sel_t sel;
    if ((rc = fit_region_select(scan, &o.region, &sel, err))) return rc;
    out->sweep.r_min = o.r_min;
    out->sweep.r_max = o.r_max;
    out->region = o.region;
    out->n_region = sel.scan.n;
    /* one sweep cache for the run's design matrices (design.h): every r and the F-test share
     * their edge lines' sweeps; without memory for it the fits just build their own */
    fit_design_cache_t *cache = o.fit.design_cache ? NULL : fit_design_cache_new();
    if (cache) o.fit.design_cache = cache;
    struct run rn = {.scan = &sel.scan, .whole = scan, .o = &o, .watch = watch, .out = out,
                     .total = o.r_max - o.r_min + 1 + (o.ftest_edges != 0) + (o.wiener != 0) +
                              (o.interp_n != 0) + (o.fit_geometry != 0),
                     .best_aic = INFINITY, .best_bic = INFINITY};
    rc = run_steps(&rn, err);
    fit_design_cache_free(cache);
    fit_scan_sel_free(&sel);
    free(rn.geo_xy);
    if (rc) {
        fit_pipeline_free(out); /* stopped or failed: nothing half-built is handed back */
        return rc;
    }
    out->total_ms = clock_mono_ms() - t0;
    return 0;
}

void fit_pipeline_free(fit_pipeline_t *pl)
{
    if (!pl) return;
    fit_sweep_free(&pl->sweep);
    fit_wiener_free(&pl->wiener);
    free(pl->interp);
    memset(pl, 0, sizeof *pl);
}
