/* test_solve.c: the linear least-squares path of fit_map (LAPACK QR, fit/wls.c) against
 * computations that share none of its code: the design matrix by adaptive quadrature
 * (fit_box_integral, not design.c), the closed-form one-parameter solution and its variance,
 * the exact map on noiseless data built from known S and I0, and the leave-one-out chi2
 * against brute-force refits without each point, and the leverages of an ill-conditioned matrix
 * whose column space is known in closed form. Also the rank-deficient fallback. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/box.h"
#include "fit/model.h"
#include "fit/noise.h"
#include "fit/wls.h"

#define NG 7            /* NG x NG spot positions */
#define NP (NG * NG)
#define R_UM 1.34
#define PITCH 6.0

static double xs[NP], ys[NP];

static fit_scan_t make_scan(const double *x, const double *y, const double *sig, size_t n)
{
    return (fit_scan_t){.n = n, .x_um = x, .y_um = y, .signal_dn = sig, .pitch_um = PITCH,
                        .spot_radius_um = R_UM, .bias_dn = 100, .gain_e_per_dn = 3,
                        .read_noise_e = 5, .frames = 12, .full_scale_dn = 0};
}

/* A (n x r*r, column j*r + i) by adaptive quadrature. */
static void box_matrix(int r, const double *x, const double *y, size_t n, double *A)
{
    double h = PITCH / r;
    for (size_t k = 0; k < n; k++)
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) {
                fit_rect_t rect = {i * h, (i + 1) * h, j * h, (j + 1) * h};
                double v;
                CHECK(fit_box_integral(R_UM, &rect, x[k], y[k], 1e-13, &v, NULL, NULL) == 0);
                A[k * (size_t)(r * r) + (size_t)(j * r + i)] = v;
            }
}

/* The weight fit_map gives a point: eq. 5 with the rounding floor of model.c's contract. */
static double weight(const fit_scan_t *s, double signal)
{
    double sg = fmax(fit_noise_sigma(FIT_NOISE_PAPER, s, signal), sqrt(1.0 / 12 / s->frames));
    return 1 / (sg * sg);
}

/* Noiseless data from a known map: the fit returns it. */
static void test_exact(void)
{
    const int r = 2;
    const double S[4] = {1.2, 0.8, 1.1, 0.9}, I0 = 5000; /* mean of S is 1 */
    double A[NP * 4], sig[NP];
    box_matrix(r, xs, ys, NP, A);
    for (size_t k = 0; k < NP; k++) {
        double m = 0;
        for (int j = 0; j < 4; j++) m += A[k * 4 + (size_t)j] * S[j];
        sig[k] = 100 + I0 * m;
    }
    fit_scan_t s = make_scan(xs, ys, sig, NP);
    fit_result_t res;
    CHECK(fit_map(&s, r, NULL, &res, NULL) == 0);
    CHECK(res.S != NULL);
    CHECK_NEAR(res.I0, I0, 1e-9, 0);
    for (int j = 0; j < 4 && res.S; j++) CHECK_NEAR(res.S[j], S[j], 0, 1e-9);
    CHECK(res.chi2 < 1e-12);
    CHECK(res.cond >= 1 && res.cond < 1e3);
    fit_result_free(&res);
}

/* r = 1: one parameter T, T = sum w a d / sum w a^2 and Var(T) = 1 / sum w a^2. */
static void test_one_parameter(const double *sig)
{
    double A[NP];
    box_matrix(1, xs, ys, NP, A);
    fit_scan_t s = make_scan(xs, ys, sig, NP);
    double swad = 0, swaa = 0, chi2 = 0;
    for (size_t k = 0; k < NP; k++) {
        double w = weight(&s, sig[k]), d = sig[k] - s.bias_dn;
        swad += w * A[k] * d;
        swaa += w * A[k] * A[k];
    }
    double T = swad / swaa;
    for (size_t k = 0; k < NP; k++) {
        double e = sig[k] - s.bias_dn - T * A[k];
        chi2 += weight(&s, sig[k]) * e * e;
    }
    fit_result_t res;
    CHECK(fit_map(&s, 1, NULL, &res, NULL) == 0);
    CHECK_NEAR(res.I0, T, 1e-10, 0);
    CHECK_NEAR(res.I0_err, 1 / sqrt(swaa), 1e-9, 0);
    CHECK_NEAR(res.chi2, chi2, 1e-9, 0);
    CHECK_NEAR(res.cond, 1, 1e-12, 0);
    fit_result_free(&res);
}

