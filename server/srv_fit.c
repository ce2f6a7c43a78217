/* srv_fit.c: the fit a fit job runs (see srv_fit.h); the same steps and JSON as `ips fit`. */
#include "server/srv_fit.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "fit/model.h"
#include "fit/wiener.h"
#include "json/fitjson.h"

void srv_fit_out_free(srv_fit_out_t *o)
{
    if (!o) return;
    json_decref(o->result);
    free(o->S);
    free(o->S_err);
    memset(o, 0, sizeof *o);
}

/* The F-test part of the document (or its error), and F / p into out. */
static json_t *ftest_part(const fit_scan_t *scan, const srv_fit_params_t *p, srv_fit_out_t *out)
{
    fit_ftest_t t;
    err_t e = {{0}};
    if (fit_ftest_run(scan, p->ftest_r, p->ftest_edges, &p->opts, &t, &e))
        return json_pack("{s:s}", "error", e.msg);
    out->f_value = t.F;
    out->p_value = t.p_value;
    return fitjson_ftest(&t);
}

static json_t *wiener_part(const fit_scan_t *scan)
{
    fit_wiener_t w;
    err_t e = {{0}};
    if (fit_wiener_run(scan, 0, &w, &e)) return json_pack("{s:s}", "error", e.msg);
    json_t *j = fitjson_wiener(&w);
    fit_wiener_free(&w);
    return j;
}

/* Copies the best-BIC map of the sweep into out (nothing when it has none). */
static int keep_map(const fit_sweep_t *sw, srv_fit_out_t *out, err_t *err)
{
    if (!sw->best_bic) return 0;
    const fit_result_t *f = &sw->fits[sw->best_bic - sw->r_min];
    if (!f->S || !f->S_err) return 0;
    size_t n = (size_t)f->r * f->r;
    out->S = malloc(n * sizeof(double));
    out->S_err = malloc(n * sizeof(double));
    if (!out->S || !out->S_err) return err_set(err, -ENOMEM, "out of memory");
    memcpy(out->S, f->S, n * sizeof(double));
    memcpy(out->S_err, f->S_err, n * sizeof(double));
    out->r = f->r;
    out->I0 = f->I0;
    out->chi2_red = f->chi2_red;
    out->status = fit_status_name(f->flags);
    return 0;
}

static int stopped(const srv_fit_hooks_t *h)
{
    return h && h->stop && atomic_load(h->stop);
}

static void progress(const srv_fit_hooks_t *h, double fraction)
{
    if (h && h->progress) h->progress(fraction, h->user);
}

/* fit_sweep_run (fit/sweep.c) r by r: the same fit_map calls and the same choice of the best r
 * (the smallest AIC / BIC among the fits with a map), so the same numbers as `ips fit`, but with
 * a stop check and progress between the fits (a large upload takes seconds per r). steps: the
 * number of progress steps of the whole job. */
static int sweep(const fit_scan_t *scan, const srv_fit_params_t *p, const srv_fit_hooks_t *h,
                 int steps, fit_sweep_t *sw, err_t *err)
{
    double best_aic = INFINITY, best_bic = INFINITY;
    *sw = (fit_sweep_t){.r_min = p->r_min, .r_max = p->r_max};
    if (p->r_min < 1 || p->r_max > 32 || p->r_min > p->r_max)
        return err_set(err, -EINVAL, "r range must satisfy 1 <= r_min <= r_max <= 32 (got %d..%d)",
                       p->r_min, p->r_max);
    sw->fits = calloc((size_t)(p->r_max - p->r_min + 1), sizeof *sw->fits);
    if (!sw->fits) return err_set(err, -ENOMEM, "out of memory");
    for (int r = p->r_min; r <= p->r_max; r++) {
        if (stopped(h)) return err_set(err, -ECANCELED, "fit stopped before r = %d", r);
        fit_result_t *f = &sw->fits[r - p->r_min];
        int rc = fit_map(scan, r, &p->opts, f, err);
        if (rc) return rc;
        progress(h, (double)(r - p->r_min + 1) / steps);
        if (!f->S) continue; /* no map: not a candidate */
        if (f->aic < best_aic) best_aic = f->aic, sw->best_aic = r;
        if (f->bic < best_bic) best_bic = f->bic, sw->best_bic = r;
    }
    return 0;
}

/* The F-test and the Wiener baseline when asked, added to the document. */
static int extras(const fit_scan_t *scan, const srv_fit_params_t *p, const srv_fit_hooks_t *h,
                  int steps, srv_fit_out_t *out, double *t_ftest, double *t_wiener, err_t *err)
{
    double t;
    int done = p->r_max - p->r_min + 1;
    if (p->ftest_edges) {
        if (stopped(h)) return err_set(err, -ECANCELED, "fit stopped before the F-test");
        t = clock_mono_ms();
        json_object_set_new(out->result, "ftest", ftest_part(scan, p, out));
        *t_ftest = clock_mono_ms() - t;
        progress(h, (double)++done / steps);
    }
    if (p->wiener) {
        if (stopped(h)) return err_set(err, -ECANCELED, "fit stopped before the Wiener baseline");
        t = clock_mono_ms();
        json_object_set_new(out->result, "wiener", wiener_part(scan));
        *t_wiener = clock_mono_ms() - t;
        progress(h, (double)++done / steps);
    }
    return 0;
}

int srv_fit_run(const fit_scan_t *scan, const srv_fit_params_t *p, const srv_fit_hooks_t *hooks,
                srv_fit_out_t *out, err_t *err)
{
    fit_sweep_t sw;
    memset(out, 0, sizeof *out);
    out->f_value = out->p_value = NAN;
    if (scan->n == 0) return err_set(err, -EINVAL, "the scan has no points inside the pixel");
    int ret = fit_scan_check(scan, err);
    if (ret) return ret;
    double t0 = clock_mono_ms(), t_ftest = 0, t_wiener = 0;
    int steps = p->r_max - p->r_min + 1 + (p->ftest_edges != 0) + (p->wiener != 0);
    ret = sweep(scan, p, hooks, steps, &sw, err);
    double t_sweep = clock_mono_ms() - t0;
    if (ret == 0) {
        out->best_aic = sw.best_aic;
        out->best_bic = sw.best_bic;
        out->result = fitjson_sweep(&sw, scan->n, &p->opts, scan->full_scale_dn);
        if (!out->result) ret = err_set(err, -ENOMEM, "out of memory encoding the fit");
    }
    if (ret == 0) ret = keep_map(&sw, out, err);
    fit_sweep_free(&sw);
    if (ret == 0) ret = extras(scan, p, hooks, steps, out, &t_ftest, &t_wiener, err);
    if (ret) return ret;
    json_object_set_new(out->result, "timing_ms",
                        json_pack("{s:f, s:f, s:f, s:f}", "sweep", t_sweep, "ftest", t_ftest,
                                  "wiener", t_wiener, "total", clock_mono_ms() - t0));
    return 0;
}
