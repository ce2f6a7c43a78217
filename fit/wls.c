/* wls.c: weighted linear least squares through LAPACK's recursive Householder QR (dgeqrt with
 * one block: the compact WY form Q = I - V T V^T) of the column-balanced weighted matrix, with
 * the exact 2-norm condition number from the singular values of R, the covariance from
 * R^-1 R^-T and the leverages from the rows of the thin Q; a rank-deficient matrix falls back to
 * GSL's truncated SVD (the minimum-norm solution). And non-negative least squares by the
 * active-set method of Lawson and Hanson (1974, ch. 23), hand-written because neither GSL nor
 * LAPACK has one; each subproblem is the same solve.
 *
 * Why QR and not SVD: W^1/2 X D^-1 = Q R (D the column balancing) costs 2 n m^2 flops in
 * BLAS-3 blocks, a few times less than GSL's unblocked one-sided SVD, and R has the same
 * singular values as the matrix itself, so cond comes from an m x m SVD (no U, no V) instead of
 * an n x m one. Householder QR is backward stable like the SVD: chi2, the parameters and the
 * covariance agree with the SVD's to rounding times cond (docs/numerics.md).
 * Why dgeqrt and not dgeqrf + dorgqr: LAPACK's blocked dgeqrf and dorgqr run their last 128
 * columns through the unblocked (BLAS-2) code, i.e. all of a fit with r <= 11; dgeqrt's
 * recursive panel (dgeqrt3) is BLAS-3 throughout, and the single T gives the thin Q's rows by
 * two triangular multiplies (qr_leverages). On the 41 x 41 raster at r = 12 (1681 x 144) the
 * factorisation and the leverages took 3.3 + 3.2 ms, now 2.1 + 1.0 ms (random matrices of that
 * shape, one OpenBLAS thread, 2026-11-24; the whole 41 x 41 sweep: docs/numerics.md). */
#include "wls.h"

#include <errno.h>
#include <float.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gemm.h"
#include "fit/gslerr.h"

/* A column's scale: the power of two that brings its 1-norm into [0.5, 1], so balancing is exact
 * (no rounding) and the same as gsl_linalg_balance_columns' (the condition numbers agree with
 * the former SVD path's). */
static double balance_scale(double asum)
{
    if (!(asum > 0) || !isfinite(asum)) return 1;
    double f = 1;
    while (asum > 1) asum /= 2, f *= 2;
    while (asum < 0.5) asum *= 2, f /= 2;
    return f;
}

/* chi2 of c (over columns cols) with the original X: sum w_k (y_k - X_k c)^2. */
static double chi2_of(const double *X, const double *w, const double *y, size_t n, size_t m,
                      const size_t *cols, size_t mc, const double *c)
{
    double chi2 = 0;
    for (size_t k = 0; k < n; k++) {
        double e = y[k];
        const double *x = X + k * m;
        if (cols)
            for (size_t j = 0; j < mc; j++) e -= x[cols[j]] * c[j];
        else
            for (size_t j = 0; j < mc; j++) e -= x[j] * c[j];
        chi2 += w[k] * e * e;
    }
    return chi2;
}

struct qr_work {
    double *A, *b, *T, *R, *Rs, *s, *d;
};

static void qr_work_free(struct qr_work *q)
{
    free(q->A);
    free(q->R);
}

static int qr_work_alloc(struct qr_work *q, size_t n, size_t mc)
{
    memset(q, 0, sizeof *q);
    q->A = malloc(sizeof(double) * (n * mc + n));
    q->R = malloc(sizeof(double) * (3 * mc * mc + 2 * mc));
    if (!q->A || !q->R) return -ENOMEM;
    q->b = q->A + n * mc;
    q->Rs = q->R + mc * mc;
    q->T = q->Rs + mc * mc;
    q->s = q->T + mc * mc;
    q->d = q->s + mc;
    return 0;
}

