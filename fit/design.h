/* design.h: the design matrix of eq. 3, A[k][j*r+i] = integral of the unit-peak Airy centred at
 * spot position k over sub-pixel (i, j) (column i, row j) of an r x r split of the pixel
 * [0, pitch]^2. The model is then M_k = I0 * sum_ij S_ij A[k][j*r+i].
 *
 * Fast path: every corner wedge (corner.h) of a sub-pixel edge line is a prefix integral of one
 * integrand that depends only on the line's distance from the spot, so one cumulative sweep per
 * distinct distance serves all its nodes, over all spots of a batch. A sweep is spectral: each
 * segment samples the integrand at `order` Chebyshev points of the first kind and integrates the
 * interpolating Chebyshev series in closed form (Clenshaw-Curtis style), so a wedge costs one
 * Clenshaw sum; cost grows like r^2 per spot, not r^4 (design.c, docs/numerics.md).
 * Leave-out: sub-pixels whose rigorous bound (sub-pixel area times the Airy envelope at its
 * nearest point, airy.h) is below skip_tol of the spot's whole flux are not integrated; they are
 * set to 0 and counted, with the largest bound left out. Thread-safe; no I/O. */
#ifndef IPSD_FIT_DESIGN_H
#define IPSD_FIT_DESIGN_H

#include <stddef.h>

#include "base/err.h"
#include "fit/stop.h"

/* Sweeps kept across calls (wedge_sweep.c): a sweep depends only on the line's scaled distance
 * w = a |e - x| and the options, so fits that share spot positions and edge lines (every r of a
 * sweep over r has the lines 0 and pitch, r = 4 has r = 2's, the F-test refits an r of the sweep,
 * a square raster has the same offsets across as along) build each distinct w once. Results are
 * the same with or without a cache (segments never depend on which targets asked for them). Not
 * thread-safe: one cache per thread of work; it serves the options of its first call, and the
 * sweeps' shape (wedge_sweep.c: short segments near the foot when any spot is outside the
 * pixel), and is bypassed by calls with others; it stops growing at 64 MB. */
typedef struct fit_design_cache fit_design_cache_t;

typedef struct fit_design_cache_stats {
    size_t sweeps, bytes;  /* sweeps held and their memory */
    size_t hits, misses;   /* look-ups that found a sweep / that started one */
} fit_design_cache_stats_t;

fit_design_cache_t *fit_design_cache_new(void); /* NULL when out of memory */
void fit_design_cache_free(fit_design_cache_t *c);
fit_design_cache_stats_t fit_design_cache_stats(const fit_design_cache_t *c);

typedef struct fit_design_opts {
    int order;       /* Chebyshev points per sweep segment (the accuracy setting), 2..64 */
    double seg_dv;   /* largest span of a*rho covered by one segment (resolves oscillations) */
    double seg_ds;   /* largest span of the wedge variable s = asinh(tan t) per segment */
    double skip_tol; /* leave out entries bounded below skip_tol * 4 pi / a^2; 0 keeps all */
    fit_design_cache_t *cache; /* sweeps shared with other calls (NULL: none) */
    fit_stop_t stop; /* polled before each batch of rows: -ECANCELED (stop.h); zero: never */
} fit_design_opts_t;

typedef struct fit_design_stats {
    size_t entries;            /* n * r * r */
    size_t skipped;            /* entries left out by the envelope bound */
    double max_skipped_bound;  /* largest bound of an entry left out (um^2), 0 if none */
    size_t radial_evals;       /* evaluations of the radial function the matrix's sweeps take:
                                  the cost without a cache (a cache may have held them; the
                                  count does not depend on what it held) */
} fit_design_stats_t;

/* Options for a target accuracy: tol is the largest error of an entry relative to the largest
 * entry of its row (as `ips bench` measures it); skip_tol = tol / 100. */
fit_design_opts_t fit_design_opts_for_tol(double tol);

/* Fills A (n x r*r, row-major, caller-allocated) for spots (x[k], y[k]). R_um > 0, pitch > 0,
 * r >= 1. stats may be NULL. Returns 0 or -EINVAL / -ENOMEM with a message in err. */
int fit_design_build(double R_um, double pitch, int r, const double *x, const double *y, size_t n,
                     const fit_design_opts_t *opts, double *A, fit_design_stats_t *stats,
                     err_t *err);

/* An upper estimate of the radial evaluations fit_design_build takes for these spots when no two
 * of them share a sweep (the case of scattered positions: a jitter series), without building
 * anything: per spot and line, the segments of a fresh sweep to the line's farthest node, each
 * of which advances E by e^seg_ds or a*rho by seg_dv (at most ln(E/E0)/seg_ds + dv/seg_dv + 1),
 * from the spot's foot on the line (E0 = 1) or, for a spot beyond the pixel's edge (every node
 * on one side), from the nearest node (design.c's sweeps never take more), times the order. It
 * grows with a x the pixel's size: a 0.012 um spot crosses ~2000 Airy rings along a 6 um edge
 * line. *far (may be NULL) gets the part beyond the radial function's
 * table (a rho >= RADIAL_Q_VMAX, radial.h), evaluated by Hankel's expansion at about 2.5 times
 * the cost. Arguments as fit_design_build's; 0 for bad ones. */
double fit_design_cost(double R_um, double pitch, int r, const double *x, const double *y,
                       size_t n, const fit_design_opts_t *opts, double *far);

#endif
