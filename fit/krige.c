/* krige.c: the kriged map (krige.h): the set-up of its likelihood problem (the fine grid's and the
 * prior grids' designs), the two models (with and without the smooth part), the likelihood-ratio
 * test between them and the posterior of the one kept. The likelihood and its maximisation are
 * krige_lik.c and krige_opt.c; each model is evaluated in the points' space or in the fine
 * cells' space, whichever costs less (krige_int.h), so that many points cost no more than the
 * fine grid's cells do. */
#include "fit/krige.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "fit/gslerr.h"
#include "gemm.h"
#include "krige_int.h"
#include "points.h"

/* Starts of the search: (log variance of the grids, of the smooth part, log l in pitches).
 * Equal variances (sd 0.05 of the mean, l a fifth of the pitch) find the optimum where both parts
 * carry structure; a smooth tilt whose best fit has no piecewise part lies in another basin,
 * reached from the second (docs/numerics.md "The kriged map"). The model without the smooth part
 * takes the first only. */
static const double starts[][3] = {{-6, -6, -1.6}, {-20, -6, 0}};

fit_krige_prior_t fit_krige_prior_divisors(int r)
{
    fit_krige_prior_t p = {.r = r};
    for (int q = 2; q <= r && p.n_grids < FIT_KRIGE_MAX_LEVELS; q++)
        if (r % q == 0) p.grids[p.n_grids++] = q;
    return p;
}

/* The fraction of fine cell i (of F) that lies in cell e of a q-grid, along one axis. */
static double overlap(int i, int F, int e, int q)
{
    double lo = fmax((double)i / F, (double)e / q), hi = fmin((double)(i + 1) / F, (double)(e + 1) / q);
    return hi > lo ? (hi - lo) * F : 0;
}

/* B (m x q^2): each fine cell's fraction in each of the q-grid's cells. */
static void grid_spread(int F, int q, double *B)
{
    size_t qq = (size_t)q * q;
    for (int y = 0; y < F; y++)
        for (int x = 0; x < F; x++)
            for (int ey = 0; ey < q; ey++)
                for (int ex = 0; ex < q; ex++)
                    B[((size_t)y * F + x) * qq + (size_t)ey * q + ex] =
                        overlap(y, F, ey, q) * overlap(x, F, ex, q);
}

/* The prior grid q's design (n x q^2): the fine grid's columns summed per q-cell when q divides
 * F (exact), else built for q itself. */
static int grid_design(const fit_scan_t *scan, const fit_points_t *pt, const double *A, int F, int q,
                       const fit_design_opts_t *dopt, double *Aq, err_t *err)
{
    size_t n = pt->n, m = (size_t)F * F, qq = (size_t)q * q;
    if (F % q) return fit_design_build(scan->spot_radius_um, scan->pitch_um, q, pt->x, pt->y, n,
                                       dopt, Aq, NULL, err);
    int f = F / q;
    for (size_t p = 0; p < n; p++) {
        double *cell = Aq + p * qq;
        const double *row = A + p * m;
        memset(cell, 0, sizeof(double) * qq);
        for (int j = 0; j < F; j++)
            for (int i = 0; i < F; i++) cell[(j / f) * q + i / f] += row[j * F + i];
    }
    return 0;
}

/* Whether the cells' space is the cheaper for a model: its p^3 factorisation against the points'
 * n^3 and, with the smooth part, the three n^2 m products a change of l costs there. */
static int cells_cheaper(size_t n, size_t m, size_t p, int smooth)
{
    double dn = (double)n, cost_points = dn * dn * dn / 3 + (smooth ? 3 * dn * dn * (double)m : 0);
    double dp = (double)p, cost_cells = dp * dp * dp;
    return cost_cells < cost_points;
}

/* Whether every grid's variance is below the second start's (sd 4.5e-5 of the mean): the
 * piecewise part is gone. */
static int grids_negligible(const kr_prob_t *k, const double *th)
{
    for (int j = 0; j < k->nl; j++)
        if (th[j] > starts[1][0]) return 0;
    return 1;
}

