/* adapt_plan.c: one planning step of an adaptive scan (adapt_plan.h): the kriged map of the points
 * so far with its posterior covariance Sigma, its expected rms error under the neighbouring priors
 * (krige.h, fit_krige_mix), the stop rule (the first plan at the target), the candidates' design rows a_j (kept from
 * plan to plan in a fit_adapt_cache_t while the grid stays) and variances s_j^2 = sigma(B + I0 a_j^T S)^2 / I0^2, the greedy batch (adapt.h) and its travel
 * order (adapt_order.c); and the starting raster and the candidate lattice. */
#include "fit/adapt_plan.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "fit/adapt.h"
#include "fit/design.h"
#include "fit/noise.h"

fit_adapt_opts_t fit_adapt_opts_default(void)
{
    fit_adapt_opts_t o = {.fit = fit_options_default(),
                          .r_max = 8,
                          .region = {.kind = FIT_REGION_INSIDE},
                          .box_um = {-INFINITY, INFINITY, -INFINITY, INFINITY},
                          .lattice = FIT_ADAPT_LATTICE,
                          .batch = FIT_ADAPT_BATCH,
                          .target_err = FIT_ADAPT_TARGET_ERR,
                          .max_points = FIT_ADAPT_MAX_POINTS,
                          .start_points = FIT_ADAPT_START_GRID * FIT_ADAPT_START_GRID};
    o.fit.noise = FIT_NOISE_SHOT_READ;
    return o;
}

const char *fit_adapt_stop_name(fit_adapt_stop_t s)
{
    switch (s) {
    case FIT_ADAPT_GO: return "go";
    case FIT_ADAPT_TARGET: return "target";
    case FIT_ADAPT_BUDGET: return "budget";
    case FIT_ADAPT_NO_GAIN: return "no_gain";
    }
    return "unknown";
}

static int in_box(const double *box, double x, double y)
{
    return !box || (x >= box[0] && x <= box[1] && y >= box[2] && y <= box[3]);
}

int fit_adapt_start(double pitch_um, int n0, const double *box_um, double *x, double *y)
{
    if (n0 < 1 || !(pitch_um > 0) || !isfinite(pitch_um)) return -EINVAL;
    int k = 0;
    for (int j = 0; j < n0; j++)
        for (int i0 = 0; i0 < n0; i0++) {
            int i = j % 2 ? n0 - 1 - i0 : i0; /* odd rows right to left */
            double px = (i + 0.5) * pitch_um / n0, py = (j + 0.5) * pitch_um / n0;
            if (!in_box(box_um, px, py)) continue;
            x[k] = px, y[k++] = py;
        }
    return k;
}

long fit_adapt_candidates(double pitch_um, const fit_adapt_opts_t *o, double **x, double **y)
{
    *x = *y = NULL;
    int L = o->lattice;
    if (L < 2 || L > FIT_ADAPT_LATTICE_MAX || !(pitch_um > 0) || !isfinite(pitch_um))
        return -EINVAL;
    double h = pitch_um / L;
    int lo = 0, hi = L; /* inside and all: the pixel and its edges; a margin reaches beyond */
    if (o->region.kind == FIT_REGION_MARGIN) {
        int k = (int)fmin(ceil(o->region.margin_um / h), FIT_ADAPT_LATTICE_MAX);
        lo -= k, hi += k;
    }
    size_t side = (size_t)(hi - lo + 1);
    if (!(*x = malloc(sizeof(double) * side * side)) || !(*y = malloc(sizeof(double) * side * side))) {
        free(*x), free(*y);
        *x = *y = NULL;
        return -ENOMEM;
    }
    long n = 0;
    for (int j = lo; j <= hi; j++)
        for (int i = lo; i <= hi; i++) {
            double px = i * pitch_um / L, py = j * pitch_um / L;
            if (!fit_region_contains(&o->region, pitch_um, px, py) || !in_box(o->box_um, px, py))
                continue;
            (*x)[n] = px, (*y)[n++] = py;
        }
    return n;
}

static int check_opts(const fit_adapt_opts_t *o, err_t *err)
{
    if (o->r_max < 1 || o->r_max > 32)
        return err_set(err, -EINVAL, "adaptive plan: r_max must be 1..32 (got %d)", o->r_max);
    if (o->lattice < 2 || o->lattice > FIT_ADAPT_LATTICE_MAX)
        return err_set(err, -EINVAL, "adaptive plan: lattice must be 2..%d (got %d)",
                       FIT_ADAPT_LATTICE_MAX, o->lattice);
    if (o->batch < 1) return err_set(err, -EINVAL, "adaptive plan: batch must be >= 1 (got %d)", o->batch);
    if (!(o->target_err > 0) || !isfinite(o->target_err))
        return err_set(err, -EINVAL, "adaptive plan: target_err must be > 0 (got %g)", o->target_err);
    if (isnan(o->box_um[0]) || isnan(o->box_um[1]) || isnan(o->box_um[2]) || isnan(o->box_um[3]) ||
        o->box_um[0] > o->box_um[1] || o->box_um[2] > o->box_um[3])
        return err_set(err, -EINVAL, "adaptive plan: the allowed box [%g, %g] x [%g, %g] is empty",
                       o->box_um[0], o->box_um[1], o->box_um[2], o->box_um[3]);
    return 0;
}

