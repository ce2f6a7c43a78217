/* wls.c: weighted linear least squares by GSL's column-balanced SVD (gsl_multifit_wlinear),
 * and non-negative least squares by the active-set method of Lawson and Hanson (1974, ch. 23),
 * hand-written because GSL has none; each of its subproblems is again gsl_multifit_wlinear. */
#include "wls.h"

#include <errno.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Unconstrained solve on the columns listed in cols (all when cols is NULL, mc = m). */
static int solve_cols(const double *X, const double *w, const double *y, size_t n, size_t m,
                      const size_t *cols, size_t mc, double *c, double *cov, double *chi2,
                      double *rcond, size_t *rank)
{
    int rc = 0;
    gsl_matrix *A = gsl_matrix_alloc(n, mc), *C = gsl_matrix_alloc(mc, mc);
    gsl_vector *gw = gsl_vector_alloc(n), *gy = gsl_vector_alloc(n), *gc = gsl_vector_alloc(mc);
    gsl_multifit_linear_workspace *ws = gsl_multifit_linear_alloc(n, mc);
    if (!A || !C || !gw || !gy || !gc || !ws) {
        rc = -ENOMEM;
        goto out;
    }
    for (size_t k = 0; k < n; k++) {
        for (size_t j = 0; j < mc; j++)
            gsl_matrix_set(A, k, j, X[k * m + (cols ? cols[j] : j)]);
        gsl_vector_set(gw, k, w[k]);
        gsl_vector_set(gy, k, y[k]);
    }
    if (gsl_multifit_wlinear_tsvd(A, gw, gy, GSL_DBL_EPSILON, gc, C, chi2, rank, ws) !=
        GSL_SUCCESS) {
        rc = -EDOM;
        goto out;
    }
    *rcond = gsl_multifit_linear_rcond(ws);
    for (size_t j = 0; j < mc; j++) {
        c[j] = gsl_vector_get(gc, j);
        if (cov)
            for (size_t i = 0; i < mc; i++) cov[j * mc + i] = gsl_matrix_get(C, j, i);
    }
out:
    gsl_matrix_free(A);
    gsl_matrix_free(C);
    gsl_vector_free(gw);
    gsl_vector_free(gy);
    gsl_vector_free(gc);
    gsl_multifit_linear_free(ws);
    return rc;
}

/* Gradient of -chi2/2: g = X^T W (y - X c). */
static void neg_gradient(const double *X, const double *w, const double *y, size_t n, size_t m,
                         const double *c, double *g)
{
    memset(g, 0, sizeof(double) * m);
    for (size_t k = 0; k < n; k++) {
        double r = y[k];
        for (size_t j = 0; j < m; j++) r -= X[k * m + j] * c[j];
        r *= w[k];
        for (size_t j = 0; j < m; j++) g[j] += X[k * m + j] * r;
    }
}

struct nnls_work {
    unsigned char *passive; /* free parameters */
    size_t *cols;           /* their indices */
    double *g, *z, *zc, *cv;
};

/* Lists the passive set into cols; returns its size. */
static size_t passive_cols(const struct nnls_work *nw, size_t m)
{
    size_t np = 0;
    for (size_t j = 0; j < m; j++)
        if (nw->passive[j]) nw->cols[np++] = j;
    return np;
}

/* Lawson-Hanson inner loop: solve on the passive set; while some free parameter would turn
 * negative, step back to the boundary and release the parameters that reach it. */
static int nnls_inner(const double *X, const double *w, const double *y, size_t n, size_t m,
                      double *c, struct nnls_work *nw, wls_result_t *res)
{
    for (int inner = 0; inner < 3 * (int)m + 10; inner++) {
        size_t np = passive_cols(nw, m);
        int rc = solve_cols(X, w, y, n, m, nw->cols, np, nw->zc, nw->cv, &res->chi2, &res->rcond,
                            &res->rank);
        if (rc) return rc;
        memset(nw->z, 0, sizeof(double) * m);
        for (size_t q = 0; q < np; q++) nw->z[nw->cols[q]] = nw->zc[q];
        double alpha = 2;
        for (size_t q = 0; q < np; q++) {
            size_t j = nw->cols[q];
            if (nw->z[j] <= 0) alpha = fmin(alpha, c[j] / (c[j] - nw->z[j]));
        }
        if (alpha > 1) { /* all free parameters positive: accept */
            memcpy(c, nw->z, sizeof(double) * m);
            return 0;
        }
        for (size_t j = 0; j < m; j++) {
            c[j] += alpha * (nw->z[j] - c[j]);
            if (nw->passive[j] && c[j] <= 1e-300) nw->passive[j] = 0, c[j] = 0;
        }
    }
    return 0;
}