/* The best of the starts for the model in k; th gets its optimum, and the state is left there
 * (value and derivatives, for the posterior). */
double kr_best_of_starts(kr_prob_t *k, int n_starts, double *th)
{
    int np = kr_theta_count(k);
    double best = HUGE_VAL, t[KR_MAX_THETA];
    int best_s = -1;
    for (int s = 0; s < n_starts && !k->stopped; s++) {
        /* the second start looks for an optimum without a piecewise part: when the first found
         * one, there is nothing else to look for */
        if (s == 1 && best_s == 0 && grids_negligible(k, th)) break;
        double st[KR_MAX_THETA];
        for (int i = 0; i < np; i++)
            st[i] = i < k->nl ? starts[s][0] : i == k->nl ? starts[s][1] : starts[s][2];
        double f = kr_maximise(k, st, t);
        if (isfinite(f) && f < best) best = f, best_s = s, memcpy(th, t, sizeof(double) * (size_t)np);
    }
    if (best_s >= 0 && best_s != n_starts - 1 && !k->stopped) { /* back to the best one's state */
        double g[KR_MAX_THETA], AI[KR_MAX_THETA * KR_MAX_THETA];
        if (!isfinite(kr_value(k, th)) || kr_derivs(k, th, g, AI)) return HUGE_VAL;
    }
    return best;
}

/* Without the smooth part the map is the grids' posterior mean m0, piecewise, and that model's
 * S_err sees nothing inside the grids' cells. The smooth model was not rejected as wrong, only as
 * unnecessary, so S_err becomes the expected squared error of m0 under the smooth model's
 * posterior N(m1, C1): sqrt(C1 + (m1 - m0)^2) per fine cell (its second moment about m0;
 * docs/numerics.md "The kriged map's S_err without the smooth part"). k1 is the smooth model at
 * its optimum th1. */
static int widen_by_smooth_model(kr_prob_t *k1, const double *th1, const double *const *Bq,
                                 fit_kriged_t *out)
{
    size_t m = k1->m;
    double *S1 = malloc(sizeof(double) * m), *E1 = malloc(sizeof(double) * m), g[KR_MAX_THETA],
           AI[KR_MAX_THETA * KR_MAX_THETA];
    int rc = -ENOMEM;
    if (!S1 || !E1) goto out;
    rc = -EDOM;
    if ((!k1->at_valid || memcmp(k1->at, th1, sizeof(double) * (size_t)kr_theta_count(k1))) &&
        (!isfinite(kr_value(k1, th1)) || kr_derivs(k1, th1, g, AI)))
        goto out;
    if ((rc = kr_posterior(k1, th1, Bq, S1, E1))) goto out;
    for (size_t i = 0; i < m; i++) {
        double dm = S1[i] - out->S[i];
        out->S_err[i] = sqrt(E1[i] * E1[i] + dm * dm);
    }
out:
    free(S1), free(E1);
    return k1->stopped ? -ECANCELED : rc;
}

static int check_prior(const fit_krige_prior_t *pr, err_t *err)
{
    if (pr->r < 1 || pr->r > 32) return err_set(err, -EINVAL, "r must be between 1 and 32 (got %d)", pr->r);
    if (pr->n_grids < 0 || pr->n_grids > FIT_KRIGE_MAX_LEVELS)
        return err_set(err, -EINVAL, "the kriged map's prior takes 0 to %d grids (got %d)",
                       FIT_KRIGE_MAX_LEVELS, pr->n_grids);
    for (int j = 0; j < pr->n_grids; j++) {
        if (pr->grids[j] < 2 || pr->grids[j] > 32)
            return err_set(err, -EINVAL, "a prior grid must be between 2 and 32 (got %d)", pr->grids[j]);
        for (int i = 0; i < j; i++)
            if (pr->grids[i] == pr->grids[j])
                return err_set(err, -EINVAL, "prior grid %d given twice", pr->grids[j]);
    }
    return 0;
}

