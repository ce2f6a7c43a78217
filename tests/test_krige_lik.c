/* test_krige_lik.c (white box: fit/krige_int.h, fit/krige_kernel.h): the kriged map's algebra
 * against independent computations.
 *   - The exponential kernel's closed forms (krige_kernel.c) against dense matrices built from
 *     their definition, exp(-|i - j| / (F l)), and LAPACK: the factor's Gram products, the
 *     tridiagonal inverse, the log determinant, the stencil trace, and each derivative in log l
 *     against central differences.
 *   - The restricted likelihood in the points' space (an n x n factorisation) and in the fine
 *     cells' space (Henderson's mixed-model equations) are two formulas for one number: their
 *     -log L, gradients, average information and posterior maps agree; the gradient agrees with
 *     central differences of -log L. The posterior's whole covariance of S agrees between the
 *     spaces, its diagonal is S_err^2, and its rows sum to 0 (S has mean 1 by construction).
 * The fidelity of the map itself is test_krige's and test_fidelity's. */
#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/box.h"
#include "fit/krige.h"
#include "krige_int.h"
#include "krige_kernel.h"

#define F 24

static double urand(unsigned long long *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* Dense K1 and K = K1 (x) K1 applied to an image: Y = K1 X K1. */
static void dense_k1(double l, double *K1)
{
    for (int i = 0; i < F; i++)
        for (int j = 0; j < F; j++) K1[i * F + j] = exp(-abs(i - j) / (F * l));
}

static void dense_cov(const double *K1, const double *X, double *Y)
{
    double T[F * F];
    for (int i = 0; i < F; i++)
        for (int j = 0; j < F; j++) {
            double s = 0;
            for (int k = 0; k < F; k++) s += K1[i * F + k] * X[k * F + j];
            T[i * F + j] = s;
        }
    for (int i = 0; i < F; i++)
        for (int j = 0; j < F; j++) {
            double s = 0;
            for (int k = 0; k < F; k++) s += T[i * F + k] * K1[k * F + j];
            Y[i * F + j] = s;
        }
}

static double dot(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++) s += a[i] * b[i];
    return s;
}

