/* krige.h: the kriged map: the pixel's sensitivity as a Gaussian process on a fine F x F grid,
 * estimated from the same points as the r x r fits, not picked among them.
 *
 * Model (docs/numerics.md "The kriged map"): the fine cells' T = I0 S carry a prior
 *     T = mu 1 + u,   u ~ N(0, K),   K = a^2 k(|x - x'|_1 / l) + sum_q tau_q^2 B_q B_q^T,
 * mu flat; k(s) = exp(-s) (the exponential kernel, Matern 1/2: continuous, rough, edges stay
 * sharp) of the L1 distance between cell centres, so K's smooth part is a product of two
 * one-dimensional kernels, exp(-|dx| / l) exp(-|dy| / l) (pixel layouts are rectilinear, and the
 * product makes A K A^T cost N F^3 rather than N F^4); B_q spreads a q x q grid's cells over the
 * fine cells they contain, for every divisor q >= 2 of the recommended r (F is a multiple of r,
 * so those grids, and the exact piecewise maps they hold, are in the prior). The data are
 * d = A T + e, e ~ N(0, diag sigma^2), with A the fine grid's design matrix (design.h) and sigma
 * the noise model's. The hyperparameters (a, l, tau_q) maximise the restricted likelihood (mu
 * integrated out; Patterson and Thompson), by GSL's BFGS with its analytic gradient,
 *     d(-2 log L) / d theta = tr(P dV) - (P d)^T dV (P d),   V = D + A K A^T,
 *     P = V^-1 - V^-1 1_A (1_A^T V^-1 1_A)^-1 1_A^T V^-1   (1_A: the mean's column, A 1);
 * the map is the posterior mean, T = mu 1 + K A^T P d, its covariance K - K A^T P A K, both
 * normalised to S = T / mean T (as fit_result_t). The smooth part stays only when it raises
 * the restricted likelihood significantly, 2 (log L_1 - log L_0) >= FIT_KRIGE_LR against the
 * prior of the divisor grids alone (or the flat map, r = 1): where the truth is exactly
 * piecewise on the recommended grid (a dead corner on r = 3, a uniform pixel) the smooth part
 * only adds noise. Its error bars then come from the smooth model all the same (S_err below).
 *
 * Chosen by measuring against the simulator's truth (bench/fidelity.c --krige): see FIT_KRIGE_LR.
 * Cost: one N x N factorisation per likelihood evaluation, 90-330 evaluations: about 0.1 s for
 * 81 points, up to 5.4 s for 361. Pure, thread-safe. */
#ifndef IPSD_FIT_KRIGE_H
#define IPSD_FIT_KRIGE_H

#include "base/err.h"
#include "fit/model.h"

/* The fine grid: the smallest multiple of r with at least this many cells a side. */
#define FIT_KRIGE_CELLS 24
/* The likelihood-ratio threshold of the smooth part: chi^2 with 2 degrees of freedom at 0.1 %
 * (docs/numerics.md "The kriged map", "The threshold"). Both models' maps were measured on every
 * case of seeds 1-21 and 22-42 (2352): within 1.1x of the best r in hindsight at threshold 0
 * (always smooth) 2257, 6: 2348, 9.21 (1 %, the first choice): 2351, 11.3-20: 2352 (mean ratio
 * 0.489-0.505), 30: 2351. The 672 cases of exactly piecewise scenes (flat, dead corner), which
 * the smooth part only blurs, reach ratios up to 9.5 (the 9.21 miss: a dead corner, 1.49x); at
 * 13.82 their nominal false-pass rate is 0.1 %, for a mean ratio of 0.493 against 0.486. */
#define FIT_KRIGE_LR 13.82
/* Largest number of points: the restricted likelihood factors an N x N matrix per evaluation. */
#define FIT_KRIGE_MAX_POINTS 1200
#define FIT_KRIGE_MAX_LEVELS 8 /* divisors q >= 2 of r <= 32: at most 5 (24: 2 3 4 6 8 12 24) */

typedef struct fit_kriged {
    int grid;           /* F: the map is F x F (0: none) */
    int r;              /* the recommended r whose divisor grids are in the prior */
    int smooth;         /* 1: the smooth part was kept (its likelihood ratio >= FIT_KRIGE_LR) */
    double lr;          /* 2 (log L with the smooth part - log L without), >= 0 */
    double amplitude;   /* a / I0: the smooth part's standard deviation in S units (0: none) */
    double length_um;   /* l: its correlation length (NaN: none) */
    int n_levels;
    int level_q[FIT_KRIGE_MAX_LEVELS];     /* the divisor grids q */
    double level_sd[FIT_KRIGE_MAX_LEVELS]; /* tau_q / I0, S units */
    double log_lik;     /* the restricted log-likelihood of the model kept (up to a constant) */
    int evaluations;    /* of the likelihood, both models */
    double *S, *S_err;  /* F*F, row-major y then x, mean 1: posterior mean and standard deviation
                           (the noise model's units, as fit_result_t.S_err); without the smooth
                           part, S_err is the root of the smooth model's posterior second moment
                           about S (its variance plus its mean's distance from S): the divisor
                           grids alone see nothing inside their cells (krige.c) */
    double ms;          /* cost */
} fit_kriged_t;

/* The kriged map of scan's usable points (fit_map's, with opts' noise model and design tol) with
 * the divisor grids of r in its prior. 0 with a map; -EINVAL (r outside 1..32, fewer than 3
 * points, more than FIT_KRIGE_MAX_POINTS, no signal), -ENOMEM, -EDOM (the algebra failed),
 * -ECANCELED (opts->stop) with err. */
int fit_krige(const fit_scan_t *scan, int r, const fit_options_t *opts, fit_kriged_t *out,
              err_t *err);

void fit_kriged_free(fit_kriged_t *k);

#endif