/* Everything fit_krige_with allocates (krige_int.h). */
struct kr_work {
    fit_points_t pt;
    double *s2, *A, *one, *Aq[FIT_KRIGE_MAX_LEVELS], *Bq[FIT_KRIGE_MAX_LEVELS],
        *Mq[FIT_KRIGE_MAX_LEVELS];
    kr_prob_t k1, k0;
    fit_options_t o; /* the options the problems point into (their stop) */
    int F;
};

void kr_work_free(kr_work_t *w)
{
    if (!w) return;
    fit_points_free(&w->pt);
    free(w->s2), free(w->A), free(w->one);
    for (int j = 0; j < FIT_KRIGE_MAX_LEVELS; j++) free(w->Aq[j]), free(w->Bq[j]), free(w->Mq[j]);
    kr_prob_free(&w->k1);
    kr_prob_free(&w->k0);
    free(w);
}

kr_prob_t *kr_work_model(kr_work_t *w, int smooth)
{
    return smooth ? &w->k1 : &w->k0;
}

const double *const *kr_work_spread(const kr_work_t *w)
{
    return (const double *const *)w->Bq;
}

/* The two problems' common set-up: points, designs, I0, the grids' matrices. */
static int setup(const fit_scan_t *scan, const fit_krige_prior_t *pr, const fit_options_t *o,
                 int force_cells, struct kr_work *w, int F, err_t *err)
{
    size_t nonfinite, saturated, m = (size_t)F * F;
    if (fit_points_select(scan, o->noise, &w->pt, &nonfinite, &saturated))
        return err_set(err, -ENOMEM, "out of memory for the kriged map");
    size_t n = w->pt.n;
    if (n < 3) return err_set(err, -EINVAL, "the kriged map needs at least 3 usable points (got %zu)", n);
    if (!(w->s2 = malloc(sizeof(double) * n)) || !(w->A = malloc(sizeof(double) * n * m)) ||
        !(w->one = malloc(sizeof(double) * n)))
        return err_set(err, -ENOMEM, "out of memory for the kriged map");
    for (size_t i = 0; i < n; i++) w->s2[i] = w->pt.sigma[i] * w->pt.sigma[i];
    fit_design_opts_t dopt = fit_design_opts_for_tol(o->design_tol > 0 ? o->design_tol : 1e-12);
    dopt.cache = o->design_cache;
    dopt.stop = o->stop;
    int rc = fit_design_build(scan->spot_radius_um, scan->pitch_um, F, w->pt.x, w->pt.y, n, &dopt,
                              w->A, NULL, err);
    if (rc) return rc;
    double sw = 0, swd = 0; /* I0: the weighted least-squares flat map, the variances' scale */
    for (size_t i = 0; i < n; i++) {
        w->one[i] = 0;
        for (size_t c = 0; c < m; c++) w->one[i] += w->A[i * m + c];
        sw += w->one[i] * w->one[i] / w->s2[i];
        swd += w->one[i] * w->pt.d[i] / w->s2[i];
    }
    double I0 = swd / sw;
    if (!(I0 > 0) || !isfinite(I0))
        return err_set(err, -EINVAL, "no signal for the kriged map (flat fit %g)", I0);
    for (int j = 0; j < pr->n_grids; j++) {
        int q = pr->grids[j];
        size_t qq = (size_t)q * q;
        if (!(w->Aq[j] = malloc(sizeof(double) * n * qq)) || !(w->Bq[j] = malloc(sizeof(double) * m * qq)))
            return err_set(err, -ENOMEM, "out of memory for the kriged map");
        if ((rc = grid_design(scan, &w->pt, w->A, F, q, &dopt, w->Aq[j], err))) return rc;
        grid_spread(F, q, w->Bq[j]);
    }
    kr_prob_t base = {.n = n, .m = m, .F = F, .d = w->pt.d, .s2 = w->s2, .A = w->A,
                      .one = w->one, .I0 = I0, .nl = pr->n_grids, .stop = &o->stop};
    size_t pq = 1;
    for (int j = 0; j < pr->n_grids; j++) {
        base.q[j] = pr->grids[j];
        base.Aq[j] = w->Aq[j];
        pq += (size_t)pr->grids[j] * pr->grids[j];
    }
    w->k1 = base, w->k0 = base;
    w->k1.smooth = 1;
    w->k1.cells = force_cells >= 0 ? force_cells : cells_cheaper(n, m, pq + m, 1);
    w->k0.cells = force_cells >= 0 ? force_cells : cells_cheaper(n, m, pq, 0);
    if (!w->k1.cells || !w->k0.cells) /* the grids' n x n matrices, shared */
        for (int j = 0; j < pr->n_grids; j++) {
            size_t qq = (size_t)pr->grids[j] * pr->grids[j];
            if (!(w->Mq[j] = malloc(sizeof(double) * n * n)))
                return err_set(err, -ENOMEM, "out of memory for the kriged map");
            fit_gemm(w->Aq[j], 0, w->Aq[j], 1, n, qq, n, I0 * I0, 0, w->Mq[j]);
            w->k1.Mq[j] = w->k0.Mq[j] = w->Mq[j];
        }
    if (kr_prob_init(&w->k1) || kr_prob_init(&w->k0))
        return err_set(err, -ENOMEM, "out of memory for the kriged map");
    return 0;
}

