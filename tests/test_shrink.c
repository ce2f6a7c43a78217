/* test_shrink.c: the shrunk map (fit/shrink.h) against analytic and independent values: the area
 * overlaps of two grids; with isotropic noise V = sigma^2 I, the empirical-Bayes shrinkage is the
 * positive-part James-Stein factor 1 - d sigma^2 / |D|^2 (and its S_err g sigma); with two noise
 * levels, tau^2 and the kept fractions against a brute-force search of the marginal likelihood;
 * the joint covariance of two fits (fit_map_joint_cov) against fit_map's own S_err and against
 * finite differences of refits; and in a sweep: none at r = 1. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/box.h"
#include "fit/noise.h"
#include "fit/shrink.h"

static void overlaps(void)
{
    double w[12 * 12];
    for (int r = 2; r <= 12; r++)
        for (int q = 1; q < r; q++) {
            fit_grid_overlap(r, q, w);
            for (int a = 0; a < r; a++) { /* each fine cell is covered once */
                double s = 0;
                for (int b = 0; b < q; b++) s += w[a * q + b];
                CHECK_NEAR(s, 1, 1e-12, 0);
            }
            for (int b = 0; b < q; b++) { /* each coarse cell's width, r/q fine cells */
                double s = 0;
                for (int a = 0; a < r; a++) s += w[a * q + b];
                CHECK_NEAR(s, (double)r / q, 1e-12, 0);
            }
        }
    fit_grid_overlap(3, 2, w); /* [0,1/3) in [0,1/2); [1/3,2/3) half in each; [2/3,1) in [1/2,1) */
    CHECK(w[0] == 1 && w[1] == 0 && w[4] == 0 && w[5] == 1);
    CHECK_NEAR(w[2], 0.5, 1e-12, 0);
    CHECK_NEAR(w[3], 0.5, 1e-12, 0);
    /* a 2 x 2 map averaged onto 3 x 3: corners keep their cell, edge middles average two cells,
     * the centre all four; and back onto 1 x 1, the mean */
    double v[4] = {1, 2, 3, 4}, out[9], want[9] = {1, 1.5, 2, 2, 2.5, 3, 3, 3.5, 4}, one;
    CHECK(fit_grid_average(v, 2, 3, out) == 0);
    for (int j = 0; j < 9; j++) CHECK_NEAR(out[j], want[j], 1e-12, 0);
    CHECK(fit_grid_average(v, 2, 1, &one) == 0);
    CHECK_NEAR(one, 2.5, 1e-12, 0);
}

/* A checkerboard of amplitude a (r = 2) over a flat r = 1 map with V = sigma^2 I: the marginal
 * likelihood of tau^2 peaks at |D|^2 / d - sigma^2 = a^2 - sigma^2, so g = 1 - sigma^2 / a^2
 * (0 when sigma >= a), S = 1 +- g a, S_err^2 = g^2 sigma^2 (noise) + (1 - g)^2 tau^2 (bias)
 * = g sigma^2, the posterior variance (the coarse map has no noise here). */
static void isotropic(void)
{
    double a = 0.1, Sr[4] = {1 + a, 1 - a, 1 - a, 1 + a}, Sq = 1, Cqq = 0, Crq[4] = {0};
    double Crr[16];
    static const struct {
        double sigma, scale, g;
    } cases[] = {
        {0.05, 1, 0.75}, {0.02, 1, 0.96}, {0.025, 2, 0.75}, /* the scatter doubles sigma */
        {0.1, 1, 0}, {0.2, 1, 0},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        double s = cases[k].sigma, g = cases[k].g, se = s * cases[k].scale;
        memset(Crr, 0, sizeof Crr);
        for (int j = 0; j < 4; j++) Crr[j * 4 + j] = s * s;
        fit_shrunk_t out;
        err_t err;
        CHECK(fit_shrink_with_cov(Sr, 2, &Sq, 1, Crr, &Cqq, Crq, cases[k].scale, &out, &err) == 0);
        CHECK(out.r == 2 && out.toward_r == 1);
        CHECK_NEAR(out.factor, g, 1e-5, 1e-5);
        CHECK_NEAR(out.S[0], 1 + g * a, 1e-6, 1e-6);
        CHECK_NEAR(out.S[1], 1 - g * a, 1e-6, 1e-6);
        CHECK_NEAR(out.S_err[0], sqrt(g) * s, 1e-5, 1e-6);
        for (int j = 0; j < 4; j++) /* that fraction of the kept detail g a */
            CHECK_NEAR(out.S_res[j], FIT_RES_FRACTION * g * a, 1e-5, 1e-6);
        CHECK_NEAR(out.tau, g > 0 ? sqrt(a * a - se * se) : 0, 1e-5, 1e-6);
        CHECK_NEAR(out.noise, se, 1e-12, 0);
        CHECK_NEAR(out.detail, a, 1e-12, 0);
        fit_shrunk_free(&out);
    }
    /* refused: no coarser map */
    fit_shrunk_t out;
    err_t err;
    CHECK(fit_shrink_with_cov(Sr, 2, Sr, 2, Crr, Crr, Crr, 1, &out, &err) == -EINVAL);
    CHECK(out.S == NULL);
}

