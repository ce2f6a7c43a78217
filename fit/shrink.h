/* shrink.h: the shrunk map: the recommended r's map with its detail over the next coarser fit
 * shrunk where the data cannot tell it from noise. The two fits share the data, so their
 * difference D = S_r - P S_{r-1} (P: the coarser map averaged over each finer sub-pixel's area)
 * is the detail the finer grid adds plus noise whose covariance V is known exactly from the two
 * fits' joint covariance (fit_map_joint_cov): V = C_rr + P C_qq P^T - C_rq P^T - P C_rq^T, times
 * the data's scatter^2 (recommend.h's noise_scale). In V's eigenvectors u_k (variances lambda_k)
 * the detail's coordinates z_k = u_k^T D are modelled as signal of one variance tau^2 plus noise,
 * z_k ~ N(0, tau^2 + lambda_k); tau^2 is the maximum of that marginal likelihood (empirical Bayes,
 * a ridge toward the coarser map whose strength the data choose), and each coordinate keeps the
 * fraction tau^2 / (tau^2 + lambda_k) (its posterior mean): the noise-dominated patterns (the
 * checkerboards of the spot's near-null space, lambda_k large) go, detail well above the noise
 * stays. With V = sigma^2 I this is the positive-part James-Stein factor
 * max(0, 1 - d sigma^2 / |D|^2). Chosen by measuring against the simulator's truth
 * (bench/fidelity.c, docs/numerics.md "The shrunk map"): over 1176 cases within 1.1x of the best
 * r in hindsight in 1174 (worst 1.15x) against the recommended map's 1162 (1.32x) and the scalar
 * James-Stein factor's 1169 (1.18x), closer to the truth than the recommended map in 817 and
 * farther in 9 (by at most 1e-4); on 1176 fresh cases (seeds 43-63) 1166 against 1140. An
 * addition beside the recommended map (the paper's map, which a calibration stores when asked;
 * the kriged map by default), not instead of it. Pure, thread-safe. */
#ifndef IPSD_FIT_SHRINK_H
#define IPSD_FIT_SHRINK_H

#include "base/err.h"
#include "fit/model.h"

typedef struct fit_shrunk {
    int r;          /* grid of the map (the finer fit's r); 0: no shrunk map */
    int toward_r;   /* the coarser fit it was pulled toward */
    double factor;  /* the fraction of the detail kept: |shrunk detail| / |D|, 0..1 */
    double detail;  /* rms of D over the sub-pixels: what the finer grid adds */
    double noise;   /* rms noise of D (sqrt(trace V / d), scaled to the data's scatter) */
    double tau;     /* the detail's signal rms per pattern, tau (0: none found above noise) */
    double *S;      /* r*r, row-major y then x, mean 1, as fit_result_t */
    double *S_err;  /* r*r: its noise (tau held fixed, from the joint covariance) and the
                       shrinkage's expected squared bias, (1 - g_k)^2 tau^2 per pattern: the
                       posterior's variance (the noise model's units, as fit_result_t.S_err) */
    double *S_res;  /* r*r: the resolution error of the r grid's sub-pixel values, the part of
                       their error against the truth's sub-pixel means that comes from structure
                       finer than the grid (the fit's piecewise-constant model leaks it through
                       the spot), which S_err does not count: FIT_RES_FRACTION of the detail the
                       shrinkage keeps, |(G D)_j| (its posterior mean), in S units. Add it in
                       quadrature to S_err (the data's scatter's units) for the recommended map
                       of the same r and for this map alike. */
} fit_shrunk_t;

/* The resolution error as a fraction of the kept detail: the structure below the r grid taken as
 * 0.4 of the amplitude of what the r grid resolves beyond r - 1. Chosen by measuring S_err's
 * honesty against the simulator's truth (bench/fidelity.c, docs/numerics.md "The resolution
 * error"): z = (S - truth's sub-pixel mean) / error over the sub-pixels of the recommended map,
 * seeds 1-11 (19,534 sub-pixels): S_err alone rms z 1.40, 87.7 % within 2 sigma; with S_res at
 * 0.4 / 0.5 / 0.6: 1.00 / 0.95 / 0.91 and 95.6 / 96.7 / 97.3 % (a Gaussian: 1, 95.4 %). 0.4,
 * the closest, on held-out seeds 22-42 (37,374): 1.41 / 87.5 % -> 1.01 / 95.4 %. */
#define FIT_RES_FRACTION 0.4

/* The weights of a coarse q-grid's cells in each cell of a finer r-grid along one axis: w[a*q+b]
 * is the fraction of fine cell a covered by coarse cell b (each row sums to 1). */
void fit_grid_overlap(int r, int q, double *w);

/* out (r x r) = the q x q map v averaged over each cell of an r x r grid of the same square (any
 * r, q >= 1; row-major y then x): W v W^T with W from fit_grid_overlap. 0 or -ENOMEM. */
int fit_grid_average(const double *v, int q, int r, double *out);

/* The shrinkage itself: maps Sr (r*r) and Sq (q*q, q < r), their covariances Crr, Cqq and
 * Crq = Cov(Sr, Sq) (row-major, the noise model's units), noise_scale the data's scatter
 * (multiplies the noise's sigma). 0, or -EINVAL (q >= r, q < 1) / -ENOMEM / -EDOM (the
 * eigen-decomposition failed) with err. */
int fit_shrink_with_cov(const double *Sr, int r, const double *Sq, int q, const double *Crr,
                        const double *Cqq, const double *Crq, double noise_scale,
                        fit_shrunk_t *out, err_t *err);

/* Largest r with a shrunk map: the eigen-decomposition and the products of r^2 x r^2 matrices
 * cost O(r^6) (r = 20: 400 x 400, tens of ms; r = 32 would take seconds). */
#define FIT_SHRINK_R_MAX 20 /* (docs/numerics.md "The shrunk map") */

/* The shrunk map of a sweep of scan (fitted with opts): its recommended r toward r - 1, with
 * their joint covariance. 0 with out->r = 0 when there is none (no recommended r, r = 1, r - 1
 * not in the sweep or without a map, r > FIT_SHRINK_R_MAX); else as fit_shrink_with_cov and
 * fit_map_joint_cov. */
int fit_shrink_recommended(const fit_scan_t *scan, const fit_options_t *opts,
                           const fit_sweep_t *sw, double noise_scale, fit_shrunk_t *out,
                           err_t *err);

void fit_shrunk_free(fit_shrunk_t *s);

#endif