/* Final statistics and covariance on the passive set (zero rows for parameters at 0). */
static int nnls_finish(const double *X, const double *w, const double *y, size_t n, size_t m,
                       double *c, double *cov, struct nnls_work *nw, wls_result_t *res)
{
    size_t np = passive_cols(nw, m);
    memset(c, 0, sizeof(double) * m);
    if (cov) memset(cov, 0, sizeof(double) * m * m);
    res->n_bound = m - np;
    if (!np) {
        res->chi2 = 0;
        for (size_t k = 0; k < n; k++) res->chi2 += w[k] * y[k] * y[k];
        return 0;
    }
    int rc = solve_cols(X, w, y, n, m, nw->cols, np, nw->zc, nw->cv, &res->chi2, &res->rcond,
                        &res->rank);
    for (size_t q = 0; q < np && !rc; q++) {
        c[nw->cols[q]] = nw->zc[q] > 0 ? nw->zc[q] : 0;
        if (cov)
            for (size_t p = 0; p < np; p++) cov[nw->cols[q] * m + nw->cols[p]] = nw->cv[q * np + p];
    }
    return rc;
}

/* Lawson-Hanson NNLS: add the parameter with the largest positive gradient to the free set
 * until the KKT conditions hold (no held parameter wants to grow). */
static int nnls(const double *X, const double *w, const double *y, size_t n, size_t m, double *c,
                double *cov, wls_result_t *res)
{
    int rc = -ENOMEM;
    struct nnls_work nw = {.passive = calloc(m, 1), .cols = malloc(sizeof(size_t) * m),
                           .g = malloc(sizeof(double) * m), .z = malloc(sizeof(double) * m),
                           .zc = malloc(sizeof(double) * m), .cv = malloc(sizeof(double) * m * m)};
    if (!nw.passive || !nw.cols || !nw.g || !nw.z || !nw.zc || !nw.cv) goto out;
    memset(c, 0, sizeof(double) * m);
    double gtol = 0;
    rc = 0;
    for (int outer = 0; outer < 3 * (int)m + 10 && !rc; outer++) {
        neg_gradient(X, w, y, n, m, c, nw.g);
        double gmax = 0, gscale = 0;
        size_t jmax = m;
        for (size_t j = 0; j < m; j++) gscale = fmax(gscale, fabs(nw.g[j]));
        if (outer == 0) gtol = 1e-12 * gscale;
        for (size_t j = 0; j < m; j++)
            if (!nw.passive[j] && nw.g[j] > gmax) gmax = nw.g[j], jmax = j;
        if (jmax == m || gmax <= gtol) break; /* KKT conditions hold */
        nw.passive[jmax] = 1;
        rc = nnls_inner(X, w, y, n, m, c, &nw, res);
    }
    if (!rc) rc = nnls_finish(X, w, y, n, m, c, cov, &nw, res);
out:
    free(nw.passive);
    free(nw.cols);
    free(nw.g);
    free(nw.z);
    free(nw.zc);
    free(nw.cv);
    return rc;
}

int wls_solve(const double *X, const double *w, const double *y, size_t n, size_t m, int nonneg,
              double *c, double *cov, wls_result_t *res)
{
    memset(res, 0, sizeof *res);
    if (nonneg) return nnls(X, w, y, n, m, c, cov, res);
    return solve_cols(X, w, y, n, m, NULL, m, c, cov, &res->chi2, &res->rcond, &res->rank);
}