/* The leverages h_kk = ||Q_k||^2, Q_k row k of the thin Q = Q [I; 0] (exact to rounding at any
 * cond: Q is orthogonal to rounding; A R^-1 would lose cond x eps, bench/README.md; test_solve
 * checks both). With Q = I - V T V^T and V = [V1; V2] (V1 unit lower triangular, mc x mc), the
 * thin Q is [I - V1 M; -V2 M] with M = T V1^T, upper triangular as a product of two upper
 * triangles, so V2 M = (V2 T) V1^T is formed in place over V2 by two triangular multiplies
 * (dtrmm) and the top block I - V1 T V1^T in Rs (free once the singular values are out).
 * Destroys V. */
static void qr_leverages(struct qr_work *q, size_t n, size_t mc, double *hat)
{
    double *top = q->Rs;
    for (size_t j = 0; j < mc; j++)
        for (size_t i = 0; i < mc; i++) top[i + j * mc] = i <= j ? q->T[i + j * mc] : 0;
    fit_trmm(0, 0, 1, 1, mc, mc, q->A, n, top, mc); /* M = T V1^T */
    fit_trmm(1, 0, 0, 1, mc, mc, q->A, n, top, mc); /* V1 M */
    if (n > mc) {
        fit_trmm(0, 1, 0, 0, n - mc, mc, q->T, mc, q->A + mc, n); /* V2 T */
        fit_trmm(0, 0, 1, 1, n - mc, mc, q->A, n, q->A + mc, n);  /* (V2 T) V1^T = V2 M */
    }
    memset(hat, 0, sizeof(double) * n);
    for (size_t j = 0; j < mc; j++) {
        const double *vj = q->A + j * n, *tj = top + j * mc;
        for (size_t k = 0; k < mc; k++) {
            double e = (k == j) - tj[k];
            hat[k] += e * e;
        }
        for (size_t k = mc; k < n; k++) hat[k] += vj[k] * vj[k];
    }
}

/* The QR path on the columns cols (all when NULL). Returns 0, 1 when the balanced matrix is
 * rank-deficient (singular values at or below DBL_EPSILON times the largest, GSL's tsvd
 * truncation: the caller falls back), -ENOMEM or -EDOM. */
