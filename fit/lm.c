/* lm.c: Levenberg-Marquardt fit of the paper's model with GSL's nonlinear least squares
 * (trust-region LM with More's scaling, SVD solver: the problem is rank-deficient by one,
 * the scale between I0 and S, which the damping absorbs). */
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
};

/* residuals f_k = (I0 (A S)_k - y_k) / sigma_k; parameters x = (S_1..S_m, I0) */
static int lm_f(const gsl_vector *x, void *vd, gsl_vector *f)
{
    const struct lm_data *d = vd;
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
    const struct lm_data *d = vd;
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

int lm_fit(const double *A, const double *sigma, const double *y, size_t n, size_t m, double *S,
           double *I0, lm_result_t *res)
{
    struct lm_data d = {A, sigma, y, n, m};
    gsl_multifit_nlinear_parameters par = gsl_multifit_nlinear_default_parameters();
    par.trs = gsl_multifit_nlinear_trs_lm;
    par.solver = gsl_multifit_nlinear_solver_svd;
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
        rc = -EDOM;
        goto out;
    }
    int st = gsl_multifit_nlinear_driver(LM_MAX_ITER, 1e-12, 1e-12, 1e-15, NULL, NULL, &info, ws);
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
