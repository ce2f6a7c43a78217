/* model.c: one r x r fit of the pixel response model (eq. 3) by weighted chi-square (eq. 4):
 * point selection, design matrix, the linear global minimum (wls.c) and/or the paper's LM
 * (lm.c), normalisation of S to mean 1 with uncertainties, and the trust status. */
#include "fit/model.h"

#include <errno.h>
#include <float.h>
#include <gsl/gsl_cdf.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "fit/gslerr.h"
#include "gemm.h"
#include "lm.h"
#include "points.h"
#include "wls.h"

#define COND_LIMIT 1e8     /* beyond: near-collinear columns, the map is noise-dominated */
#define SIGNAL_SIGMAS 3.0  /* light must stand this many standard deviations above the noise */

fit_options_t fit_options_default(void)
{
    return (fit_options_t){.noise = FIT_NOISE_PAPER, .method = FIT_LINEAR, .nonneg = 0,
                           .design_tol = 1e-12};
}

const char *fit_status_name(unsigned flags)
{
    if (flags & FIT_NO_POINTS) {
        if (flags & FIT_SATURATED) return "saturated";
        if (flags & FIT_NONFINITE) return "nonfinite_input";
        return "no_points";
    }
    if (flags & FIT_UNDERDETERMINED) return "underdetermined";
    if (flags & FIT_NO_SIGNAL) return "no_signal";
    if (flags & FIT_ILL_CONDITIONED) return "ill_conditioned";
    if (flags & FIT_UNCONSTRAINED) return "unconstrained";
    if (flags & FIT_POOR_FIT) return "poor_fit";
    if (flags & FIT_LM_NOT_GLOBAL) return "lm_not_global";
    if (flags & FIT_LM_NOT_CONVERGED) return "lm_not_converged";
    if (flags & FIT_NONFINITE) return "nonfinite_input"; /* map fine, points left out */
    if (flags & FIT_SATURATED) return "saturated";
    return "ok";
}

int fit_scan_check(const fit_scan_t *scan, err_t *err)
{
    if (!scan) return err_set(err, -EINVAL, "no scan");
    if (scan->n && (!scan->x_um || !scan->y_um || !scan->signal_dn))
        return err_set(err, -EINVAL, "scan arrays missing");
    if (!(scan->pitch_um > 0) || !isfinite(scan->pitch_um))
        return err_set(err, -EINVAL, "pitch_um must be a positive number (got %g)", scan->pitch_um);
    if (!(scan->spot_radius_um > 0) || !isfinite(scan->spot_radius_um))
        return err_set(err, -EINVAL, "spot_radius_um must be a positive number (got %g)",
                       scan->spot_radius_um);
    if (!(scan->gain_e_per_dn > 0) || !isfinite(scan->gain_e_per_dn))
        return err_set(err, -EINVAL, "gain_e_per_dn must be a positive number (got %g)",
                       scan->gain_e_per_dn);
    if (!(scan->read_noise_e >= 0) || !isfinite(scan->read_noise_e))
        return err_set(err, -EINVAL, "read_noise_e must be a non-negative number (got %g)",
                       scan->read_noise_e);
    if (!isfinite(scan->bias_dn)) return err_set(err, -EINVAL, "bias_dn must be a finite number");
    if (scan->frames < 1)
        return err_set(err, -EINVAL, "frames must be at least 1 (got %d)", scan->frames);
    return 0;
}

/* S = T / mean(T) and its covariance through J = (I - S 1^T / m) / mean(T): the scale that LM
 * cannot see (I0 against S) is fixed by the normalisation. */