/* cv_chi2 against refitting without each point in turn and predicting it. */
static void test_leave_one_out(const double *sig)
{
    const int r = 2;
    double A[NP * 4], x[NP], y[NP], sg[NP];
    box_matrix(r, xs, ys, NP, A);
    fit_scan_t s = make_scan(xs, ys, sig, NP);
    fit_result_t all;
    CHECK(fit_map(&s, r, NULL, &all, NULL) == 0);
    double cv = 0;
    for (size_t k = 0; k < NP; k++) {
        size_t n = 0;
        for (size_t q = 0; q < NP; q++)
            if (q != k) x[n] = xs[q], y[n] = ys[q], sg[n] = sig[q], n++;
        fit_scan_t s1 = make_scan(x, y, sg, n);
        fit_result_t res;
        CHECK(fit_map(&s1, r, NULL, &res, NULL) == 0);
        if (!res.S) {
            CHECK(res.S != NULL);
            fit_result_free(&res);
            continue;
        }
        double pred = 0;
        for (int j = 0; j < 4; j++) pred += A[k * 4 + (size_t)j] * res.S[j];
        double e = sig[k] - s.bias_dn - res.I0 * pred;
        cv += weight(&s, sig[k]) * e * e;
        fit_result_free(&res);
    }
    CHECK_NEAR(all.cv_chi2, cv, 1e-8, 0);
    CHECK(all.cv_chi2 > all.chi2);
    fit_result_free(&all);
}

/* Q0_kj: the orthonormal DCT-II basis on n points (column j). */
static double dct_basis(int n, int k, int j)
{
    return (j ? sqrt(2.0 / n) : sqrt(1.0 / n)) * cos(M_PI * (k + 0.5) * j / n);
}

/* X = Q0 R0 (n x m, row-major) with R0_ij = d_i = 10^(-9 i / (m - 1)) for i <= j: column j is
 * column j - 1 plus d_j Q0_j, so the columns are nearly parallel whatever their scaling (cond
 * ~1e9 after the column balancing); and h0_k = sum_j Q0_kj^2. */
static void ill_conditioned(int n, int m, double *X, double *h0)
{
    for (int k = 0; k < n; k++) {
        h0[k] = 0;
        for (int j = 0; j < m; j++) {
            double x = 0, q = dct_basis(n, k, j);
            h0[k] += q * q;
            for (int i = 0; i <= j; i++) x += dct_basis(n, k, i) * pow(10, -9.0 * i / (m - 1));
            X[k * m + j] = x;
        }
    }
}

/* Leverages (wls_solve_hat) of X = Q0 R0: the hat matrix is Q0 Q0^T whatever R0 is, so
 * h_k = sum_j Q0_kj^2, while R0 makes cond ~1e9 and more. X is rounded as it is built, which
 * moves its column space by ~cond x eps, so h_k agrees to that (1e-6); but the h_k of the thin
 * Q, orthonormal to rounding, sum to m to rounding (the trace of a projector) and are each 1
 * with as many points as parameters, at any cond. Leverages from A R^-1 (not orthonormal) would
 * miss both by ~cond x eps. */
static void test_leverages(void)
{
    enum { N = 200, M = 48 };
    static double X[N * M], w[N], y[N], c[M], hat[N], h0[N];
    for (int k = 0; k < N; k++) w[k] = 1, y[k] = sin(0.1 * k);
    ill_conditioned(N, M, X, h0);
    wls_result_t res;
    CHECK(wls_solve_hat(X, w, y, N, M, 0, c, NULL, hat, NULL, &res) == 0);
    CHECK(res.lapack == 1);
    CHECK(1 / res.rcond > 1e9);
    double sum = 0;
    for (int k = 0; k < N; k++) {
        CHECK_NEAR(hat[k], h0[k], 0, 1e-6);
        sum += hat[k];
    }
    CHECK_NEAR(sum, M, 1e-12, 0);
    ill_conditioned(M, M, X, h0); /* square */
    CHECK(wls_solve_hat(X, w, y, M, M, 0, c, NULL, hat, NULL, &res) == 0);
    CHECK(res.lapack == 1);
    for (int k = 0; k < M; k++) CHECK_NEAR(hat[k], 1, 0, 1e-12);
}

/* Every spot at one place: the columns are proportional, the fit says so (the SVD fallback). */
static void test_rank_deficient(void)
{
    double x[9], y[9], sig[9];
    for (int k = 0; k < 9; k++) x[k] = 3, y[k] = 3, sig[k] = 1000 + k;
    fit_scan_t s = make_scan(x, y, sig, 9);
    fit_result_t res;
    CHECK(fit_map(&s, 2, NULL, &res, NULL) == 0);
    CHECK(res.flags & FIT_ILL_CONDITIONED);
    CHECK(isfinite(res.chi2));
    fit_result_free(&res);
}

int main(void)
{
    for (int j = 0; j < NG; j++)
        for (int i = 0; i < NG; i++) {
            xs[j * NG + i] = 0.6 + 0.8 * i;
            ys[j * NG + i] = 0.6 + 0.8 * j;
        }
    /* data: a smooth map plus a deterministic ripple standing in for noise */
    double A[NP * 4], sig[NP];
    box_matrix(2, xs, ys, NP, A);
    for (size_t k = 0; k < NP; k++)
        sig[k] = 100 + 3000 * (1.1 * A[k * 4] + 0.9 * A[k * 4 + 1] + A[k * 4 + 2] +
                               A[k * 4 + 3]) +
                 4 * sin(7.3 * (double)k);
    test_exact();
    test_one_parameter(sig);
    test_leave_one_out(sig);
    test_leverages();
    test_rank_deficient();
    CHECK_DONE();
}
