/* recommend.h: the recommended r of a sweep: the r whose map is expected to come closest to the
 * pixel's true sensitivity. AIC and BIC (kept exactly as the paper defines them) measure how well
 * each r predicts the data; they do not see that the finest maps' checkerboards lie in the
 * spot's near-null space, so they pick the largest r the points allow and store noise. The rule
 * here was chosen by measuring every candidate against the simulator's truth over scene families,
 * rasters, photon levels and seeds (bench/fidelity.c; the table is in the README):
 *   1. admissible maps: a map exists with no status flag that makes it untrustworthy
 *      (underdetermined, no_signal, ill_conditioned, unconstrained), and its own noise, the rms of
 *      S_err over the sub-pixels scaled to the data's scatter (see noise_scale in recommend.c), is
 *      at most noise_to_contrast times its contrast, the standard deviation of S over the
 *      sub-pixels (the r = 1 map, with neither, is always admissible);
 *   2. of those, the one with the smallest leave-one-out prediction chi2 (fit_result_t.cv_chi2):
 *      the map that best predicts spot positions it was not fitted to.
 * Measured (168 cases): within 1.1x of the best map in hindsight in 153, within 1.32x in all,
 * against 120 and 14.6x for BIC, 71 and 5700x for AIC; the same under both noise models.
 * Pure, thread-safe. */
#ifndef IPSD_FIT_RECOMMEND_H
#define IPSD_FIT_RECOMMEND_H

#include "fit/model.h"

typedef struct fit_recommend_opts {
    double noise_to_contrast; /* admissible when the map's noise <= this x its contrast (0.25) */
} fit_recommend_opts_t;

fit_recommend_opts_t fit_recommend_opts_default(void);

typedef struct fit_recommendation {
    int r;            /* recommended r, 0 when no fit of the sweep has an admissible map */
    int range_edge;   /* AIC or BIC picked r_max or the largest r the points determine */
    char reason[320]; /* one sentence for people */
} fit_recommendation_t;

/* Applies the rule to a finished sweep (opts NULL: the defaults). */
void fit_recommend(const fit_sweep_t *sw, const fit_recommend_opts_t *opts,
                   fit_recommendation_t *out);

/* The map's own noise (rms of S_err) and contrast (standard deviation of S) over its sub-pixels;
 * NaN without a map. */
void fit_map_noise_contrast(const fit_result_t *f, double *noise, double *contrast);

#endif
