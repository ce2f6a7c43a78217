/* ptc.h: photon transfer (EMVA 1288, Release 3.1 / 4.0 Linear) from pairs of flat and dark frames:
 * the system gain K (DN/e-), the temporal dark noise, the saturation point and the linearity
 * error of a sensor. Pure numerics (GSL regressions), no I/O.
 *
 * The camera model (EMVA 1288 section 2, eqs. 8 and 9 of Release 3.1): a pixel's temporal variance
 * is  sigma_y^2 = K^2 sigma_d^2 + sigma_q^2 + K (mu_y - mu_y.dark)  with sigma_q^2 = 1/12 DN^2 the
 * quantisation noise of an ideal ADC. So the photon-transfer plot (sigma_y^2 - sigma_y.dark^2
 * against mu_y - mu_y.dark) is a line through the origin of slope K, and the dark variance gives
 * the read noise sigma_d = sqrt(sigma_y.dark^2 - 1/12) / K electrons.
 *
 * Per exposure level the caller measures one pair of flats (A, B) and one pair of darks with
 * fit_ptc_pair; fit_ptc_analyse takes the table of levels (ascending exposure). */
#ifndef IPSD_FIT_PTC_H
#define IPSD_FIT_PTC_H

#include <stddef.h>
#include <stdint.h>

/* One exposure level: means (DN) and temporal variances (DN^2) of the flat pair and dark pair. */
typedef struct fit_ptc_level {
    double exposure_us;
    double mu_y, s2_y;       /* flats */
    double mu_dark, s2_dark; /* darks at the same exposure */
} fit_ptc_level_t;

/* The mean and temporal variance of a pair of frames of n pixels (EMVA 1288 R3.1 section 6.1):
 * mean = (sum A + sum B) / 2n; variance = sum ((A - B) - (mean A - mean B))^2 / 2n, i.e. half the
 * variance of the difference image, which cancels the fixed pattern (each pixel's own offset and
 * sensitivity) and leaves the temporal noise of one frame. Returns 0, or -EINVAL (n < 2). */
int fit_ptc_pair(const uint16_t *a, const uint16_t *b, size_t n, double *mean, double *s2);

typedef struct fit_ptc_result {
    double K;                   /* system gain, DN/e- (slope of the photon-transfer fit) */
    double K_err;               /* its standard error from the fit's residuals */
    double gain_e_per_dn;       /* 1 / K, the form ipsd's sensors store */
    double dark_dn;             /* mu_y.dark: mean dark level (bias), DN */
    double s2_dark;             /* sigma_y.dark^2 (DN^2): the dark variance at zero exposure */
    double read_noise_e;        /* sigma_d = sqrt(sigma_y.dark^2 - 1/12) / K; 0 when below 1/12 */
    double read_noise_dn;       /* sqrt(sigma_y.dark^2 - 1/12) */
    size_t sat_index;           /* level where the variance peaks (EMVA saturation point) */
    double saturation_dn;       /* mu_y - mu_y.dark there (DN above the dark level) */
    size_t fit_lo, fit_hi;      /* levels of the gain fit, inclusive (dark level .. 70 % of sat) */
    double linearity_error_pct; /* max |relative deviation| from the linear fit, 5-95 % of sat */
    double le_min_pct, le_max_pct; /* smallest and largest relative deviation there (%) */
    double lin_slope, lin_offset;  /* mu_y - mu_y.dark = slope * exposure + offset (DN, us) */
    size_t lin_lo, lin_hi;         /* levels of the linearity fit, inclusive */
} fit_ptc_result_t;

/* Analyses n levels (ascending exposure; at least 3 with signal below saturation). Returns 0,
 * or -EINVAL (too few usable levels, non-finite values, or no photon-transfer slope: K <= 0,
 * e.g. noise-free frames), -EDOM when a regression fails, -ENOMEM. Levels: at most 4096. */
int fit_ptc_analyse(const fit_ptc_level_t *lv, size_t n, fit_ptc_result_t *out);

#endif