static int qr_solve(const double *X, const double *w, const double *y, size_t n, size_t m,
                    const size_t *cols, size_t mc, double *c, double *cov, double *hat,
                    double *rcond)
{
    struct qr_work q;
    double wq = 0, *work = NULL;
    lapack_int *iwork = NULL;
    int rc = qr_work_alloc(&q, n, mc);
    if (rc) goto out;
    if (n < mc || mc == 0) { /* fewer points than columns: rank-deficient by count */
        rc = 1;
        goto out;
    }
    lapack_int N = (lapack_int)n, M = (lapack_int)mc;
    /* A = W^1/2 X (column-major, as LAPACK wants it), b = W^1/2 y */
    for (size_t k = 0; k < n; k++) q.b[k] = sqrt(w[k]); /* W^1/2 for now */
    for (size_t k0 = 0; k0 < n; k0 += 32) { /* transposed in blocks of 32 rows: each column's
                                              writes stay contiguous, the rows in cache */
        size_t k1 = k0 + 32 < n ? k0 + 32 : n;
        for (size_t j = 0; j < mc; j++) {
            size_t cj = cols ? cols[j] : j;
            double *a = q.A + j * n;
            for (size_t k = k0; k < k1; k++) a[k] = q.b[k] * X[k * m + cj];
        }
    }
    for (size_t k = 0; k < n; k++) q.b[k] *= y[k];
    for (size_t j = 0; j < mc; j++) { /* column balancing: A D^-1 */
        double *a = q.A + j * n, ss = 0;
        for (size_t k = 0; k < n; k++) ss += fabs(a[k]);
        q.d[j] = balance_scale(ss);
        double inv = 1 / q.d[j];
        for (size_t k = 0; k < n; k++) a[k] *= inv;
    }
    /* LAPACKE's _work calls: the plain ones scan every input for NaN first (2 % of a 41 x 41
     * sweep's instructions) and allocate their workspace on each call; one workspace here.
     * dgeqrt wants mc x mc, dgemqrt (one column) mc, dgesdd what it says. */
    iwork = malloc(sizeof(lapack_int) * 8 * mc);
    if (!iwork || LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'N', M, M, q.Rs, M, q.s, NULL, 1, NULL,
                                      1, &wq, -1, iwork)) {
        rc = iwork ? -EDOM : -ENOMEM;
        goto out;
    }
    size_t lwork = mc * mc > (size_t)wq ? mc * mc : (size_t)wq;
    if (!(work = malloc(sizeof(double) * lwork))) {
        rc = -ENOMEM;
        goto out;
    }
    /* A = Q R with Q = I - V T V^T: V below A's diagonal (unit diagonal implied), R on and
     * above it, T (mc x mc, upper triangular) apart: one block, nb = mc */
    if (LAPACKE_dgeqrt_work(LAPACK_COL_MAJOR, N, M, M, q.A, N, q.T, M, work)) {
        rc = -EDOM;
        goto out;
    }
    for (size_t j = 0; j < mc; j++) /* R (upper triangle) and a copy for its singular values */
        for (size_t i = 0; i < mc; i++) q.R[i + j * mc] = q.Rs[i + j * mc] = i <= j ? q.A[i + j * n] : 0;
    if (LAPACKE_dgesdd_work(LAPACK_COL_MAJOR, 'N', M, M, q.Rs, M, q.s, NULL, 1, NULL, 1, work,
                            (lapack_int)lwork, iwork)) {
        rc = -EDOM;
        goto out;
    }
    if (!(q.s[mc - 1] > DBL_EPSILON * q.s[0])) { /* rank-deficient (or NaN) */
        rc = 1;
        goto out;
    }
    *rcond = q.s[mc - 1] / q.s[0];
    /* x = R^-1 (Q^T b), c = D^-1 x */
    if (LAPACKE_dgemqrt_work(LAPACK_COL_MAJOR, 'L', 'T', N, 1, M, M, q.A, N, q.T, M, q.b, N,
                             work) ||
        LAPACKE_dtrtrs_work(LAPACK_COL_MAJOR, 'U', 'N', 'N', M, 1, q.R, M, q.b, N)) {
        rc = -EDOM;
        goto out;
    }
    for (size_t j = 0; j < mc; j++) c[j] = q.b[j] / q.d[j];
    if (hat) qr_leverages(&q, n, mc, hat); /* before cov: it overwrites R */
    if (cov) { /* (X^T W X)^-1 = D^-1 R^-1 R^-T D^-1: dtrtri, then dlauum forms U U^T */
        if (LAPACKE_dtrtri_work(LAPACK_COL_MAJOR, 'U', 'N', M, q.R, M) ||
            LAPACKE_dlauum_work(LAPACK_COL_MAJOR, 'U', M, q.R, M)) {
            rc = -EDOM;
            goto out;
        }
        for (size_t j = 0; j < mc; j++)
            for (size_t i = 0; i <= j; i++)
                cov[i * mc + j] = cov[j * mc + i] = q.R[i + j * mc] / (q.d[i] * q.d[j]);
    }
out:
    free(work);
    free(iwork);
    qr_work_free(&q);
    return rc;
}

/* The fallback for a rank-deficient matrix: GSL's column-balanced SVD truncated at
 * DBL_EPSILON of the largest singular value (the minimum-norm solution on the numerical rank). */
