/* recommend.h: the recommended r of a sweep: the r whose map is expected to come closest to the
 * pixel's true sensitivity. AIC and BIC (kept exactly as the paper defines them) measure how well
 * each r predicts the data; they do not see that the finest maps' checkerboards lie in the
 * spot's near-null space, so they pick the largest r the points allow and store noise. The rule
 * here was chosen by measuring every candidate against the simulator's truth over scene families,
 * rasters, photon levels and seeds (bench/fidelity.c; the tables are in docs/studies/maps.md):
 *   1. admissible maps: a map exists with no status flag that makes it untrustworthy
 *      (underdetermined, no_signal, ill_conditioned, unconstrained), and its own noise, the rms of
 *      S_err over the sub-pixels scaled to the data's scatter (see noise_scale in recommend.c), is
 *      at most noise_to_contrast times its contrast, the standard deviation of S over the
 *      sub-pixels (the r = 1 map, with neither, is always admissible);
 *   2. of those, r_cv, the one with the smallest leave-one-out prediction chi2
 *      (fit_result_t.cv_chi2): the map that best predicts spot positions it was not fitted to;
 *      then the one-standard-error rule (Hastie, Tibshirani and Friedman, The Elements of
 *      Statistical Learning, 7.10): r_se, the smallest admissible r whose leave-one-out chi2 is
 *      within one standard error (fit_loo_se) of r_cv's, provided its reduced chi2 is at most
 *      coarse_misfit times the data's scatter (the guard of step 3: a coarser map that misfits
 *      the points has an error the data can see) or r divides r_cv (one_se_nested: r's grid is
 *      one of r_cv's, and the scatter, read from the finest fits, is biased low against it: a
 *      dead third at the procedure's raster, seed 37, r = 3 exact at reduced chi2 1.107 against
 *      r = 6's 0.717, leave-one-out chi2 0.19 apart with a standard error of 15.5); r_cv when
 *      there is none. The leave-one-out
 *      curve is flat within its noise between a map that already represents the pixel and the
 *      finer ones that only fit noise (a dead corner at 9 x 9, seed 13: r = 3 exact, rms 0.001,
 *      and r = 6, 0.005, leave-one-out chi2/N 0.956 and 0.918 +- 0.175);
 *   3. then r_se (below, r_cv names the map step 2 ended with) against its neighbours r_cv - 1
 *      and r_cv + 1, by the map's expected error
 *      against the truth (fit_map_expected_error): noise_weight x its noise^2 plus its
 *      resolution error^2, the truth's variation inside a sub-pixel that a piecewise-constant map
 *      cannot show, estimated from the differences of neighbouring sub-pixels. The data cannot
 *      see that error (the spot averages over it), so the prediction chi2 alone stops one r
 *      short on smooth pixels. A neighbour competes only when it is admissible and the data do
 *      not speak against it: r_cv + 1 only if it fits the points at least as well as r_cv (a
 *      finer grid that fits worse is misaligned with structure r_cv resolves exactly, e.g. a
 *      dead third of the pixel), r_cv - 1 (>= 2) only if its reduced chi2 is at most
 *      coarse_misfit times the data's own scatter (noise_scale^2), or at most coarse_near times
 *      r_cv's own reduced chi2: a coarser map that misfits the points has an error the
 *      resolution estimate does not see, unless r_cv misfits them about as much (then the
 *      misfit says nothing about which of the two is closer to the truth);
 *   4. when step 3 keeps r_cv but r_cv misfits the points, its reduced chi2 above escape_misfit
 *      times both r_cv + 1's and their scatter, while r_cv + 1 fits them better, has noise at
 *      most escape_noise_to_contrast of its contrast and an expected error at most
 *      escape_error_ratio times r_cv's, r_cv + 1: a map that does not describe the data is
 *      biased by more than the next one's extra noise (narrow structure, such as the paper's
 *      edge dips, that the resolution estimate underrates); the error ratio keeps the
 *      checkerboard out (a noise-dominated r_cv + 1 that fits the points).
 * The settings (fit_recommend_opts_default) were chosen on seeds 1-3 of bench/fidelity.c and
 * checked on held-out seeds; the tables, and the candidate rules measured against this one and
 * rejected (bench/recommend_replay.py), are in docs/studies/maps.md and docs/numerics.md, "The
 * recommended r".
 * Pure, thread-safe. */