static void normalise(const double *T, const double *covT, size_t m, fit_result_t *res)
{
    double mean = 0, one_cov_one = 0;
    for (size_t j = 0; j < m; j++) mean += T[j];
    mean /= m;
    double *rowsum = calloc(m, sizeof(double)); /* (Cov 1)_i */
    for (size_t i = 0; i < m && rowsum; i++) {
        for (size_t j = 0; j < m; j++) rowsum[i] += covT[i * m + j];
        one_cov_one += rowsum[i];
    }
    res->I0 = mean;
    res->I0_err = sqrt(fmax(one_cov_one, 0)) / m;
    for (size_t i = 0; i < m; i++) {
        double s = T[i] / mean;
        /* Var(S_i) = [C_ii - 2 S_i (C 1)_i / m + S_i^2 (1^T C 1) / m^2] / mean^2 */
        double v = covT[i * m + i] - 2 * s * (rowsum ? rowsum[i] : 0) / m +
                   s * s * one_cov_one / ((double)m * m);
        res->S[i] = s;
        res->S_err[i] = sqrt(fmax(v, 0)) / fabs(mean);
    }
    free(rowsum);
}

/* The paper's LM from S = 1 (method lm/both); I0 starts at the best constant-map amplitude. */
static int run_lm(const double *A, const fit_points_t *p, size_t m, const fit_options_t *opts,
                  double *T, fit_result_t *res)
{
    double *S = malloc(sizeof(double) * m), num = 0, den = 0;
    if (!S) return -ENOMEM;
    for (size_t k = 0; k < p->n; k++) {
        double a1 = 0;
        for (size_t j = 0; j < m; j++) a1 += A[k * m + j];
        num += p->w[k] * p->d[k] * a1;
        den += p->w[k] * a1 * a1;
    }
    double I0 = den > 0 ? num / den : 1;
    for (size_t j = 0; j < m; j++) S[j] = 1;
    lm_result_t lm;
    int rc = lm_fit(A, p->sigma, p->d, p->n, m, S, &I0, &opts->stop, &lm);
    if (rc == 0) {
        res->lm_chi2 = lm.chi2;
        res->lm_iterations = lm.iterations;
        if (!lm.converged) res->flags |= FIT_LM_NOT_CONVERGED;
        /* LM must land on the global minimum of the linear problem (to 1e-6 relative) */
        if (opts->method == FIT_BOTH && lm.chi2 > res->chi2 * (1 + 1e-6) + 1e-9)
            res->flags |= FIT_LM_NOT_GLOBAL;
        if (opts->method == FIT_LM) {
            for (size_t j = 0; j < m; j++) T[j] = I0 * S[j];
            res->chi2 = lm.chi2;
        }
    }
    free(S);
    return rc;
}

/* Leave-one-out prediction chi2 of a linear least-squares fit, without refitting: with the
 * weighted hat matrix H = W^1/2 A C A^T W^1/2, C = (A^T W A)^-1, the residual of point k when it
 * is left out is e_k / (1 - h_kk) (the PRESS identity), so sum w_k (e_k / (1 - h_kk))^2 is the
 * chi2 of predicting every point from all the others. The leverages h_kk come from the solver
 * (wls.h: the squared row norms of the thin Q, exact to rounding, not A C A^T, which loses
 * cond^2 times the rounding). A point that alone determines a parameter (h_kk -> 1) makes it
 * infinite. */
static double loo_chi2(const double *A, const fit_points_t *p, size_t m, const double *T,
                       const double *hat)
{
    double sum = 0;
    for (size_t k = 0; k < p->n; k++) {
        const double *a = A + k * m;
        double e = p->d[k], h = hat[k];
        for (size_t i = 0; i < m; i++) e -= a[i] * T[i];
        if (!(h < 1 - 1e-12)) return INFINITY;
        double loo = e / (1 - h);
        sum += p->w[k] * loo * loo;
    }
    return sum;
}

