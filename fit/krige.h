/* krige.h: the kriged map: the pixel's sensitivity as a Gaussian process on a fine F x F grid,
 * estimated from the same points as the r x r fits, not picked among them.
 *
 * Model (docs/numerics.md "The kriged map"): the fine cells' T = I0 S carry a prior
 *     T = mu 1 + u,   u ~ N(0, K),   K = a^2 k(|x - x'|_1 / l) + sum_q tau_q^2 B_q B_q^T,
 * mu flat; k(s) = exp(-s) (the exponential kernel, Matern 1/2: continuous, rough, edges stay
 * sharp) of the L1 distance between cell centres, so K's smooth part is a product of two
 * one-dimensional kernels, exp(-|dx| / l) exp(-|dy| / l) (pixel layouts are rectilinear); B_q
 * spreads a q x q grid's cells over the fine cells (each fine cell's share of each q-cell), for
 * the prior's grids q (fit_krige_prior_t; F is a multiple of its r, so r's divisor grids lie
 * exactly on fine cells; other grids get their own design and a fractional spread). The fit job
 * takes the prior from its sweep (fit_krige_prior_for_sweep: the recommended r's divisor grids,
 * docs/numerics.md "The prior from the sweep"). The data are d = A T + e, e ~ N(0, diag
 * sigma^2), with A the fine grid's design matrix (design.h; grid q's own design for the q-cells'
 * part) and sigma the noise model's. The hyperparameters (a, l, tau_q) maximise the restricted
 * likelihood (mu integrated out; Patterson and Thompson) by Fisher scoring with the average
 * information and the analytic gradient in a trust region (krige_opt.c); the map is the
 * posterior mean, T = mu 1 + K A^T P d, with its covariance, both normalised to S = T / mean T (as
 * fit_result_t). The smooth part stays only when it raises the restricted likelihood
 * significantly, 2 (log L_1 - log L_0) >= FIT_KRIGE_LR against the prior of the grids alone
 * (or the flat map): where the truth is exactly piecewise (a dead corner on r = 3, a uniform
 * pixel) the smooth part only adds noise. Its error bars then come from the smooth model all
 * the same (S_err below).
 *
 * Cost: each model is evaluated in the points' space (one n x n factorisation a step) or in the
 * fine cells' space (the mixed-model equations: one p x p factorisation, p = 1 + F^2 + sum q^2,
 * however many points), whichever costs less (krige_int.h); 10-30 evaluations a model. On the
 * reference 81-point scan about 10 ms, 361 points about 0.08 s, 1681 points 0.15 s, the 2601
 * points of the whole 51 x 51 raster about 0.3 s (docs/numerics.md "The kriged map's speed").
 * Pure, thread-safe. */
#ifndef IPSD_FIT_KRIGE_H
#define IPSD_FIT_KRIGE_H

#include "base/err.h"
#include "fit/model.h"

/* The fine grid: the smallest multiple of r with at least this many cells a side. */
#define FIT_KRIGE_CELLS 24
/* The likelihood-ratio threshold of the smooth part: chi^2 with 2 degrees of freedom at 0.1 %
 * (docs/numerics.md "The kriged map", "The threshold"). */
#define FIT_KRIGE_LR 13.82
#define FIT_KRIGE_MAX_LEVELS 12 /* grids in the prior */

/* The prior's piecewise part: the grids q x q whose cells each carry an independent offset with
 * the grid's own variance, and the r whose multiple is the fine grid. */
typedef struct fit_krige_prior {
    int r;                           /* 1..32: F is its smallest multiple >= FIT_KRIGE_CELLS */
    int n_grids;
    int grids[FIT_KRIGE_MAX_LEVELS]; /* 2..32, distinct */
} fit_krige_prior_t;

/* The divisor grids q >= 2 of r (those F holds exactly). */
fit_krige_prior_t fit_krige_prior_divisors(int r);

