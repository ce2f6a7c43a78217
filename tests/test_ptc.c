/* test_ptc.c: fit/ptc.h against analytic cases: the pair statistics of frames built with a known
 * fixed pattern and a known temporal part, and the analysis of levels that follow the EMVA 1288
 * camera model exactly (the photon-transfer line, a variance peak at saturation, a linear
 * response), whose gain, dark noise, saturation and linearity are known by construction. */
#include <errno.h>
#include <math.h>
#include <stdint.h>

#include "check.h"
#include "fit/ptc.h"

#define NPX 1000

static void pair_cases(void)
{
    uint16_t a[NPX], b[NPX];
    double sum_p = 0;
    for (int k = 0; k < NPX; k++) {
        int p = 500 + (k * 37) % 101; /* a fixed pattern: the difference cancels it */
        int d = (k & 1) ? 1 : -1;     /* a temporal part of mean 0: A - B = 2d, variance 4 */
        a[k] = (uint16_t)(p + d);
        b[k] = (uint16_t)(p - d);
        sum_p += p;
    }
    double mu, s2;
    CHECK(fit_ptc_pair(a, b, NPX, &mu, &s2) == 0);
    CHECK_NEAR(mu, sum_p / NPX, 1e-15, 0);
    CHECK_NEAR(s2, 2.0, 1e-15, 0); /* var(A - B) / 2 = 4 / 2 */
    /* an offset between the frames (a lamp drift) does not count as temporal noise */
    for (int k = 0; k < NPX; k++)
        b[k] = (uint16_t)(b[k] + 7);
    CHECK(fit_ptc_pair(a, b, NPX, &mu, &s2) == 0);
    CHECK_NEAR(s2, 2.0, 1e-15, 0);
    /* identical frames: no temporal noise at all */
    CHECK(fit_ptc_pair(a, a, NPX, &mu, &s2) == 0);
    CHECK(s2 == 0);
    CHECK(fit_ptc_pair(a, b, 1, &mu, &s2) == -EINVAL);
}

/* levels of the EMVA model: K DN/e-, dark noise sd_e e-, bias 100 DN, a response of R DN/us up to
 * the clip at ysat DN above the dark, where the variance falls (the clipped pixels stop varying) */
static void model_cases(double K, double sd_e, double R, double ysat)
{
    fit_ptc_level_t lv[40];
    double s2d = K * K * sd_e * sd_e + 1.0 / 12; /* R3.1 eq. 8 with no light */
    size_t n = 0, peak = 0;
    for (int i = 0; i < 40; i++) {
        double t = 100.0 * i, y = R * t;
        lv[n].exposure_us = t;
        lv[n].mu_dark = 100;
        lv[n].s2_dark = s2d;
        if (y <= ysat) {
            lv[n].mu_y = 100 + y;
            lv[n].s2_y = s2d + K * y; /* R3.1 eq. 9 */
            peak = n;
        } else {
            lv[n].mu_y = 100 + ysat;
            lv[n].s2_y = s2d * 0.5; /* past saturation */
        }
        n++;
    }
    fit_ptc_result_t r;
    CHECK(fit_ptc_analyse(lv, n, &r) == 0);
    CHECK_NEAR(r.K, K, 1e-12, 0);
    CHECK_NEAR(r.gain_e_per_dn, 1 / K, 1e-12, 0);
    CHECK_NEAR(r.read_noise_e, sd_e, 1e-12, 0);
    CHECK_NEAR(r.dark_dn, 100, 1e-15, 0);
    CHECK(r.sat_index == peak);
    CHECK_NEAR(r.saturation_dn, R * 100.0 * (double)peak, 1e-12, 0);
    CHECK(r.fit_lo == 0);
    CHECK(lv[r.fit_hi].mu_y - 100 <= 0.7 * r.saturation_dn);
    CHECK(lv[r.fit_hi + 1].mu_y - 100 > 0.7 * r.saturation_dn);
    CHECK_NEAR(r.linearity_error_pct, 0, 0, 1e-9); /* an exactly linear response */
    CHECK_NEAR(r.lin_slope, R, 1e-12, 0);
    CHECK_NEAR(r.lin_offset, 0, 0, 1e-9);
}

/* a response bent by a known amount: Y = R t (1 - b t). The weighted line through the 5-95 %
 * range cannot follow it, so the linearity error is positive and of the order of the bend. */
static void nonlinear_case(void)
{
    fit_ptc_level_t lv[30];
    double K = 0.25, b = 1e-5, R = 1.0;
    for (int i = 0; i < 30; i++) {
        double t = 1000.0 * i / 29 + 1, y = R * t * (1 - b * t);
        lv[i] = (fit_ptc_level_t){t, 100 + y, 3 + K * y, 100, 3};
    }
    lv[29].s2_y = 1; /* the variance peaks at level 28 */
    fit_ptc_result_t r;
    CHECK(fit_ptc_analyse(lv, 30, &r) == 0);
    CHECK(r.sat_index == 28);
    /* the bend over the range is b t ~ 1 %: the deviation from the best line is a fraction of it */
    CHECK(r.linearity_error_pct > 0.05 && r.linearity_error_pct < 1.0);
}

static void bad_cases(void)
{
    fit_ptc_level_t lv[5];
    for (int i = 0; i < 5; i++) /* noise-free frames: no variance, no photon-transfer slope */
        lv[i] = (fit_ptc_level_t){100.0 * i, 100 + 50.0 * i, 0, 100, 0};
    fit_ptc_result_t r;
    CHECK(fit_ptc_analyse(lv, 5, &r) == -EINVAL);
    CHECK(fit_ptc_analyse(lv, 2, &r) == -EINVAL);
    lv[2].mu_y = NAN;
    CHECK(fit_ptc_analyse(lv, 5, &r) == -EINVAL);
}

int main(void)
{
    pair_cases();
    model_cases(1 / 3.153, 5.67, 2.0, 16283);
    model_cases(1 / 1.2, 2.5, 7.0, 20000);
    nonlinear_case();
    bad_cases();
    CHECK_DONE();
}