/* Solves for T = I0 S on the selected points and fills the result's statistics and map. */
static int solve(const double *A, const fit_points_t *p, int r, const fit_options_t *opts,
                 fit_result_t *res)
{
    size_t m = (size_t)r * r, n = p->n;
    double *T = malloc(sizeof(double) * m), *cov = malloc(sizeof(double) * m * m);
    double *hat = malloc(sizeof(double) * n);
    int rc = -ENOMEM;
    if (!T || !cov || !hat) goto out;
    wls_result_t w;
    /* polled inside the non-negative solve's loops and after the solve (wls.h) */
    if ((rc = wls_solve_hat(A, p->w, p->d, n, m, opts->nonneg, T, cov, hat, &opts->stop, &w)))
        goto out;
    res->chi2 = w.chi2;
    res->cond = w.rcond > 0 ? 1 / w.rcond : INFINITY;
    res->cv_chi2 = loo_chi2(A, p, m, T, hat);
    if (opts->method != FIT_LINEAR && !opts->nonneg && (rc = run_lm(A, p, m, opts, T, res)))
        goto out;
    res->chi2_red = n > (size_t)res->params ? res->chi2 / (double)(n - (size_t)res->params) : NAN;
    if (n > (size_t)res->params) { /* upper tail of the chi-square distribution of the residuals */
        res->chi2_p = gsl_cdf_chisq_Q(res->chi2, (double)(n - (size_t)res->params));
        if (res->chi2_p < FIT_POOR_FIT_P) res->flags |= FIT_POOR_FIT;
    }
    double N = (double)n, l = log(res->chi2 / N);
    res->aic = N * l + 2 * res->params; /* AIC = N ln(chi2/N) + 2p */
    res->bic = N * l + res->params * log(N); /* BIC = N ln(chi2/N) + p ln N */
    if (res->cond > COND_LIMIT || w.rank < m) res->flags |= FIT_ILL_CONDITIONED;
    res->S = malloc(sizeof(double) * m);
    res->S_err = malloc(sizeof(double) * m);
    if (!res->S || !res->S_err) {
        rc = -ENOMEM;
        goto out;
    }
    normalise(T, cov, m, res);
    /* No light: without signal, S = T / mean(T) is a ratio of noises. Decided on the data, not on
     * the fit (which an ill-conditioned problem makes uncertain anyway): the zero model's chi2
     * sum w y^2 must exceed its noise-only expectation N by SIGNAL_SIGMAS sqrt(2N). */
    double chi2_zero = 0;
    for (size_t k = 0; k < n; k++) chi2_zero += p->w[k] * p->d[k] * p->d[k];
    int no_signal = !(chi2_zero > N + SIGNAL_SIGMAS * sqrt(2 * N));
    if (no_signal) res->flags |= FIT_NO_SIGNAL;
    else if (!(res->I0 > 0) || !isfinite(res->I0)) res->flags |= FIT_ILL_CONDITIONED;
    if (no_signal || !(res->I0 > 0) || !isfinite(res->I0)) { /* no meaningful normalisation */
        free(res->S);
        free(res->S_err);
        res->S = res->S_err = NULL;
    } else {
        for (size_t j = 0; j < m; j++)
            if (!(res->S_err[j] <= 1)) res->n_unconstrained++;
        if (res->n_unconstrained) res->flags |= FIT_UNCONSTRAINED;
    }
    rc = 0;
out:
    free(T);
    free(cov);
    free(hat);
    return rc;
}

/* model_dn: M_k + bias for every input point that was used, NaN for the others; resid: the
 * normalised residuals (signal - M_k - bias) / sigma_k of the same points. */
static int fill_model(const fit_scan_t *scan, const double *A, const fit_points_t *p, int r,
                      fit_result_t *res)
{
    size_t m = (size_t)r * r, nn = scan->n ? scan->n : 1;
    res->model_dn = malloc(sizeof(double) * nn);
    res->resid = malloc(sizeof(double) * nn);
    if (!res->model_dn || !res->resid) return -ENOMEM;
    for (size_t k = 0; k < scan->n; k++) res->model_dn[k] = res->resid[k] = NAN;
    if (!res->S) return 0;
    for (size_t q = 0; q < p->n; q++) {
        double as = 0;
        for (size_t j = 0; j < m; j++) as += A[q * m + j] * res->S[j];
        size_t k = p->idx[q];
        res->model_dn[k] = res->I0 * as + scan->bias_dn;
        res->resid[k] = (p->d[q] - res->I0 * as) / p->sigma[q];
    }
    return 0;
}

