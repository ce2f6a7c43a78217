/* shrink.c: the shrunk map (see shrink.h). */
#include "fit/shrink.h"

#include <errno.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_min.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/gslerr.h"
#include "gemm.h"

void fit_grid_overlap(int r, int q, double *w)
{
    for (int a = 0; a < r; a++)
        for (int b = 0; b < q; b++) {
            /* cells [a/r, (a+1)/r) and [b/q, (b+1)/q) of the unit pitch; the fraction of the
             * fine cell (width 1/r) the overlap covers */
            double lo = fmax((double)a / r, (double)b / q);
            double hi = fmin((double)(a + 1) / r, (double)(b + 1) / q);
            w[a * q + b] = hi > lo ? (hi - lo) * r : 0;
        }
}

int fit_grid_average(const double *v, int q, int r, double *out)
{
    double *w = malloc(sizeof(double) * (size_t)r * q);
    if (!w) return -ENOMEM;
    fit_grid_overlap(r, q, w);
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            double s = 0;
            for (int l = 0; l < q; l++) {
                if (w[j * q + l] == 0) continue;
                for (int k = 0; k < q; k++) s += w[j * q + l] * w[i * q + k] * v[l * q + k];
            }
            out[j * r + i] = s;
        }
    free(w);
    return 0;
}

/* Patterns whose noise variance is below this fraction of the largest carry no noise (the
 * constant pattern: both maps have mean 1, so D and its noise have none) */
#define NOISELESS 1e-14

/* The negative log marginal likelihood of tau^2 = exp(u) (shrink.h), constants dropped. */
struct marginal {
    const double *z2, *lam;
    size_t k;
};

static double nll(double u, void *p)
{
    const struct marginal *m = p;
    double t = exp(u), s = 0;
    for (size_t i = 0; i < m->k; i++) s += log(t + m->lam[i]) + m->z2[i] / (t + m->lam[i]);
    return 0.5 * s;
}

/* tau^2 maximising the marginal likelihood of the coordinates z2 (squared) with noise variances
 * lam; 0 when the likelihood is largest as tau^2 -> 0 (no detail above the noise). A grid in
 * log tau^2 brackets the minimum, GSL's Brent minimiser refines it. */
static double ml_tau2(const double *z2, const double *lam, size_t k)
{
    double zmax = 0, lmax = 0;
    for (size_t i = 0; i < k; i++) zmax = fmax(zmax, z2[i]), lmax = fmax(lmax, lam[i]);
    if (!(zmax > 0)) return 0;
    struct marginal m = {z2, lam, k};
    enum { GRID = 64 };
    /* from far below the smallest noise variance that matters to ten times the largest z^2 */
    double lo = log(fmax(zmax, lmax) * 1e-12), hi = log(zmax * 10), f[GRID];
    int best = 0;
    for (int i = 0; i < GRID; i++) {
        f[i] = nll(lo + (hi - lo) * i / (GRID - 1), &m);
        if (f[i] < f[best]) best = i;
    }
    if (best == 0) return 0;
    double u = lo + (hi - lo) * best / (GRID - 1);
    if (best == GRID - 1) return exp(u);
    double a = lo + (hi - lo) * (best - 1) / (GRID - 1), b = lo + (hi - lo) * (best + 1) / (GRID - 1);
    if (!(f[best] < f[best - 1] && f[best] < f[best + 1])) return exp(u); /* flat: the grid's */
    gsl_function F = {nll, &m};
    gsl_min_fminimizer *s = gsl_min_fminimizer_alloc(gsl_min_fminimizer_brent);
    if (!s || gsl_min_fminimizer_set(s, &F, u, a, b) != GSL_SUCCESS) {
        if (s) gsl_min_fminimizer_free(s);
        return exp(u);
    }
    for (int it = 0; it < 100; it++) {
        if (gsl_min_fminimizer_iterate(s) != GSL_SUCCESS) break;
        if (gsl_min_test_interval(gsl_min_fminimizer_x_lower(s), gsl_min_fminimizer_x_upper(s),
                                  1e-6, 0) == GSL_SUCCESS)
            break;
    }
    u = gsl_min_fminimizer_x_minimum(s);
    gsl_min_fminimizer_free(s);
    return exp(u);
}