/* I0 (DN per unit-peak flux) of the recommended fit, else of the flat one: what turns the map's
 * prediction into a signal. NaN when neither has a map. */
static double sweep_I0(const fit_sweep_t *sw)
{
    int r = sw->recommended_r;
    if (r >= sw->r_min && r <= sw->r_max && sw->fits[r - sw->r_min].S)
        return sw->fits[r - sw->r_min].I0;
    return sw->r_min == 1 && sw->fits[0].S ? sw->fits[0].I0 : NAN;
}

void fit_adapt_cache_free(fit_adapt_cache_t *c)
{
    if (!c) return;
    free(c->cx), free(c->cy), free(c->A);
    memset(c, 0, sizeof *c);
}

/* The nc candidates' (cx, cy) design rows on the F x F grid into A (nc x F^2): the cache's when
 * it holds the same ones, else built, and then kept in the cache (a cache that cannot take them
 * is emptied, not an error). */
static int candidate_rows(const fit_scan_t *scan, const fit_adapt_opts_t *o, int F,
                          const double *cx, const double *cy, long nc, fit_adapt_cache_t *cache,
                          double *A, err_t *err)
{
    size_t m = (size_t)F * F, bytes = sizeof(double) * m * (size_t)nc;
    double tol = o->fit.design_tol > 0 ? o->fit.design_tol : 1e-12;
    if (cache && cache->A && cache->grid == F && cache->nc == nc &&
        cache->radius_um == scan->spot_radius_um && cache->pitch_um == scan->pitch_um &&
        cache->tol == tol && !memcmp(cache->cx, cx, sizeof(double) * (size_t)nc) &&
        !memcmp(cache->cy, cy, sizeof(double) * (size_t)nc)) {
        memcpy(A, cache->A, bytes);
        return 0;
    }
    fit_design_opts_t dopt = fit_design_opts_for_tol(tol);
    int rc = fit_design_build(scan->spot_radius_um, scan->pitch_um, F, cx, cy, (size_t)nc, &dopt,
                              A, NULL, err);
    if (rc || !cache) return rc;
    fit_adapt_cache_free(cache);
    double *kx = malloc(sizeof(double) * (size_t)nc), *ky = malloc(sizeof(double) * (size_t)nc),
           *kA = malloc(bytes);
    if (!kx || !ky || !kA) {
        free(kx), free(ky), free(kA);
        return 0;
    }
    memcpy(kx, cx, sizeof(double) * (size_t)nc), memcpy(ky, cy, sizeof(double) * (size_t)nc);
    memcpy(kA, A, bytes);
    *cache = (fit_adapt_cache_t){F, nc, scan->spot_radius_um, scan->pitch_um, tol, kx, ky, kA};
    return 0;
}