int fit_map(const fit_scan_t *scan, int r, const fit_options_t *opts, fit_result_t *out,
            err_t *err)
{
    fit_gsl_policy();
    memset(out, 0, sizeof *out);
    out->r = r;
    out->params = r * r + 1;
    out->lm_chi2 = out->chi2 = out->chi2_red = out->aic = out->bic = out->cv_chi2 = NAN;
    out->chi2_p = NAN;
    out->I0 = out->I0_err = out->cond = NAN;
    fit_options_t o = opts ? *opts : fit_options_default();
    if (r < 1 || r > 32) return err_set(err, -EINVAL, "r must be between 1 and 32 (got %d)", r);
    int rc = fit_scan_check(scan, err);
    if (rc) return rc;
    fit_points_t p;
    double *A = NULL, t0 = clock_mono_ms();
    if ((rc = fit_points_select(scan, o.noise, &p, &out->n_nonfinite, &out->n_saturated)))
        goto out;
    if (out->n_nonfinite) out->flags |= FIT_NONFINITE;
    if (out->n_saturated) out->flags |= FIT_SATURATED;
    if (p.n == 0) out->flags |= FIT_NO_POINTS;
    else if ((size_t)out->params > p.n) out->flags |= FIT_UNDERDETERMINED;
    out->n_used = p.n;
    if (!(out->flags & (FIT_NO_POINTS | FIT_UNDERDETERMINED))) {
        size_t m = (size_t)r * r;
        if (!(A = malloc(sizeof(double) * p.n * m))) {
            rc = -ENOMEM;
            goto out;
        }
        fit_design_opts_t d = fit_design_opts_for_tol(o.design_tol > 0 ? o.design_tol : 1e-12);
        d.cache = o.design_cache;
        d.stop = o.stop;
        rc = fit_design_build(scan->spot_radius_um, scan->pitch_um, r, p.x, p.y, p.n, &d, A,
                              &out->design, err);
        if (rc) goto out;
        double t1 = clock_mono_ms();
        out->design_ms = t1 - t0;
        if ((rc = solve(A, &p, r, &o, out))) goto out;
        out->solve_ms = clock_mono_ms() - t1;
    }
    rc = fill_model(scan, A, &p, r, out);
out:
    if (rc == -ENOMEM) err_set(err, rc, "out of memory fitting r = %d", r);
    else if (rc == -EDOM) err_set(err, rc, "the linear algebra failed for r = %d", r);
    else if (rc == -ECANCELED) err_set(err, rc, "fit stopped (r = %d)", r);
    if (rc) fit_result_free(out);
    fit_points_free(&p);
    free(A);
    return rc;
}

/* One fit's pieces for fit_map_joint_cov: its design on the selected points, T and (A^T W A)^-1. */
struct joint_part {
    double *A, *T, *cov;
};

static int joint_part(const fit_scan_t *scan, const fit_points_t *p, int r, const fit_options_t *o,
                      struct joint_part *j, err_t *err)
{
    size_t m = (size_t)r * r;
    j->A = malloc(sizeof(double) * p->n * m);
    j->T = malloc(sizeof(double) * m);
    j->cov = malloc(sizeof(double) * m * m);
    if (!j->A || !j->T || !j->cov) return err_set(err, -ENOMEM, "out of memory");
    fit_design_opts_t d = fit_design_opts_for_tol(o->design_tol > 0 ? o->design_tol : 1e-12);
    d.cache = o->design_cache;
    int rc = fit_design_build(scan->spot_radius_um, scan->pitch_um, r, p->x, p->y, p->n, &d, j->A,
                              NULL, err);
    if (rc) return rc;
    wls_result_t w;
    if ((rc = wls_solve(j->A, p->w, p->d, p->n, m, 0, j->T, j->cov, NULL, &w)))
        return err_set(err, rc, "the linear algebra failed for r = %d", r);
    return 0;
}