/* Two noisy patterns of a 2 x 2 map over a flat one: the checkerboard u1 with noise variance
 * 0.01 and the left-right step u2 with 1e-4, the top-bottom step u3 with 1e-4; D = 0.12 u1 +
 * 0.08 u2 + 0.01 u3. tau^2 from a brute-force scan of the marginal likelihood; each pattern
 * keeps tau^2 / (tau^2 + lambda): the checkerboard, within its noise, mostly goes. */
static void two_levels(void)
{
    static const double u[3][4] = {{0.5, -0.5, -0.5, 0.5}, {0.5, -0.5, 0.5, -0.5},
                                   {0.5, 0.5, -0.5, -0.5}};
    const double lam[3] = {0.01, 1e-4, 1e-4}, c[3] = {0.12, 0.08, 0.01};
    double Crr[16] = {0}, Sr[4], Sq = 1, Cqq = 0, Crq[4] = {0};
    for (int j = 0; j < 4; j++) {
        Sr[j] = 1;
        for (int p = 0; p < 3; p++) Sr[j] += c[p] * u[p][j];
        for (int k = 0; k < 4; k++)
            for (int p = 0; p < 3; p++) Crr[j * 4 + k] += lam[p] * u[p][j] * u[p][k];
    }
    double best_t = 0, best_f = INFINITY; /* brute force over log tau^2 */
    for (int i = 0; i <= 200000; i++) {
        double t = exp(log(1e-9) + (log(1.0) - log(1e-9)) * i / 200000.0), f = 0;
        for (int p = 0; p < 3; p++) f += log(t + lam[p]) + c[p] * c[p] / (t + lam[p]);
        if (f < best_f) best_f = f, best_t = t;
    }
    fit_shrunk_t out;
    err_t err;
    CHECK(fit_shrink_with_cov(Sr, 2, &Sq, 1, Crr, &Cqq, Crq, 1, &out, &err) == 0);
    CHECK_NEAR(out.tau * out.tau, best_t, 1e-3, 0);
    for (int j = 0; j < 4; j++) {
        double want = 1;
        for (int p = 0; p < 3; p++) want += best_t / (best_t + lam[p]) * c[p] * u[p][j];
        CHECK_NEAR(out.S[j], want, 1e-4, 0);
    }
    double g1 = best_t / (best_t + lam[0]), g2 = best_t / (best_t + lam[1]);
    CHECK(g1 < 0.5 && g2 > 0.9); /* the noisy checkerboard mostly goes, the step stays */
    fit_shrunk_free(&out);
}

/* fit_map_joint_cov on a synthetic 9 x 9 scan of a pixel with four quadrants of different
 * sensitivity (r = 4 and 2, which both represent it exactly, so the weights' dependence on the
 * signal does not enter the first-order response): the diagonals are fit_map's S_err^2, and
 * Cov(S4, S2) equals L4 diag(sigma^2) L2^T with L = dS/d(signal) from central differences of
 * refits. */