int kr_work_new(const fit_scan_t *scan, const fit_krige_prior_t *pr, const fit_options_t *opts,
                int force_cells, kr_work_t **out, err_t *err)
{
    *out = NULL;
    int rc = check_prior(pr, err);
    if (rc || (rc = fit_scan_check(scan, err))) return rc;
    fit_options_t o = opts ? *opts : fit_options_default();
    kr_work_t *w = calloc(1, sizeof *w); /* ~130 KB: the kernels' tables */
    if (!w) return err_set(err, -ENOMEM, "out of memory for the kriged map");
    w->o = o;
    w->F = pr->r * ((FIT_KRIGE_CELLS + pr->r - 1) / pr->r);
    if ((rc = setup(scan, pr, &w->o, force_cells, w, w->F, err))) {
        kr_work_free(w);
        return rc;
    }
    *out = w;
    return 0;
}

/* The planner's covariance of S (fit_krige_with_cov): the smooth model's posterior covariance,
 * plus (m1 - m0)(m1 - m0)^T about the map kept when the smooth part was dropped, so that its
 * diagonal is S_err^2 as widen_by_smooth_model makes it; the kept model's own otherwise. */
static int planning_cov(kr_prob_t *k, const double *th, kr_prob_t *k1, const double *th1,
                        int use_k1, const double *const *Bq, fit_kriged_t *out)
{
    size_t m = k->m;
    double *S1 = malloc(sizeof(double) * m), g[KR_MAX_THETA], AI[KR_MAX_THETA * KR_MAX_THETA];
    int rc = -ENOMEM;
    if (!S1 || !(out->S_cov = malloc(sizeof(double) * m * m))) goto out;
    rc = -EDOM;
    if (use_k1 && (!k1->at_valid || memcmp(k1->at, th1, sizeof(double) * (size_t)kr_theta_count(k1))) &&
        (!isfinite(kr_value(k1, th1)) || kr_derivs(k1, th1, g, AI)))
        goto out;
    if ((rc = kr_posterior_cov(use_k1 ? k1 : k, use_k1 ? th1 : th, Bq, S1, out->S_cov))) goto out;
    for (size_t i = 0; use_k1 && i < m; i++)
        for (size_t j = 0; j < m; j++) out->S_cov[i * m + j] += (S1[i] - out->S[i]) * (S1[j] - out->S[j]);
out:
    free(S1);
    return rc;
}