/* The batch: candidates' design rows and variances, the greedy pick, the travel order. */
static int pick_batch(const fit_scan_t *scan, const fit_adapt_opts_t *o, double I0,
                      const double *Sigma, fit_adapt_cache_t *cache, fit_adapt_step_t *out,
                      err_t *err)
{
    int F = out->map.grid, rc = 0;
    size_t m = (size_t)F * F;
    double *cx = NULL, *cy = NULL, *A = NULL, *s2 = NULL, *mv = NULL;
    int *picked = NULL;
    size_t *perm = NULL;
    long nc = fit_adapt_candidates(scan->pitch_um, o, &cx, &cy);
    if (nc < 0) {
        rc = err_set(err, (int)nc, "adaptive plan: no candidate lattice (%ld)", nc);
        goto out;
    }
    int batch = o->batch;
    if ((size_t)batch > o->max_points - scan->n) batch = (int)(o->max_points - scan->n);
    if (!(A = malloc(sizeof(double) * m * (size_t)(nc ? nc : 1))) ||
        !(s2 = malloc(sizeof(double) * (size_t)(nc ? nc : 1))) ||
        !(mv = malloc(sizeof(double) * (size_t)(batch + 1))) ||
        !(picked = malloc(sizeof(int) * (size_t)batch)) ||
        !(perm = malloc(sizeof(size_t) * (size_t)batch))) {
        rc = err_set(err, -ENOMEM, "adaptive plan: out of memory for %ld candidates", nc);
        goto out;
    }
    if (nc && (rc = candidate_rows(scan, o, F, cx, cy, nc, cache, A, err))) goto out;
    size_t k = 0; /* candidates kept: below full scale where the map predicts their signal */
    for (long j = 0; j < nc; j++) {
        const double *a = A + (size_t)j * m;
        double pred = 0;
        for (size_t c = 0; c < m; c++) pred += a[c] * out->map.S[c];
        double signal = scan->bias_dn + I0 * pred;
        if (scan->full_scale_dn > 0 && signal >= scan->full_scale_dn) continue;
        double sigma = fit_noise_sigma(o->fit.noise, scan, signal);
        if (!(sigma >= 0) || !isfinite(sigma)) continue;
        if (k != (size_t)j) memmove(A + k * m, a, sizeof(double) * m);
        cx[k] = cx[j], cy[k] = cy[j];
        s2[k++] = sigma * sigma / (I0 * I0);
    }
    int n = fit_adapt_pick(m, Sigma, k, A, s2, batch, picked, mv, err);
    if (n < 0) {
        rc = n;
        goto out;
    }
    if (n == 0) {
        out->stop = FIT_ADAPT_NO_GAIN;
        goto out;
    }
    double *bx = malloc(sizeof(double) * (size_t)n), *by = malloc(sizeof(double) * (size_t)n);
    if (!bx || !by || !(out->x_um = malloc(sizeof(double) * (size_t)n)) ||
        !(out->y_um = malloc(sizeof(double) * (size_t)n))) {
        free(bx), free(by);
        rc = err_set(err, -ENOMEM, "adaptive plan: out of memory");
        goto out;
    }
    for (int i = 0; i < n; i++) bx[i] = cx[picked[i]], by[i] = cy[picked[i]];
    double x0 = scan->pitch_um / 2, y0 = x0; /* from the last position taken */
    if (scan->n && isfinite(scan->x_um[scan->n - 1]) && isfinite(scan->y_um[scan->n - 1]))
        x0 = scan->x_um[scan->n - 1], y0 = scan->y_um[scan->n - 1];
    out->path_um = fit_adapt_order((size_t)n, bx, by, x0, y0, perm);
    for (int i = 0; i < n; i++) out->x_um[i] = bx[perm[i]], out->y_um[i] = by[perm[i]];
    free(bx), free(by);
    out->n = n;
    /* the picks lower the posterior's part; the priors' spread is held */
    out->predicted_err = sqrt(mv[n] + fmax(out->expected_err * out->expected_err -
                                           out->posterior_err * out->posterior_err, 0));
out:
    free(cx), free(cy), free(A), free(s2), free(mv), free(picked), free(perm);
    return rc;
}

int fit_adapt_plan(const fit_scan_t *scan, const fit_adapt_opts_t *opts,
                   fit_adapt_cache_t *cache, fit_adapt_step_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    out->expected_err = out->posterior_err = out->predicted_err = out->path_um = NAN;
    double t0 = clock_mono_ms();
    fit_adapt_opts_t o = opts ? *opts : fit_adapt_opts_default();
    int rc = check_opts(&o, err);
    if (rc || (rc = fit_scan_check(scan, err))) return rc;
    fit_scan_sel_t sel = {0};
    fit_sweep_t sw = {0};
    if ((rc = fit_region_select(scan, &o.region, &sel, err))) goto out;
    if ((rc = fit_sweep_run(&sel.scan, 1, o.r_max, &o.fit, &sw, err))) goto out;
    out->n_fitted = sw.fits[0].n_used;
    double I0 = sweep_I0(&sw);
    if (!(I0 > 0) || !isfinite(I0)) {
        rc = err_set(err, -EINVAL, "adaptive plan: no fit of the %zu points has a map", sel.scan.n);
        goto out;
    }
    fit_krige_prior_t pr = fit_krige_prior_for_sweep(&sw);
    out->r = pr.r;
    if ((rc = fit_krige_with_cov(&sel.scan, &pr, &o.fit, &out->map, err))) goto out;
    size_t m = (size_t)out->map.grid * out->map.grid;
    double tr = 0;
    for (size_t c = 0; c < m; c++) tr += out->map.S_cov[c * m + c];
    out->posterior_err = sqrt(fmax(tr, 0) / (double)m);
    /* the error a scan reports and stops on: under the neighbouring priors too */
    if ((rc = fit_krige_mix(&sel.scan, &out->map, &o.fit, err))) goto out;
    out->expected_err = out->map.mix_err;
    out->target_met = out->expected_err <= o.target_err;
    out->smooth = out->map.smooth;
    if (out->target_met && scan->n > o.start_points) out->stop = FIT_ADAPT_TARGET;
    else if (scan->n >= o.max_points) out->stop = FIT_ADAPT_BUDGET;
    else rc = pick_batch(scan, &o, I0, out->map.S_cov, cache, out, err);
    free(out->map.S_cov);
    out->map.S_cov = NULL;
out:
    fit_sweep_free(&sw);
    fit_scan_sel_free(&sel);
    out->ms = clock_mono_ms() - t0;
    return rc;
}

void fit_adapt_step_free(fit_adapt_step_t *s)
{
    if (!s) return;
    free(s->x_um), free(s->y_um);
    s->x_um = s->y_um = NULL;
    s->n = 0;
    fit_kriged_free(&s->map);
}