static void joint_cov(void)
{
    enum { NG = 9, N = NG * NG, A = 4, B = 2, MA = A * A, MB = B * B };
    static const double quad[MB] = {0.8, 1.1, 1.0, 1.2};
    double x[N], y[N], sig[N];
    for (int q = 0; q < N; q++) {
        x[q] = 0.6 + 0.6 * (q % NG);
        y[q] = 0.6 + 0.6 * (q / NG);
        double m = 0;
        for (int c = 0; c < MB; c++) {
            fit_rect_t b = {3.0 * (c % 2), 3.0 * (c % 2 + 1), 3.0 * (c / 2), 3.0 * (c / 2 + 1)};
            double v, e;
            fit_box_integral(1.34, &b, x[q], y[q], 1e-14, &v, &e, NULL);
            m += quad[c] * v;
        }
        sig[q] = 100 + 2000 * m;
    }
    fit_scan_t sc = {N, x, y, sig, 6.0, 1.34, 100, 3.153, 5.67, 12, FIT_FULL_SCALE_DEFAULT};
    double CA[MA * MA], CB[MB * MB], CAB[MA * MB];
    err_t err;
    CHECK(fit_map_joint_cov(&sc, A, B, NULL, CA, CB, CAB, &err) == 0);
    fit_result_t fa, fb;
    CHECK(fit_map(&sc, A, NULL, &fa, &err) == 0 && fit_map(&sc, B, NULL, &fb, &err) == 0);
    for (int j = 0; j < MA; j++) CHECK_NEAR(sqrt(CA[j * MA + j]), fa.S_err[j], 1e-7, 0);
    for (int j = 0; j < MB; j++) CHECK_NEAR(sqrt(CB[j * MB + j]), fb.S_err[j], 1e-7, 0);
    static double LA[MA * N], LB[MB * N];
    double s2[N], h = 1e-3;
    fit_options_t o = fit_options_default();
    for (int k = 0; k < N; k++) {
        s2[k] = pow(fit_noise_sigma(o.noise, &sc, sig[k]), 2);
        fit_result_t pa, ma, pb, mb;
        double s0 = sig[k];
        sig[k] = s0 + h;
        fit_map(&sc, A, NULL, &pa, &err), fit_map(&sc, B, NULL, &pb, &err);
        sig[k] = s0 - h;
        fit_map(&sc, A, NULL, &ma, &err), fit_map(&sc, B, NULL, &mb, &err);
        sig[k] = s0;
        for (int j = 0; j < MA; j++) LA[j * N + k] = (pa.S[j] - ma.S[j]) / (2 * h);
        for (int j = 0; j < MB; j++) LB[j * N + k] = (pb.S[j] - mb.S[j]) / (2 * h);
        fit_result_free(&pa), fit_result_free(&ma), fit_result_free(&pb), fit_result_free(&mb);
    }
    double worst = 0, scale = 0;
    for (int i = 0; i < MA; i++)
        for (int j = 0; j < MB; j++) {
            double c = 0;
            for (int k = 0; k < N; k++) c += LA[i * N + k] * s2[k] * LB[j * N + k];
            worst = fmax(worst, fabs(c - CAB[i * MB + j]));
            scale = fmax(scale, fabs(c));
        }
    CHECK(scale > 0 && worst <= 1e-4 * scale);
    fit_result_free(&fa), fit_result_free(&fb);
    /* too few points for r = 9 (82 parameters, 81 points) */
    static double big[81 * 81];
    CHECK(fit_map_joint_cov(&sc, 9, 2, NULL, big, CB, big, &err) == -EINVAL);
}

/* In a sweep: none when the recommendation is r = 1 or r - 1 is outside the sweep. */
static void in_sweep(void)
{
    double one = 1, zero = 0, S2[4] = {0.9, 1.1, 1.1, 0.9}, E2[4] = {0.01, 0.01, 0.01, 0.01};
    fit_result_t f[2];
    memset(f, 0, sizeof f);
    f[0].r = 1, f[0].S = &one, f[0].S_err = &zero;
    f[1].r = 2, f[1].S = S2, f[1].S_err = E2;
    fit_sweep_t sw = {.r_min = 1, .r_max = 2, .fits = f, .recommended_r = 1};
    fit_scan_t none = {0};
    fit_shrunk_t s;
    err_t err;
    CHECK(fit_shrink_recommended(&none, NULL, &sw, 1, &s, &err) == 0 && s.r == 0 && !s.S);
    sw = (fit_sweep_t){.r_min = 2, .r_max = 2, .fits = f + 1, .recommended_r = 2};
    CHECK(fit_shrink_recommended(&none, NULL, &sw, 1, &s, &err) == 0 && s.r == 0);
}

int main(void)
{
    overlaps();
    isotropic();
    two_levels();
    joint_cov();
    in_sweep();
    CHECK_DONE();
}