static int svd_solve(const double *X, const double *w, const double *y, size_t n, size_t m,
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

/* Leverages from the covariance, h_kk = w_k x_k^T C x_k (the fallback's way; C is (X^T W X)^+). */
static void hat_from_cov(const double *X, const double *w, size_t n, size_t m, const size_t *cols,
                         size_t mc, const double *C, double *hat)
{
    for (size_t k = 0; k < n; k++) {
        const double *x = X + k * m;
        double h = 0;
        for (size_t i = 0; i < mc; i++) {
            double ci = 0;
            for (size_t j = 0; j < mc; j++) ci += C[i * mc + j] * x[cols ? cols[j] : j];
            h += x[cols ? cols[i] : i] * ci;
        }
        hat[k] = w[k] * h;
    }
}

/* Unconstrained solve on the columns listed in cols (all when cols is NULL, mc = m): the QR
 * path, or the SVD when the matrix is rank-deficient. */
static int solve_cols(const double *X, const double *w, const double *y, size_t n, size_t m,
                      const size_t *cols, size_t mc, double *c, double *cov, double *hat,
                      wls_result_t *res)
{
    int rc = qr_solve(X, w, y, n, m, cols, mc, c, cov, hat, &res->rcond);
    if (rc == 0) {
        res->chi2 = chi2_of(X, w, y, n, m, cols, mc, c);
        res->rank = mc;
        res->lapack = 1;
        return 0;
    }
    if (rc < 0) return rc;
    res->lapack = 0;
    double *C = cov;
    if (!C && hat && !(C = malloc(sizeof(double) * mc * mc))) return -ENOMEM;
    rc = svd_solve(X, w, y, n, m, cols, mc, c, C, &res->chi2, &res->rcond, &res->rank);
    if (rc == 0 && hat) hat_from_cov(X, w, n, m, cols, mc, C, hat);
    if (C != cov) free(C);
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

/* The stop poll of the active-set loops (stop.h's site "nnls"); stop may be NULL. */
static int stopped(const fit_stop_t *stop)
{
    return stop && fit_stop_at(stop, FIT_STOP_SITE_NNLS);
}

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
                      double *c, struct nnls_work *nw, const fit_stop_t *stop, wls_result_t *res)
{
    for (int inner = 0; inner < 3 * (int)m + 10; inner++) {
        if (stopped(stop)) return -ECANCELED; /* each step is a QR of n x np */
        size_t np = passive_cols(nw, m);
        int rc = solve_cols(X, w, y, n, m, nw->cols, np, nw->zc, NULL, NULL, res);
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
                       double *c, double *cov, double *hat, struct nnls_work *nw,
                       wls_result_t *res)
{
    size_t np = passive_cols(nw, m);
    memset(c, 0, sizeof(double) * m);
    if (cov) memset(cov, 0, sizeof(double) * m * m);
    if (hat) memset(hat, 0, sizeof(double) * n);
    res->n_bound = m - np;
    if (!np) {
        res->chi2 = 0;
        for (size_t k = 0; k < n; k++) res->chi2 += w[k] * y[k] * y[k];
        return 0;
    }
    int rc = solve_cols(X, w, y, n, m, nw->cols, np, nw->zc, cov ? nw->cv : NULL, hat, res);
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
                double *cov, double *hat, const fit_stop_t *stop, wls_result_t *res)
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
        if (stopped(stop)) {
            rc = -ECANCELED;
            break;
        }
        neg_gradient(X, w, y, n, m, c, nw.g);
        double gmax = 0, gscale = 0;
        size_t jmax = m;
        for (size_t j = 0; j < m; j++) gscale = fmax(gscale, fabs(nw.g[j]));
        if (outer == 0) gtol = 1e-12 * gscale;
        for (size_t j = 0; j < m; j++)
            if (!nw.passive[j] && nw.g[j] > gmax) gmax = nw.g[j], jmax = j;
        if (jmax == m || gmax <= gtol) break; /* KKT conditions hold */
        nw.passive[jmax] = 1;
        rc = nnls_inner(X, w, y, n, m, c, &nw, stop, res);
    }
    if (!rc) rc = nnls_finish(X, w, y, n, m, c, cov, hat, &nw, res);
out:
    free(nw.passive);
    free(nw.cols);
    free(nw.g);
    free(nw.z);
    free(nw.zc);
    free(nw.cv);
    return rc;
}

int wls_solve_hat(const double *X, const double *w, const double *y, size_t n, size_t m,
                  int nonneg, double *c, double *cov, double *hat, const fit_stop_t *stop,
                  wls_result_t *res)
{
    memset(res, 0, sizeof *res);
    fit_gsl_policy(); /* GSL's handler off (the SVD fallback), OpenBLAS on this thread */
    if (nonneg) return nnls(X, w, y, n, m, c, cov, hat, stop, res);
    int rc = solve_cols(X, w, y, n, m, NULL, m, c, cov, hat, res);
    /* one LAPACK call, which cannot be interrupted: polled after it */
    return rc == 0 && stop && fit_stop_now(stop) ? -ECANCELED : rc;
}

int wls_solve(const double *X, const double *w, const double *y, size_t n, size_t m, int nonneg,
              double *c, double *cov, const fit_stop_t *stop, wls_result_t *res)
{
    return wls_solve_hat(X, w, y, n, m, nonneg, c, cov, NULL, stop, res);
}
