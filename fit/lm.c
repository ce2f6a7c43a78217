/* lm.c: Levenberg-Marquardt fit of the paper's model with GSL's nonlinear least squares
 * (trust-region LM with More's scaling). The problem is rank-deficient by one, the scale between
 * I0 and S, which the damping absorbs; GSL's QR solver (column-pivoted QR of the Jacobian, then
 * the damped system by Givens rotations) is documented reliable for rank-deficient Jacobians and
 * costs about a third of its SVD solver (one SVD of the n x (m + 1) Jacobian per iteration):
 * measured at r = 16 on 2000 points, 1.6 s against 5.1 s per iteration on a loaded 2-core VM, the
 * same chi2 and 15 against 14 iterations. The iteration is what a stop waits for (stop.h). */
#include "lm.h"

#include <errno.h>
#include <gsl/gsl_blas.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <math.h>

#define LM_MAX_ITER 1000

struct lm_data {
    const double *A, *sigma, *y;
    size_t n, m;
    const fit_stop_t *stop;
    int stopped; /* the stop answered: the driver was ended by lm_f's or lm_df's error */
};

/* The stop poll of every residual, Jacobian and iteration (stop.h's site "lm"). One iteration is
 * a Jacobian, GSL's QR of it (n x (m + 1): the bulk of the time, one call that cannot be polled)
 * and a few residuals; so a stop is seen within one factorisation. */
static int lm_stop(struct lm_data *d)
{
    if (d->stopped) return 1;
    if (d->stop && fit_stop_at(d->stop, FIT_STOP_SITE_LM)) d->stopped = 1;
    return d->stopped;
}

/* residuals f_k = (I0 (A S)_k - y_k) / sigma_k; parameters x = (S_1..S_m, I0) */
static int lm_f(const gsl_vector *x, void *vd, gsl_vector *f)
{
    struct lm_data *d = vd;
    if (lm_stop(d)) return GSL_EBADFUNC; /* ends the driver: GSL passes the error up */
    double I0 = gsl_vector_get(x, d->m);
    for (size_t k = 0; k < d->n; k++) {
        double as = 0;
        for (size_t j = 0; j < d->m; j++) as += d->A[k * d->m + j] * gsl_vector_get(x, j);
        gsl_vector_set(f, k, (I0 * as - d->y[k]) / d->sigma[k]);
    }
    return GSL_SUCCESS;
}

/* Jacobian: df_k/dS_j = I0 A_kj / sigma_k, df_k/dI0 = (A S)_k / sigma_k */
static int lm_df(const gsl_vector *x, void *vd, gsl_matrix *J)
{
    struct lm_data *d = vd;
    if (lm_stop(d)) return GSL_EBADFUNC; /* before the Jacobian and the SVD that follows it */
    double I0 = gsl_vector_get(x, d->m);
    for (size_t k = 0; k < d->n; k++) {
        double as = 0, is = 1 / d->sigma[k];
        for (size_t j = 0; j < d->m; j++) {
            double a = d->A[k * d->m + j];
            as += a * gsl_vector_get(x, j);
            gsl_matrix_set(J, k, j, I0 * a * is);
        }
        gsl_matrix_set(J, k, d->m, as * is);
    }
    return GSL_SUCCESS;
}

/* gsl_multifit_nlinear_driver's loop (GSL 2.x, multifit_nlinear/fdf.c: iterate, end when the
 * first iteration makes no progress, test for convergence, at most LM_MAX_ITER), which also ends
 * when the stop answered. GSL's driver ignores an iteration's error, so a residual function that
 * refuses to run does not end it: each further iteration still factors the Jacobian. This loop
 * polls the stop before each iteration too (lm_stop). */
static int drive(gsl_multifit_nlinear_workspace *ws, struct lm_data *d, int *info)
{
    int st = GSL_CONTINUE;
    for (size_t iter = 0; st == GSL_CONTINUE && iter < LM_MAX_ITER && !lm_stop(d);) {
        st = gsl_multifit_nlinear_iterate(ws);
        if (st == GSL_ENOPROG && iter == 0) {
            /* GSL's driver reports this as GSL_EMAXITER, but no iteration limit was hit: no
             * step lowers the cost from the start, so the start is a minimum to rounding (at
             * r = 1 the start, S = 1 and the linear I0, is the exact solution). The caller's
             * comparison with the linear minimum (FIT_LM_NOT_GLOBAL) still catches a start that
             * is not the global one. */
            *info = st;
            return GSL_ENOPROG;
        }
        ++iter;
        st = gsl_multifit_nlinear_test(1e-12, 1e-12, 1e-15, info, ws);
        if (st == GSL_ETOLF || st == GSL_ETOLX || st == GSL_ETOLG) st = GSL_SUCCESS;
        if (iter >= LM_MAX_ITER && st != GSL_SUCCESS) st = GSL_EMAXITER;
    }
    return st;
}

int lm_fit(const double *A, const double *sigma, const double *y, size_t n, size_t m, double *S,
           double *I0, const fit_stop_t *stop, lm_result_t *res)
{
    struct lm_data d = {A, sigma, y, n, m, stop, 0};
    gsl_multifit_nlinear_parameters par = gsl_multifit_nlinear_default_parameters();
    par.trs = gsl_multifit_nlinear_trs_lm;
    par.solver = gsl_multifit_nlinear_solver_qr;
    gsl_multifit_nlinear_workspace *ws =
        gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &par, n, m + 1);
    gsl_vector *x0 = gsl_vector_alloc(m + 1);
    int rc = 0;
    if (!ws || !x0) {
        rc = -ENOMEM;
        goto out;
    }
    for (size_t j = 0; j < m; j++) gsl_vector_set(x0, j, S[j]);
    gsl_vector_set(x0, m, *I0);
    gsl_multifit_nlinear_fdf fdf = {.f = lm_f, .df = lm_df, .n = n, .p = m + 1, .params = &d};
    int info = 0;
    if (gsl_multifit_nlinear_init(x0, &fdf, ws) != GSL_SUCCESS) {
        rc = d.stopped ? -ECANCELED : -EDOM;
        goto out;
    }
    int st = drive(ws, &d, &info);
    if (d.stopped) {
        rc = -ECANCELED;
        goto out;
    }
    if (st != GSL_SUCCESS && st != GSL_EMAXITER && st != GSL_ENOPROG) {
        rc = -EDOM;
        goto out;
    }
    const gsl_vector *x = gsl_multifit_nlinear_position(ws);
    for (size_t j = 0; j < m; j++) S[j] = gsl_vector_get(x, j);
    *I0 = gsl_vector_get(x, m);
    double fn = gsl_blas_dnrm2(gsl_multifit_nlinear_residual(ws));
    res->chi2 = fn * fn;
    res->iterations = (int)gsl_multifit_nlinear_niter(ws);
    res->converged = st != GSL_EMAXITER;
out:
    gsl_multifit_nlinear_free(ws);
    gsl_vector_free(x0);
    return rc;
}
