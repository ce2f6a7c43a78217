/* ptc.c: photon transfer per EMVA 1288 (ptc.h): pair statistics, the gain fit, the dark noise,
 * the saturation point and the linearity error. The regressions are GSL's (gsl_fit_mul for the
 * fit through the origin that the standard asks for, gsl_fit_linear, gsl_fit_wlinear). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include <gsl/gsl_fit.h>

#include "fit/gslerr.h"
#include "fit/ptc.h"

/* sigma_q^2 of an ideal uniform quantiser with a step of 1 DN (EMVA 1288 R3.1 eq. 8) */
#define PTC_S2Q (1.0 / 12.0)
/* the gain fit runs up to 70 % of the saturation signal, the linearity fit over 5-95 %
 * (EMVA 1288 R3.1 sections 6.3 and 6.6) */
#define PTC_FIT_TOP 0.70
#define PTC_LIN_LO 0.05
#define PTC_LIN_HI 0.95
#define PTC_MAX_LEVELS 4096

int fit_ptc_pair(const uint16_t *a, const uint16_t *b, size_t n, double *mean, double *s2)
{
    if (n < 2) return -EINVAL;
    /* sums of integers are exact in double up to 2^53: no compensated summation needed */
    double sa = 0, sb = 0;
    for (size_t k = 0; k < n; k++) {
        sa += a[k];
        sb += b[k];
    }
    double ma = sa / (double)n, mb = sb / (double)n, dm = ma - mb, ss = 0;
    for (size_t k = 0; k < n; k++) {
        double d = ((double)a[k] - (double)b[k]) - dm;
        ss += d * d;
    }
    /* EMVA 1288 R3.1 section 6.1: mu_y = (mu_A + mu_B) / 2,
     * sigma_y^2 = 1/(2n) sum ((y_A - y_B) - (mu_A - mu_B))^2 */
    *mean = 0.5 * (ma + mb);
    *s2 = ss / (2.0 * (double)n);
    return 0;
}

static int finite_levels(const fit_ptc_level_t *lv, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(lv[i].exposure_us) || !isfinite(lv[i].mu_y) || !isfinite(lv[i].s2_y) ||
            !isfinite(lv[i].mu_dark) || !isfinite(lv[i].s2_dark))
            return 0;
    return 1;
}

static int analyse(const fit_ptc_level_t *lv, size_t n, fit_ptc_result_t *r, double *x, double *y,
                   double *w)
{
    /* saturation: the level where the temporal variance peaks (EMVA 1288 R3.1 section 6.3:
     * mu_y.sat is the mean at the maximum of the photon-transfer curve) */
    size_t is = 0;
    for (size_t i = 1; i < n; i++)
        if (lv[i].s2_y > lv[is].s2_y) is = i;
    r->sat_index = is;
    r->saturation_dn = lv[is].mu_y - lv[is].mu_dark;
    if (!(r->saturation_dn > 0)) return -EINVAL;

    /* the gain: sigma_y^2 - sigma_y.dark^2 = K (mu_y - mu_y.dark) (R3.1 eq. 9), a line through
     * the origin fitted from the dark level up to 70 % of saturation */
    size_t m = 0;
    r->fit_lo = n;
    for (size_t i = 0; i <= is; i++) {
        double sig = lv[i].mu_y - lv[i].mu_dark;
        if (sig > PTC_FIT_TOP * r->saturation_dn) continue;
        if (r->fit_lo == n) r->fit_lo = i;
        r->fit_hi = i;
        x[m] = sig;
        y[m] = lv[i].s2_y - lv[i].s2_dark;
        m++;
    }
    if (m < 2) return -EINVAL;
    double K, cov, sumsq;
    if (gsl_fit_mul(x, 1, y, 1, m, &K, &cov, &sumsq)) return -EDOM;
    if (!(K > 0) || !isfinite(K)) return -EINVAL;
    r->K = K;
    r->K_err = sqrt(cov);
    r->gain_e_per_dn = 1.0 / K;

    /* the dark level and dark variance at zero exposure: EMVA extrapolates the dark variance
     * linearly in the exposure time when there are more than two exposure times (dark current
     * grows it); otherwise the mean */
    size_t distinct = 1; /* distinct exposures (levels ascending) */
    double mu_d = 0, s2_d = 0;
    for (size_t i = 0; i < n; i++) {
        x[i] = lv[i].exposure_us;
        y[i] = lv[i].s2_dark;
        mu_d += lv[i].mu_dark;
        s2_d += lv[i].s2_dark;
        if (i > 0 && lv[i].exposure_us != lv[i - 1].exposure_us) distinct++;
    }
    r->dark_dn = mu_d / (double)n;
    r->s2_dark = s2_d / (double)n;
    if (distinct > 2) {
        double c0, c1, c00, c01, c11;
        if (gsl_fit_linear(x, 1, y, 1, n, &c0, &c1, &c00, &c01, &c11, &sumsq)) return -EDOM;
        r->s2_dark = c0;
    }
    /* sigma_d = sqrt(sigma_y.dark^2 - sigma_q^2) / K (R3.1 eq. 8 with no light) */
    double rn2 = r->s2_dark - PTC_S2Q;
    r->read_noise_dn = rn2 > 0 ? sqrt(rn2) : 0;
    r->read_noise_e = r->read_noise_dn / K;

    /* linearity (R3.1 section 6.6): mu_y - mu_y.dark against the exposure (proportional to the
     * photons at constant irradiance) over 5-95 % of saturation, fitted so that the relative
     * deviations are least squares (weights 1 / Y^2), then the relative deviation in percent */
    m = 0;
    r->lin_lo = n;
    for (size_t i = 0; i <= is; i++) {
        double sig = lv[i].mu_y - lv[i].mu_dark;
        if (sig < PTC_LIN_LO * r->saturation_dn || sig > PTC_LIN_HI * r->saturation_dn) continue;
        if (r->lin_lo == n) r->lin_lo = i;
        r->lin_hi = i;
        x[m] = lv[i].exposure_us;
        y[m] = sig;
        w[m] = 1.0 / (sig * sig);
        m++;
    }
    if (m < 3) return -EINVAL;
    double c0, c1, c00, c01, c11;
    if (gsl_fit_wlinear(x, 1, w, 1, y, 1, m, &c0, &c1, &c00, &c01, &c11, &sumsq)) return -EDOM;
    r->lin_slope = c1;
    r->lin_offset = c0;
    r->le_min_pct = INFINITY;
    r->le_max_pct = -INFINITY;
    for (size_t k = 0; k < m; k++) {
        double f = c0 + c1 * x[k];
        double dev = 100.0 * (y[k] - f) / f;
        if (dev < r->le_min_pct) r->le_min_pct = dev;
        if (dev > r->le_max_pct) r->le_max_pct = dev;
    }
    r->linearity_error_pct = fmax(fabs(r->le_min_pct), fabs(r->le_max_pct));
    return 0;
}

int fit_ptc_analyse(const fit_ptc_level_t *lv, size_t n, fit_ptc_result_t *r)
{
    if (n < 3 || n > PTC_MAX_LEVELS || !finite_levels(lv, n)) return -EINVAL;
    fit_gsl_policy();
    *r = (fit_ptc_result_t){0};
    double *buf = malloc(sizeof(double) * 3 * n);
    if (!buf) return -ENOMEM;
    int rc = analyse(lv, n, r, buf, buf + n, buf + 2 * n);
    free(buf);
    return rc;
}