/* J = (I - S 1^T / m) / mean(T): the Jacobian of S = T / mean(T) (normalise above) */
static double *norm_jacobian(const double *T, size_t m)
{
    double *J = malloc(sizeof(double) * m * m), mean = 0;
    if (!J) return NULL;
    for (size_t i = 0; i < m; i++) mean += T[i];
    mean /= (double)m;
    for (size_t i = 0; i < m; i++)
        for (size_t k = 0; k < m; k++)
            J[i * m + k] = ((i == k) - T[i] / mean / (double)m) / mean;
    return J;
}

int fit_map_joint_cov(const fit_scan_t *scan, int r1, int r2, const fit_options_t *opts,
                      double *C11, double *C22, double *C12, err_t *err)
{
    fit_gsl_policy();
    fit_options_t o = opts ? *opts : fit_options_default();
    if (r1 < 1 || r1 > 32 || r2 < 1 || r2 > 32)
        return err_set(err, -EINVAL, "r must be between 1 and 32 (got %d, %d)", r1, r2);
    int rc = fit_scan_check(scan, err);
    if (rc) return rc;
    size_t m1 = (size_t)r1 * r1, m2 = (size_t)r2 * r2;
    fit_points_t p;
    size_t n_nonfinite, n_saturated;
    struct joint_part a = {0}, b = {0};
    double *G = NULL, *J1 = NULL, *J2 = NULL, *X = NULL, *Y = NULL;
    if ((rc = fit_points_select(scan, o.noise, &p, &n_nonfinite, &n_saturated))) {
        rc = err_set(err, rc, "out of memory");
        goto out;
    }
    if (p.n < m1 + 1 || p.n < m2 + 1) {
        rc = err_set(err, -EINVAL, "too few points (%zu) for r = %d and %d", p.n, r1, r2);
        goto out;
    }
    if ((rc = joint_part(scan, &p, r1, &o, &a, err)) || (rc = joint_part(scan, &p, r2, &o, &b, err)))
        goto out;
    /* Cov(T1, T2) = C1 (A1^T W A2) C2, since T = C A^T W d and Cov(d) = W^-1 */
    G = malloc(sizeof(double) * m1 * m2);
    J1 = norm_jacobian(a.T, m1);
    J2 = norm_jacobian(b.T, m2);
    size_t big = (m1 > m2 ? m1 : m2);
    X = malloc(sizeof(double) * big * big);
    Y = malloc(sizeof(double) * big * big);
    if (!G || !J1 || !J2 || !X || !Y) {
        rc = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    /* G = A1^T (W A2); W A2 overwrites A2, which is not needed again */
    for (size_t q = 0; q < p.n; q++)
        for (size_t k = 0; k < m2; k++) b.A[q * m2 + k] *= p.w[q];
    fit_gemm(a.A, 1, b.A, 0, m1, p.n, m2, 1, 0, G);
    fit_gemm(a.cov, 0, G, 0, m1, m1, m2, 1, 0, X);  /* C1 G */
    fit_gemm(X, 0, b.cov, 0, m1, m2, m2, 1, 0, Y);  /* C1 G C2 = Cov(T1, T2) */
    fit_gemm(J1, 0, Y, 0, m1, m1, m2, 1, 0, X);     /* J1 Cov(T1, T2) */
    fit_gemm(X, 0, J2, 1, m1, m2, m2, 1, 0, C12);   /* ... J2^T */
    fit_gemm(J1, 0, a.cov, 0, m1, m1, m1, 1, 0, X);
    fit_gemm(X, 0, J1, 1, m1, m1, m1, 1, 0, C11);
    fit_gemm(J2, 0, b.cov, 0, m2, m2, m2, 1, 0, X);
    fit_gemm(X, 0, J2, 1, m2, m2, m2, 1, 0, C22);
out:
    free(a.A), free(a.T), free(a.cov), free(b.A), free(b.T), free(b.cov);
    free(G), free(J1), free(J2), free(X), free(Y);
    fit_points_free(&p);
    return rc;
}

void fit_result_free(fit_result_t *res)
{
    if (!res) return;
    free(res->S);
    free(res->S_err);
    free(res->model_dn);
    free(res->resid);
    res->S = res->S_err = res->model_dn = res->resid = NULL;
}