#ifndef IPSD_FIT_RECOMMEND_H
#define IPSD_FIT_RECOMMEND_H

#include "fit/model.h"

typedef struct fit_recommend_opts {
    double noise_to_contrast; /* admissible when the map's noise <= this x its contrast (0.25) */
    double noise_weight;      /* weight of noise^2 in the expected error of step 3 (2); <= 0:
                                 no step 3 (the r_cv of step 2 is the recommendation) */
    double coarse_misfit;     /* r_cv - 1 competes when chi2_red <= this x scatter^2 (1.5) */
    double escape_misfit;     /* step 4 when r_cv's chi2_red > this x the larger of r_cv + 1's
                                 chi2_red and scatter^2 (1.7); <= 0: no step 4 */
    double escape_noise_to_contrast; /* r_cv + 1's admissibility in step 4 (0.5) */
    double escape_error_ratio; /* step 4 only when r_cv + 1's expected error (fit_map_expected_
                                  error) <= this x r_cv's (2); <= 0: no step 4 */
    double coarse_near;        /* r_cv - 1 also competes when its chi2_red <= this x r_cv's own
                                  (1.15): it misfits hardly more than r_cv does; <= 0: never */
    double one_se;             /* step 2's one-standard-error rule: the leave-one-out chi2 may
                                  exceed r_cv's by this many standard errors (1); <= 0: off */
    int one_se_nested;         /* step 2's misfit guard waived for an r dividing r_cv (its grid
                                  is one of r_cv's: the same map with fewer parameters) (1) */
} fit_recommend_opts_t;

fit_recommend_opts_t fit_recommend_opts_default(void);

typedef struct fit_recommendation {
    int r;            /* recommended r, 0 when no fit of the sweep has an admissible map */
    int range_edge;   /* AIC or BIC picked r_max or the largest r the points determine */
    char reason[320]; /* one sentence for people */
    /* how the rule got there, for the evidence harness (bench/fidelity.c --explain): */
    int r_cv;           /* step 2's smallest leave-one-out chi2 (0: none) */
    int r_se;           /* step 2's one-standard-error pick, where steps 3 and 4 start */
    int step;           /* the step that decided: 2 (r_se kept), 3 (a neighbour's smaller
                           expected error), 4 (the misfit escape to r_se + 1); 0: no pick */
    int vetoed;         /* r_cv - 1 when step 3 left it out as misfitting the points, else 0 */
    double noise_scale; /* the data's scatter relative to the noise model's sigma */
} fit_recommendation_t;

/* Applies the rule to a finished sweep (opts NULL: the defaults). */
void fit_recommend(const fit_sweep_t *sw, const fit_recommend_opts_t *opts,
                   fit_recommendation_t *out);

/* The standard error of the fit's leave-one-out chi2 (cv_chi2), a sum of one term per point:
 * sqrt(n) times the terms' standard deviation. A term is e_k^2 / (1 - h_kk)^2 (e the normalised
 * residual, resid); the leverages h_kk are replaced by the common factor that makes the terms sum
 * to cv_chi2 (as generalised cross-validation replaces them by their mean). NaN without
 * residuals (f->resid NULL) or chi2. */
double fit_loo_se(const fit_result_t *f);

/* The map's own noise (rms of S_err) and contrast (standard deviation of S) over its sub-pixels;
 * NaN without a map. */
void fit_map_noise_contrast(const fit_result_t *f, double *noise, double *contrast);

/* The expected rms error of the map against the truth, relative to its mean, as step 3 weighs it:
 * sqrt(noise_weight x noise^2 + resolution^2), with noise the rms of S_err times noise_scale and
 * resolution^2 = (mean dx^2 + mean dy^2 - 4 noise^2) / 12 (>= 0), dx and dy the differences of
 * horizontally and vertically neighbouring sub-pixels: a truth that changes linearly by d across
 * a sub-pixel varies inside it with variance d^2 / 12, and each difference carries twice the
 * noise variance. *noise and *resolution (either may be NULL) receive the two parts. NaN without
 * a map or for r = 1 (no neighbours to compare). */
double fit_map_expected_error(const fit_result_t *f, double noise_scale, double noise_weight,
                              double *noise, double *resolution);

#endif