static void kernel_at(double l)
{
    static kr_kernel_t k, kp, km;
    double K1[F * F], a[F * F], b[F * F], Ka[F * F], Wa[F * F], Wb[F * F], Wd[F * F],
        scr[3 * F * F], X[F * F], Y[F * F], Z[F * F];
    unsigned long long seed = 7;
    kr_kernel_set(&k, F, l);
    dense_k1(l, K1);
    for (int i = 0; i < F * F; i++) a[i] = urand(&seed) - 0.3, b[i] = urand(&seed);
    /* <L^T a L, L^T b L> = a^T K b */
    kr_kernel_factor(&k, a, Wa, NULL, scr);
    kr_kernel_factor(&k, b, Wb, NULL, scr);
    dense_cov(K1, b, Ka);
    double want = dot(a, Ka, F * F), got = dot(Wa, Wb, F * F);
    CHECK(fabs(got - want) <= 1e-11 * fabs(want));
    /* K^-1 (K X) = X */
    dense_cov(K1, a, Y);
    kr_kernel_prec(&k, Y, X, 0);
    double worst = 0;
    for (int i = 0; i < F * F; i++) worst = fmax(worst, fabs(X[i] - a[i]));
    CHECK(worst < 1e-9);
    /* K X by the kernel = the dense product */
    kr_kernel_cov(&k, a, X, 0);
    worst = 0;
    for (int i = 0; i < F * F; i++) worst = fmax(worst, fabs(X[i] - Y[i]) / (1 + fabs(Y[i])));
    CHECK(worst < 1e-12);
    /* log |K| = 2 F log |K1| by LAPACK's Cholesky */
    double L[F * F];
    memcpy(L, K1, sizeof L);
    CHECK(LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', F, L, F) == 0);
    double ld = 0;
    for (int i = 0; i < F; i++) ld += 2 * log(L[i * F + i]);
    CHECK(fabs(k.logdet - 2 * F * ld) <= 1e-8 * fabs(k.logdet) + 1e-8);
    /* tr(K^-1 C) for a symmetric C: sum over the stencil against the dense K^-1 = K1^-1 (x) K1^-1
     * (LAPACK's inverse) */
    static double C[F * F * F * F];
    for (int i = 0; i < F * F; i++)
        for (int j = 0; j <= i; j++) C[i * F * F + j] = C[j * F * F + i] = urand(&seed) - 0.5;
    double Ki[F * F];
    memcpy(Ki, L, sizeof Ki);
    CHECK(LAPACKE_dpotri(LAPACK_ROW_MAJOR, 'L', F, Ki, F) == 0);
    for (int i = 0; i < F; i++)
        for (int j = i + 1; j < F; j++) Ki[i * F + j] = Ki[j * F + i];
    double tr = 0;
    for (int y = 0; y < F; y++)
        for (int x = 0; x < F; x++)
            for (int y2 = 0; y2 < F; y2++)
                for (int x2 = 0; x2 < F; x2++)
                    tr += Ki[y * F + y2] * Ki[x * F + x2] * C[(y * F + x) * F * F + y2 * F + x2];
    double trk = kr_kernel_prec_trace(&k, C, F * F, 0);
    CHECK(fabs(trk - tr) <= 1e-8 * (1 + fabs(tr)));
    /* every derivative in log l against central differences */
    double h = 1e-5;
    kr_kernel_set(&kp, F, l * exp(h));
    kr_kernel_set(&km, F, l * exp(-h));
    CHECK(fabs(k.dlogdet - (kp.logdet - km.logdet) / (2 * h)) <= 1e-5 * (1 + fabs(k.dlogdet)));
    double Wp[F * F], Wm[F * F];
    kr_kernel_factor(&k, a, Wa, Wd, scr);
    kr_kernel_factor(&kp, a, Wp, NULL, scr);
    kr_kernel_factor(&km, a, Wm, NULL, scr);
    worst = 0;
    for (int i = 0; i < F * F; i++) worst = fmax(worst, fabs(Wd[i] - (Wp[i] - Wm[i]) / (2 * h)));
    CHECK(worst < 1e-5);
    kr_kernel_prec(&k, a, X, 1);
    kr_kernel_prec(&kp, a, Y, 0);
    kr_kernel_prec(&km, a, Z, 0);
    worst = 0;
    for (int i = 0; i < F * F; i++)
        worst = fmax(worst, fabs(X[i] - (Y[i] - Z[i]) / (2 * h)) / (1 + fabs(X[i])));
    CHECK(worst < 1e-4);
    kr_kernel_cov(&k, a, X, 1);
    kr_kernel_cov(&kp, a, Y, 0);
    kr_kernel_cov(&km, a, Z, 0);
    worst = 0;
    for (int i = 0; i < F * F; i++)
        worst = fmax(worst, fabs(X[i] - (Y[i] - Z[i]) / (2 * h)) / (1 + fabs(X[i])));
    CHECK(worst < 1e-5);
    double td = kr_kernel_prec_trace(&k, C, F * F, 1);
    double tdn = (kr_kernel_prec_trace(&kp, C, F * F, 0) - kr_kernel_prec_trace(&km, C, F * F, 0)) / (2 * h);
    CHECK(fabs(td - tdn) <= 1e-4 * (1 + fabs(td)));
}

/* A 9 x 9 scan at 0.6 um over a 6 um pixel whose truth is a 6 x 6 pattern, by the box
 * integral, with a fixed pseudo-random noise of the noise model's size. */
#define N 81
static double xs[N], ys[N], sig[N];

static fit_scan_t make_scan(void)
{
    fit_scan_t sc = {N, xs, ys, sig, 6.0, 1.34, 100, 3.153, 5.67, 12, FIT_FULL_SCALE_DEFAULT};
    unsigned long long seed = 3;
    for (int k = 0; k < N; k++) {
        xs[k] = 3 + 0.6 * (k % 9 - 4), ys[k] = 3 + 0.6 * (k / 9 - 4);
        double s = 0;
        for (int j = 0; j < 6; j++)
            for (int i = 0; i < 6; i++) {
                fit_rect_t r = {i, i + 1.0, j, j + 1.0};
                double v, eb;
                err_t e;
                CHECK(fit_box_integral(1.34, &r, xs[k], ys[k], 1e-12, &v, &eb, &e) == 0);
                s += v * (1 + 0.1 * sin(i + 2 * j) + 0.05 * i);
            }
        sig[k] = 100 + 3000 * s + 20 * (urand(&seed) - 0.5);
    }
    return sc;
}

static void spaces_agree(void)
{
    fit_scan_t sc = make_scan();
    fit_options_t o = fit_options_default();
    o.noise = FIT_NOISE_SHOT_READ;
    fit_krige_prior_t pr = {.r = 6, .n_grids = 3, .grids = {2, 3, 5}}; /* 5: not a divisor of F */
    kr_work_t *wp, *wc;
    err_t e;
    CHECK(kr_work_new(&sc, &pr, &o, 0, &wp, &e) == 0);
    CHECK(kr_work_new(&sc, &pr, &o, 1, &wc, &e) == 0);
    static const double ths[][5] = {{-5, -7, -4, -6, -1.2}, {-9, -3, -6, -4, 0.7}, {-20, -20, -8, -3.5, 1.5}};
    for (int smooth = 0; smooth <= 1; smooth++) {
        kr_prob_t *kp = kr_work_model(wp, smooth), *kc = kr_work_model(wc, smooth);
        CHECK(!kp->cells && kc->cells);
        int np = kr_theta_count(kp);
        CHECK(np == 3 + 2 * smooth);
        for (size_t t = 0; t < sizeof ths / sizeof ths[0]; t++) {
            double th[5], gp[5], gc[5], Ap[25], Ac[25];
            memcpy(th, ths[t], sizeof th);
            double fp = kr_value(kp, th), fc = kr_value(kc, th);
            CHECK(isfinite(fp) && fabs(fp - fc) <= 1e-9 * fabs(fp));
            CHECK(kr_derivs(kp, th, gp, Ap) == 0 && kr_derivs(kc, th, gc, Ac) == 0);
            double gscale = 0;
            for (int i = 0; i < np; i++) gscale = fmax(gscale, fabs(gp[i]));
            for (int i = 0; i < np; i++) {
                CHECK(fabs(gp[i] - gc[i]) <= 1e-7 * (1 + gscale));
                for (int j = 0; j < np; j++)
                    CHECK(fabs(Ap[i * np + j] - Ac[i * np + j]) <= 1e-7 * (1 + fabs(Ap[i * np + i])));
            }
            /* the posterior maps */
            double Sp[F * F], Ep[F * F], Sc[F * F], Ec[F * F], worst = 0;
            CHECK(kr_posterior(kp, th, kr_work_spread(wp), Sp, Ep) == 0);
            CHECK(kr_posterior(kc, th, kr_work_spread(wc), Sc, Ec) == 0);
            for (int i = 0; i < F * F; i++)
                worst = fmax(worst, fmax(fabs(Sp[i] - Sc[i]), fabs(Ep[i] - Ec[i])) / Ep[i]);
            CHECK(worst < 1e-6);
            /* the whole covariance of S (kr_posterior_cov): its diagonal is S_err^2, the two
             * spaces give the same matrix, it is symmetric, and its rows sum to 0 (S has mean 1
             * whatever the data, so sum S has no variance) */
            static double Cp[F * F * F * F], Cc[F * F * F * F];
            double S2[F * F], cworst = 0, dworst = 0, rworst = 0, sworst = 0;
            CHECK(kr_posterior_cov(kp, th, kr_work_spread(wp), S2, Cp) == 0);
            CHECK(kr_posterior_cov(kc, th, kr_work_spread(wc), Sc, Cc) == 0);
            for (int i = 0; i < F * F; i++) {
                double rs = 0;
                sworst = fmax(sworst, fabs(S2[i] - Sp[i]));
                dworst = fmax(dworst, fabs(Cp[i * F * F + i] - Ep[i] * Ep[i]) / (Ep[i] * Ep[i]));
                for (int j = 0; j < F * F; j++) {
                    double scale = Ep[i] * Ep[j];
                    cworst = fmax(cworst, fabs(Cp[i * F * F + j] - Cc[i * F * F + j]) / scale);
                    cworst = fmax(cworst, fabs(Cp[i * F * F + j] - Cp[j * F * F + i]) / scale);
                    rs += Cp[i * F * F + j];
                }
                rworst = fmax(rworst, fabs(rs) / (Ep[i] * Ep[i]));
            }
            CHECK(sworst < 1e-12 && dworst < 1e-7 && cworst < 1e-6 && rworst < 1e-6);
            /* the gradient against central differences of -log L */
            for (int i = 0; i < np; i++) {
                double h = 1e-5, tp[5], tm[5];
                memcpy(tp, th, sizeof tp), memcpy(tm, th, sizeof tm);
                tp[i] += h, tm[i] -= h;
                double d = (kr_value(kp, tp) - kr_value(kp, tm)) / (2 * h);
                CHECK(fabs(d - gp[i]) <= 1e-4 * (1 + fabs(gp[i])));
            }
        }
    }
    kr_work_free(wp);
    kr_work_free(wc);
}

int main(void)
{
    kernel_at(0.05);
    kernel_at(0.7);
    kernel_at(4.0);
    spaces_agree();
    CHECK_DONE();
}