static int krige_run(const fit_scan_t *scan, const fit_krige_prior_t *pr,
                     const fit_options_t *opts, int want_cov, fit_kriged_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    out->length_um = NAN;
    fit_gsl_policy();
    double t0 = clock_mono_ms();
    kr_work_t *w;
    int rc = kr_work_new(scan, pr, opts, -1, &w, err);
    if (rc) return rc;
    int F = w->F;
    double th1[KR_MAX_THETA] = {0}, th0[KR_MAX_THETA] = {0};
    kr_prob_t *k1 = &w->k1, *k0 = &w->k0;
    /* with the smooth part, then without; keep the smaller model unless the ratio is large */
    double f1 = kr_best_of_starts(k1, 2, th1);
    double f0 = kr_best_of_starts(k0, 1, th0);
    if (k1->stopped || k0->stopped) {
        rc = err_set(err, -ECANCELED, "kriged map stopped");
        goto out;
    }
    if (!isfinite(f0) && !isfinite(f1)) {
        rc = err_set(err, -EDOM, "the kriged map's likelihood could not be evaluated");
        goto out;
    }
    out->lr = isfinite(f1) && isfinite(f0) ? fmax(2 * (f0 - f1), 0) : isfinite(f1) ? INFINITY : 0;
    int smooth = out->lr >= FIT_KRIGE_LR;
    kr_prob_t *k = smooth ? k1 : k0;
    const double *th = smooth ? th1 : th0;
    out->grid = F;
    out->r = pr->r;
    out->smooth = smooth;
    out->cells = k1->cells;
    out->log_lik = -(smooth ? f1 : f0);
    out->n_levels = pr->n_grids;
    for (int j = 0; j < pr->n_grids; j++) {
        out->level_q[j] = pr->grids[j];
        out->level_sd[j] = sqrt(exp(th[j]));
    }
    if (smooth) {
        out->amplitude = sqrt(exp(th[k->nl]));
        out->length_um = exp(th[k->nl + 1]) * scan->pitch_um;
    }
    size_t m = (size_t)F * F;
    if (!(out->S = malloc(sizeof(double) * m)) || !(out->S_err = malloc(sizeof(double) * m))) {
        rc = err_set(err, -ENOMEM, "out of memory for the kriged map");
        goto out;
    }
    const double *const *Bq = (const double *const *)w->Bq;
    if ((rc = kr_posterior(k, th, Bq, out->S, out->S_err)) ||
        (!smooth && isfinite(f1) && (rc = widen_by_smooth_model(k1, th1, Bq, out))) ||
        (want_cov && (rc = planning_cov(k, th, k1, th1, !smooth && isfinite(f1), Bq, out)))) {
        rc = rc == -ENOMEM    ? err_set(err, rc, "out of memory")
             : rc == -ECANCELED ? err_set(err, rc, "kriged map stopped")
                                : err_set(err, rc, "the kriged map's posterior failed");
        goto out;
    }
    out->evaluations = k1->evals + k0->evals;
    out->ms = clock_mono_ms() - t0;
out:
    if (rc) fit_kriged_free(out);
    kr_work_free(w);
    return rc;
}

int fit_krige_with(const fit_scan_t *scan, const fit_krige_prior_t *pr,
                   const fit_options_t *opts, fit_kriged_t *out, err_t *err)
{
    return krige_run(scan, pr, opts, 0, out, err);
}

int fit_krige_with_cov(const fit_scan_t *scan, const fit_krige_prior_t *pr,
                       const fit_options_t *opts, fit_kriged_t *out, err_t *err)
{
    return krige_run(scan, pr, opts, 1, out, err);
}

int fit_krige(const fit_scan_t *scan, int r, const fit_options_t *opts, fit_kriged_t *out,
              err_t *err)
{
    fit_krige_prior_t pr = fit_krige_prior_divisors(r < 1 || r > 32 ? 1 : r);
    pr.r = r;
    return fit_krige_with(scan, &pr, opts, out, err);
}

void fit_kriged_free(fit_kriged_t *k)
{
    if (!k) return;
    free(k->S);
    free(k->S_err);
    free(k->S_cov);
    k->S = k->S_err = k->S_cov = NULL;
    k->grid = 0;
}
