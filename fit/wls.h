/* wls.h: weighted linear least squares, the exact global minimum of the
 * chi-square of eq. 4 for a model linear in its parameters (numerics note 1), optionally with
 * non-negative parameters. */
#ifndef IPSD_FIT_WLS_H
#define IPSD_FIT_WLS_H

#include <stddef.h>

#include "fit/stop.h"

typedef struct wls_result {
    double chi2;    /* sum of squared weighted residuals at the minimum */
    double rcond;   /* reciprocal 2-norm condition number of the (column-balanced) weighted matrix */
    size_t rank;    /* numerical rank used */
    size_t n_bound; /* parameters held at 0 by the non-negativity constraint */
    int lapack;     /* 1: solved by the LAPACK QR path; 0: by the rank-revealing SVD fallback */
} wls_result_t;

/* Minimises sum_k w_k (y_k - sum_j X_kj c_j)^2 over c (m parameters, n >= m points), X row-major
 * n x m. c (m) and cov (m x m, row-major, (X^T W X)^-1, unscaled) are caller-allocated; cov may
 * be NULL. nonneg: c_j >= 0 by Lawson-Hanson active sets (LAPACK has no NNLS); the covariance is
 * then that of the free parameters, with zero rows/columns for those held at 0.
 * stop (may be NULL): polled at each active-set step of the non-negative solve (stop.h's site
 * "nnls": up to 3m + 10 outer steps of up to 3m + 10 solves each, minutes at r = 32), and
 * after the solve. Returns 0, -ENOMEM, -ECANCELED (stopped), or -EDOM when the linear algebra
 * fails. */
int wls_solve(const double *X, const double *w, const double *y, size_t n, size_t m, int nonneg,
              double *c, double *cov, const fit_stop_t *stop, wls_result_t *res);

/* The same, and hat (n, may be NULL) gets the diagonal of the weighted hat matrix
 * H = W^1/2 X (X^T W X)^-1 X^T W^1/2 (of the free parameters' columns under nonneg): the
 * leverages h_kk = ||Q_k||^2, the squared norms of the rows of the thin Q of W^1/2 X. */
int wls_solve_hat(const double *X, const double *w, const double *y, size_t n, size_t m,
                  int nonneg, double *c, double *cov, double *hat, const fit_stop_t *stop,
                  wls_result_t *res);

#endif