int fit_shrink_with_cov(const double *Sr, int r, const double *Sq, int q, const double *Crr,
                        const double *Cqq, const double *Crq, double noise_scale,
                        fit_shrunk_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (q < 1 || q >= r)
        return err_set(err, -EINVAL, "shrinking needs a coarser fit (r = %d toward %d)", r, q);
    fit_gsl_policy();
    size_t d = (size_t)r * r, e = (size_t)q * q;
    double *w = malloc(sizeof(double) * (size_t)r * q), *P = malloc(sizeof(double) * d * e);
    double *V = malloc(sizeof(double) * d * d), *X = malloc(sizeof(double) * d * (d > e ? d : e));
    double *Gs = malloc(sizeof(double) * d * d), *lam = malloc(sizeof(double) * d);
    double *D = malloc(sizeof(double) * d), *z = malloc(sizeof(double) * d);
    double *Y = malloc(sizeof(double) * d * d);
    out->S = malloc(sizeof(double) * d);
    out->S_err = malloc(sizeof(double) * d);
    out->S_res = malloc(sizeof(double) * d);
    int rc = 0;
    if (!w || !P || !V || !X || !Gs || !lam || !D || !z || !Y || !out->S || !out->S_err ||
        !out->S_res) {
        rc = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    /* P = W (x) W: fine cell (j, i) from coarse cell (l, k) with weight w[j][l] w[i][k] */
    fit_grid_overlap(r, q, w);
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++)
            for (int l = 0; l < q; l++)
                for (int k = 0; k < q; k++)
                    P[(size_t)(j * r + i) * e + (size_t)(l * q + k)] = w[j * q + l] * w[i * q + k];
    double s2 = noise_scale * noise_scale, dd = 0, tr = 0;
    if (fit_grid_average(Sq, q, r, out->S)) { /* P Sq; the kept detail is added below */
        rc = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    for (size_t j = 0; j < d; j++) {
        D[j] = Sr[j] - out->S[j];
        dd += D[j] * D[j];
    }
    /* V = Crr + P Cqq P^T - Crq P^T - P Crq^T (scaled by s2 below) */
    memcpy(V, Crr, sizeof(double) * d * d);
    fit_gemm(P, 0, Cqq, 0, d, e, e, 1, 0, X);  /* P Cqq */
    fit_gemm(X, 0, P, 1, d, e, d, 1, 1, V);    /* + P Cqq P^T */
    fit_gemm(Crq, 0, P, 1, d, e, d, -1, 1, V); /* - Crq P^T */
    fit_gemm(P, 0, Crq, 1, d, e, d, -1, 1, V); /* - P Crq^T */
    for (size_t j = 0; j < d * d; j++) V[j] *= s2;
    for (size_t j = 0; j < d; j++) tr += V[j * d + j];
    /* V = U diag(lam) U^T by LAPACK's divide and conquer; U overwrites V, eigenvector k in
     * column k (V[j * d + k]) */
    if (LAPACKE_dsyevd(LAPACK_ROW_MAJOR, 'V', 'U', (lapack_int)d, V, (lapack_int)d, lam)) {
        rc = err_set(err, -EDOM, "the eigen-decomposition of the detail's covariance failed");
        goto out;
    }
    double lmax = 0;
    for (size_t k = 0; k < d; k++) lmax = fmax(lmax, lam[k]);
    /* z = U^T D; the patterns without noise (the mean, which D lacks) keep their coordinate */
    size_t kept = 0;
    double *z2 = Y, *lk = Y + d; /* scratch: the modes with noise */
    for (size_t k = 0; k < d; k++) {
        double s = 0;
        for (size_t j = 0; j < d; j++) s += V[j * d + k] * D[j];
        z[k] = s;
        if (lam[k] > NOISELESS * lmax) z2[kept] = s * s, lk[kept++] = lam[k];
    }
    double t = ml_tau2(z2, lk, kept);
    /* Gs = U diag(g) U^T, g_k = t / (t + lam_k) (1 for the noiseless patterns) */
    for (size_t k = 0; k < d; k++) lam[k] = lam[k] > NOISELESS * lmax ? t / (t + lam[k]) : 1;
    /* the shrinkage's expected squared bias, (1 - g_k)^2 tau^2 per pattern (the detail's prior
     * variance it takes away), on the diagonal in the noise model's units: with the noise
     * g_k^2 lambda_k below, each pattern's variance is g_k lambda_k, the posterior's */
    for (size_t j = 0; j < d; j++) {
        double b = 0;
        for (size_t k = 0; k < d; k++) b += V[j * d + k] * V[j * d + k] * (1 - lam[k]) * (1 - lam[k]);
        z[j] = b * t / s2; /* z is free now: the coordinates were used */
    }
    for (size_t j = 0; j < d; j++)
        for (size_t k = 0; k < d; k++) X[j * d + k] = V[j * d + k] * lam[k];
    fit_gemm(X, 0, V, 1, d, d, d, 1, 0, Gs);
    double kept2 = 0;
    for (size_t j = 0; j < d; j++) {
        double s = 0;
        for (size_t k = 0; k < d; k++) s += Gs[j * d + k] * D[k];
        out->S[j] += s;
        out->S_res[j] = FIT_RES_FRACTION * fabs(s); /* shrink.h */
        kept2 += s * s;
    }
    /* Cov(M), M = A Sq + Gs Sr with A = (I - Gs) P:
     * A Cqq A^T + Gs Crr Gs + A Crq^T Gs + Gs Crq A^T (Gs symmetric) */
    double *A = P; /* A = P - Gs P, in place after the copy below */
    fit_gemm(Gs, 0, P, 0, d, d, e, 1, 0, X);
    for (size_t j = 0; j < d * e; j++) A[j] -= X[j];
    double *C = V; /* U is no longer needed */
    fit_gemm(A, 0, Cqq, 0, d, e, e, 1, 0, X);
    fit_gemm(X, 0, A, 1, d, e, d, 1, 0, C);
    fit_gemm(Gs, 0, Crr, 0, d, d, d, 1, 0, X);
    fit_gemm(X, 0, Gs, 0, d, d, d, 1, 1, C);
    fit_gemm(A, 0, Crq, 1, d, e, d, 1, 0, X); /* A Crq^T (d x d) */
    fit_gemm(X, 0, Gs, 0, d, d, d, 1, 0, Y);
    for (size_t j = 0; j < d; j++)
        for (size_t k = 0; k < d; k++) C[j * d + k] += Y[j * d + k] + Y[k * d + j];
    for (size_t j = 0; j < d; j++) out->S_err[j] = sqrt(fmax(C[j * d + j] + z[j], 0));
    out->r = r;
    out->toward_r = q;
    out->factor = dd > 0 ? sqrt(kept2 / dd) : 0;
    out->detail = sqrt(dd / (double)d);
    out->noise = sqrt(fmax(tr, 0) / (double)d);
    out->tau = sqrt(t);
out:
    free(w), free(P), free(V), free(X), free(Gs), free(lam), free(D), free(z), free(Y);
    if (rc) fit_shrunk_free(out);
    return rc;
}

int fit_shrink_recommended(const fit_scan_t *scan, const fit_options_t *opts,
                           const fit_sweep_t *sw, double noise_scale, fit_shrunk_t *out,
                           err_t *err)
{
    memset(out, 0, sizeof *out);
    int r = sw->recommended_r, q = r - 1;
    if (r < 2 || q < sw->r_min || r > sw->r_max || r > FIT_SHRINK_R_MAX) return 0;
    const fit_result_t *fine = &sw->fits[r - sw->r_min], *coarse = fine - 1;
    if (!fine->S || !coarse->S) return 0;
    size_t d = (size_t)r * r, e = (size_t)q * q;
    double *Crr = malloc(sizeof(double) * d * d), *Cqq = malloc(sizeof(double) * e * e);
    double *Crq = malloc(sizeof(double) * d * e);
    int rc = !Crr || !Cqq || !Crq ? err_set(err, -ENOMEM, "out of memory")
                                  : fit_map_joint_cov(scan, r, q, opts, Crr, Cqq, Crq, err);
    if (rc == 0)
        rc = fit_shrink_with_cov(fine->S, r, coarse->S, q, Crr, Cqq, Crq, noise_scale, out, err);
    free(Crr), free(Cqq), free(Crq);
    return rc;
}

void fit_shrunk_free(fit_shrunk_t *s)
{
    if (!s) return;
    free(s->S);
    free(s->S_err);
    free(s->S_res);
    s->S = s->S_err = s->S_res = NULL;
    s->r = 0;
}
