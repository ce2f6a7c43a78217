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

/* Lawson-Hanson NNLS. passive[j] marks free parameters; on return c >= 0. */
static int nnls(const double *X, const double *w, const double *y, size_t n, size_t m, double *c,
                double *cov, wls_result_t *res)
{
    int rc = 0;
    unsigned char *passive = calloc(m, 1);
    size_t *cols = malloc(sizeof(size_t) * m);
    double *g = malloc(sizeof(double) * m), *z = malloc(sizeof(double) * m);
    double *zc = malloc(sizeof(double) * m), *cv = malloc(sizeof(double) * m * m);
    if (!passive || !cols || !g || !z || !zc || !cv) {
        rc = -ENOMEM;
        goto out;
    }
    memset(c, 0, sizeof(double) * m);
    double chi2 = 0, rcond = 1, gmax_tol = 0;
    size_t rank = 0, np = 0;
    for (int outer = 0; outer < 3 * (int)m + 10; outer++) {
        neg_gradient(X, w, y, n, m, c, g);
        double gmax = 0, gscale = 0;
        size_t jmax = m;
        for (size_t j = 0; j < m; j++) gscale = fmax(gscale, fabs(g[j]));
        if (outer == 0) gmax_tol = 1e-12 * gscale;
        for (size_t j = 0; j < m; j++)
            if (!passive[j] && g[j] > gmax) gmax = g[j], jmax = j;
        if (jmax == m || gmax <= gmax_tol) break; /* KKT conditions hold */
        passive[jmax] = 1;
        for (int inner = 0; inner < 3 * (int)m + 10; inner++) {
            np = 0;
            for (size_t j = 0; j < m; j++)
                if (passive[j]) cols[np++] = j;
            if ((rc = solve_cols(X, w, y, n, m, cols, np, zc, cv, &chi2, &rcond, &rank))) goto out;
            memset(z, 0, sizeof(double) * m);
            for (size_t q = 0; q < np; q++) z[cols[q]] = zc[q];
            double alpha = 2;
            for (size_t q = 0; q < np; q++) {
                size_t j = cols[q];
                if (z[j] <= 0) alpha = fmin(alpha, c[j] / (c[j] - z[j]));
            }
            if (alpha > 1) { /* all free parameters positive: accept */
                memcpy(c, z, sizeof(double) * m);
                break;
            }
            for (size_t j = 0; j < m; j++) { /* step back to the boundary, drop what hits it */
                c[j] += alpha * (z[j] - c[j]);
                if (passive[j] && c[j] <= 1e-300) passive[j] = 0, c[j] = 0;
            }
        }
    }
    /* final statistics on the passive set */
    np = 0;
    for (size_t j = 0; j < m; j++)
        if (passive[j]) cols[np++] = j;
    memset(c, 0, sizeof(double) * m);
    if (cov) memset(cov, 0, sizeof(double) * m * m);
    if (np) {
        if ((rc = solve_cols(X, w, y, n, m, cols, np, zc, cv, &chi2, &rcond, &rank))) goto out;
        for (size_t q = 0; q < np; q++) {
            c[cols[q]] = zc[q] > 0 ? zc[q] : 0;
            if (cov)
                for (size_t p = 0; p < np; p++) cov[cols[q] * m + cols[p]] = cv[q * np + p];
        }
    } else {
        chi2 = 0;
        for (size_t k = 0; k < n; k++) chi2 += w[k] * y[k] * y[k];
    }
    res->chi2 = chi2;
    res->rcond = rcond;
    res->rank = rank;
    res->n_bound = m - np;
out:
    free(passive);
    free(cols);
    free(g);
    free(z);
    free(zc);
    free(cv);
    return rc;
}

int wls_solve(const double *X, const double *w, const double *y, size_t n, size_t m, int nonneg,
              double *c, double *cov, wls_result_t *res)
{
    memset(res, 0, sizeof *res);
    if (nonneg) return nnls(X, w, y, n, m, c, cov, res);
    return solve_cols(X, w, y, n, m, NULL, m, c, cov, &res->chi2, &res->rcond, &res->rank);
}
