/* shrink.h: the shrunk map: the recommended r's map pulled toward the next coarser fit's map by
 * the positive-part James-Stein factor. The two fits share the data, so their difference
 * D = S_r - P S_{r-1} (P: the coarser map averaged over each finer sub-pixel's area) is the
 * detail the finer grid adds plus its noise; when that detail is not clearly above the noise, the
 * estimate S_{r-1} + c D with c = max(0, 1 - (d - 2) sigma^2 / |D|^2) (d = r^2 sub-pixels, sigma^2
 * the mean S_err^2 scaled to the data's scatter) has a smaller expected squared error than S_r
 * itself (James and Stein 1961; the positive part, Baranchik 1964). Chosen by measuring against
 * the simulator's truth (bench/fidelity.c, docs/numerics.md "The shrunk map"): over 1176 cases it
 * is closer to the truth than the recommended r's own map in 833, farther in 10 (by at most
 * 0.007), and within 1.1x of the best r in hindsight in 1169 (worst 1.18x) against the rule's
 * 1162 (1.32x). An addition beside the recommended map (the calibration a fit stores), not
 * instead of it.
 * Pure, thread-safe. */
#ifndef IPSD_FIT_SHRINK_H
#define IPSD_FIT_SHRINK_H

#include "base/err.h"
#include "fit/model.h"

typedef struct fit_shrunk {
    int r;          /* grid of the map (the finer fit's r); 0: no shrunk map */
    int toward_r;   /* the coarser fit it was pulled toward */
    double factor;  /* c in [0, 1]: 1 keeps the r map, 0 is the coarser map on the r grid */
    double detail;  /* rms of D over the sub-pixels: what the finer grid adds */
    double noise;   /* rms noise of the finer map (S_err scaled to the data's scatter) */
    double *S;      /* r*r, row-major y then x, as fit_result_t */
    double *S_err;  /* r*r: c S_err_r + (1 - c) P S_err_{r-1}: a bound on the noise of
                       c S_r + (1 - c) P S_{r-1} (the two are correlated by at most 1); the bias
                       the shrinkage trades for it is not included */
} fit_shrunk_t;

/* Shrinks fine's map toward coarse's (coarse->r < fine->r, both with maps); noise_scale
 * multiplies the S_err (recommend.h's data scatter, 1 to trust the noise model). 0, or -EINVAL
 * (no map, r not coarser, r = 1) / -ENOMEM with err. */
int fit_shrink(const fit_result_t *fine, const fit_result_t *coarse, double noise_scale,
               fit_shrunk_t *out, err_t *err);

/* The weights of a coarse q-grid's cells in each cell of a finer r-grid along one axis: w[a*q+b]
 * is the fraction of fine cell a covered by coarse cell b (each row sums to 1). */
void fit_grid_overlap(int r, int q, double *w);

/* The shrunk map of a sweep: its recommended r toward r - 1 (recommend.h's data scatter as the
 * noise scale). 0 with out->r = 0 when there is none (no recommended r, r = 1, r - 1 not in the
 * sweep or without a map); -ENOMEM with err. */
int fit_shrink_recommended(const fit_sweep_t *sw, double noise_scale, fit_shrunk_t *out,
                           err_t *err);

void fit_shrunk_free(fit_shrunk_t *s);

#endif