typedef struct fit_kriged {
    int grid;           /* F: the map is F x F (0: none) */
    int r;              /* the r whose multiple F is */
    int smooth;         /* 1: the smooth part was kept (its likelihood ratio >= FIT_KRIGE_LR) */
    double lr;          /* 2 (log L with the smooth part - log L without), >= 0 */
    double amplitude;   /* a / I0: the smooth part's standard deviation in S units (0: none) */
    double length_um;   /* l: its correlation length (NaN: none) */
    int n_levels;
    int level_q[FIT_KRIGE_MAX_LEVELS];     /* the prior's grids q */
    double level_sd[FIT_KRIGE_MAX_LEVELS]; /* tau_q / I0, S units */
    double log_lik;     /* the restricted log-likelihood of the model kept (up to a constant) */
    int evaluations;    /* of the likelihood, both models */
    int cells;          /* 1: the smooth model was evaluated in the fine cells' space (many
                           points), 0: in the points' space */
    double *S, *S_err;  /* F*F, row-major y then x, mean 1: posterior mean and standard deviation
                           (the noise model's units, as fit_result_t.S_err); without the smooth
                           part, S_err is the root of the smooth model's posterior second moment
                           about S (its variance plus its mean's distance from S): the grids
                           alone see nothing inside their cells (krige.c) */
    double *S_cov;      /* F^2 x F^2 from fit_krige_with_cov, else NULL */
    double ms;          /* cost */
    /* the expected error under the neighbouring priors (fit_krige_mix; mix_n 0: not made) */
    int mix_n;                /* priors in the mixture: r - 1 (when >= 1), r, r + 1 */
    int mix_r[3];             /* their r */
    double mix_map_err[3];    /* the rms of each one's S_err over the pixel */
    double mix_spread[3];     /* the rms of each one's map minus this map (0 for r itself) */
    double mix_log_lik[3];    /* each one's restricted log-likelihood (comparable across them) */
    double mix_weight[3];     /* 1 / K within Occam's window, 0 outside */
    double mix_err;           /* sqrt(sum over the priors of weight (map_err^2 + spread^2)) */
} fit_kriged_t;

/* The kriged map of scan's usable points (fit_map's, with opts' noise model and design tol) with
 * prior's grids. 0 with a map; -EINVAL (r outside 1..32, a grid outside 2..32 or repeated,
 * fewer than 3 points, no signal), -ENOMEM, -EDOM (the algebra failed), -ECANCELED
 * (opts->stop) with err. */
int fit_krige_with(const fit_scan_t *scan, const fit_krige_prior_t *prior,
                   const fit_options_t *opts, fit_kriged_t *out, err_t *err);

/* fit_krige_with, and the whole posterior covariance of S in out->S_cov (F^2 x F^2, row-major;
 * its diagonal S_err^2): what an adaptive scan's planner (adapt.h) needs. Without the smooth
 * part it is the smooth model's covariance about the map kept, as S_err is. */
int fit_krige_with_cov(const fit_scan_t *scan, const fit_krige_prior_t *prior,
                       const fit_options_t *opts, fit_kriged_t *out, err_t *err);

/* The prior of the kriged map the fit job stores (fit/pipeline.h) and the fidelity harness
 * scores, chosen from sweep sw: the divisor grids of its recommended r (r = 1 without one).
 * Priors holding every grid of the sweep measured worse against the truth (krige_prior.c). */
fit_krige_prior_t fit_krige_prior_for_sweep(const fit_sweep_t *sw);

/* fit_krige_with the divisor grids of r. */
int fit_krige(const fit_scan_t *scan, int r, const fit_options_t *opts, fit_kriged_t *out,
              err_t *err);

void fit_kriged_free(fit_kriged_t *k);

/* The largest fine grid fit_map_ms_between and fit_krige_mix take (a kriged map's F is at most 46). */
#define FIT_KRIGE_MIX_GRID_MAX 96

/* Occam's window of fit_krige_mix: a prior whose restricted log-likelihood is this far below the
 * best of the three is left out (docs/numerics.md "The expected error under the neighbouring
 * priors"). */
#define FIT_KRIGE_MIX_WINDOW 20.0

/* The expected error of map (made from scan with opts and the divisor grids of map->r) under an
 * equal mixture of its prior and those of r - 1 (when >= 1) and r + 1: the maps of the neighbours
 * are made from the same points, and over the K of them within FIT_KRIGE_MIX_WINDOW of the best
 * likelihood
 *     e^2 = (1/K) sum_k [ <S_err_k^2> + <(m_k - m)^2> ]
 * (<.> the mean over the pixel, m the map kept) is its second moment about the map kept (docs/
 * numerics.md "The expected error under the neighbouring priors"). Fills map's mix_* fields; a
 * neighbour whose map cannot be had is left out. 0; -EINVAL (no map), -ENOMEM, -ECANCELED
 * (opts->stop) with err. The map itself and its S_err are unchanged. */
int fit_krige_mix(const fit_scan_t *scan, fit_kriged_t *map, const fit_options_t *opts,
                  err_t *err);

/* The mean over the pixel of (a - b)^2 for two piecewise-constant maps a (fa x fa) and b
 * (fb x fb), row-major y then x, each cell of equal area: exact, over the common refinement of
 * the two grids. NaN for a grid outside 1..FIT_KRIGE_MIX_GRID_MAX. */
double fit_map_ms_between(const double *a, int fa, const double *b, int fb);

#endif
