/* adapt_plan.h: the planner of an adaptive scan of one pixel: from the points taken so far, the
 * next batch of spot positions, in an order that keeps the stage's path short, and the map's
 * expected rms error; the coarse raster it starts from; its stop rule.
 *
 * One planning step (fit_adapt_plan, docs/numerics.md "Where an adaptive scan looks next"):
 * the points so far (those of the options' region) are fitted as the fit job does, the sweep
 * r = 1..r_max, then the kriged map with the recommended r's divisor grids as its prior
 * (fit_krige_prior_for_sweep), with its posterior covariance Sigma of S over the F x F fine
 * cells (fit_krige_with_cov). The root of the mean posterior variance over the cells (equal
 * areas) is sqrt(tr Sigma / F^2); the map's expected rms error e, which the scan reports and
 * stops on, is its second moment under an equal mixture of that prior and the priors of r - 1
 * and r + 1 (fit_krige_mix: the posterior alone does not see the choice of r, and falls several
 * times below the error against the truth where the choice moves). Stop at the first plan with
 * e <= target once the scan holds a planned batch beyond its starting raster (the starting
 * raster's map is where e is least honest: docs/numerics.md "An honest stop"), when the scan holds
 * max_points points, or when no candidate lowers tr Sigma; otherwise the
 * batch is fit_adapt_pick's greedy choice (adapt.h) among the candidates: the nodes
 * (i p / L, j p / L) of a lattice over the pixel (L = lattice) that lie in the region (inside:
 * 0 < i, j < L; all: 0 <= i, j <= L, the edges included; margin: as far beyond as the margin
 * allows) and in the allowed box (the stage's travel), each a design row a_j of the fine grid
 * (design.h) with the variance of its measurement in S units,
 *     s_j^2 = sigma(B + I0 a_j^T S)^2 / I0^2,
 * sigma the noise model's at the signal the map predicts (I0 the recommended fit's; a candidate
 * whose predicted signal reaches full scale is left out, as the fit would leave it out). The
 * batch is then ordered for travel (fit_adapt_order) from the scan's last position.
 *
 * Deterministic: the same points give the same batch and the same stop (the fits run on the
 * caller's thread), so an interrupted scan resumes by planning again, batch boundary after batch
 * boundary, from the points it stored. Pure numerics, no I/O, no
 * globals, thread-safe. */
#ifndef IPSD_FIT_ADAPT_PLAN_H
#define IPSD_FIT_ADAPT_PLAN_H

#include <stddef.h>

#include "base/err.h"
#include "fit/krige.h"
#include "fit/model.h"
#include "fit/region.h"
#include "fit/scandata.h"

#define FIT_ADAPT_LATTICE 30    /* candidate lattice: divisions of the pitch (0.2 um of 6 um) */
#define FIT_ADAPT_LATTICE_MAX 200
#define FIT_ADAPT_START_GRID 5  /* the starting raster, n0 x n0 */
#define FIT_ADAPT_BATCH 9
#define FIT_ADAPT_TARGET_ERR 0.01
#define FIT_ADAPT_MAX_POINTS 300

typedef struct fit_adapt_opts {
    fit_options_t fit;    /* noise model and design accuracy of the fits (default shot+read: the
                             consistent noise model, whose sigma the expected error is in) */
    int r_max;            /* the sweep r = 1..r_max whose recommended r sets the prior (8) */
    fit_region_t region;  /* the points the maps fit and where candidates may lie (inside) */
    double box_um[4];     /* allowed spot positions, pixel coordinates (scandata.h): x_min,
                             x_max, y_min, y_max (-inf, inf, -inf, inf: no limit) */
    int lattice;          /* L, 2..FIT_ADAPT_LATTICE_MAX (FIT_ADAPT_LATTICE) */
    int batch;            /* positions a batch, >= 1 (FIT_ADAPT_BATCH) */
    double target_err;    /* stop at an expected rms error <= this, > 0 (FIT_ADAPT_TARGET_ERR) */
    size_t max_points;    /* stop when the scan holds this many points (FIT_ADAPT_MAX_POINTS) */
    size_t start_points;  /* the starting raster's points: a target stops the scan only once it
                             holds more, a planned batch at least (FIT_ADAPT_START_GRID^2) */
} fit_adapt_opts_t;

/* The defaults above. */
fit_adapt_opts_t fit_adapt_opts_default(void);

typedef enum fit_adapt_stop {
    FIT_ADAPT_GO = 0,      /* a batch to take */
    FIT_ADAPT_TARGET = 1,  /* the expected error is at or below target_err */
    FIT_ADAPT_BUDGET = 2,  /* the scan holds max_points points */
    FIT_ADAPT_NO_GAIN = 3, /* no candidate lowers the posterior variance */
} fit_adapt_stop_t;

/* "go", "target", "budget" or "no_gain" (static string). */
const char *fit_adapt_stop_name(fit_adapt_stop_t s);

typedef struct fit_adapt_step {
    fit_adapt_stop_t stop;
    size_t n_fitted;      /* the scan's usable points in the region: what the map fitted */
    double expected_err;  /* e of the map of the points so far, under the neighbouring priors
                             (fit_krige_mix): what the stop rule reads */
    double posterior_err; /* the root of the mean posterior variance, sqrt(tr Sigma / F^2), under
                             the recommended r's prior alone (the rms of map.S_err) */
    int target_met;       /* e <= target_err at this plan (a stop once past the start) */
    int smooth;           /* the kriged map kept its smooth part (map.smooth, kept after
                             fit_adapt_step_free for the scan's reports) */
    double predicted_err; /* e expected after the batch: the posterior's part as the picks lower
                             it, the priors' spread held (NaN without a batch) */
    int n;                /* positions in the batch (0 unless stop is FIT_ADAPT_GO) */
    double *x_um, *y_um;  /* n positions, pixel coordinates, in travel order (owned) */
    double path_um;       /* the stage's path through them from the scan's last position */
    int r;                /* the recommended r whose divisor grids are the prior (1: none) */
    fit_kriged_t map;     /* the kriged map of the points so far (owned; S_cov released) */
    double ms;            /* cost of the step */
} fit_adapt_step_t;

/* What a scan's plans share: the candidates' design rows on the fine grid of the last plan (the
 * bulk of a step's design work), reused while the grid, the spot and the candidates stay the
 * same (rebuilt when the recommended r moves F), so a plan with the cache gives the batch a plan
 * without it gives, bit for bit. Zero it before the scan's first plan; release it with
 * fit_adapt_cache_free. One scan's, used by one thread at a time. */
typedef struct fit_adapt_cache {
    int grid;                 /* F of the rows kept (0: none) */
    long nc;                  /* candidates */
    double radius_um, pitch_um, tol; /* the spot, the pixel, the design accuracy they were built at */
    double *cx, *cy;          /* nc candidate positions */
    double *A;                /* nc x F^2 design rows, row-major */
} fit_adapt_cache_t;

void fit_adapt_cache_free(fit_adapt_cache_t *c);

/* One planning step for scan (all points taken so far, in the order taken; positions relative to
 * the pixel's corner) under o (NULL: the defaults). cache (NULL: none)
 * carries the candidates' design rows from plan to plan (it changes no result). 0 with *out
 * (release with fit_adapt_step_free, also after an error); -EINVAL (bad options naming them, too
 * few points for the map, no signal), -ENOMEM, -EDOM (the algebra failed) with err. */
int fit_adapt_plan(const fit_scan_t *scan, const fit_adapt_opts_t *o, fit_adapt_cache_t *cache,
                   fit_adapt_step_t *out, err_t *err);

void fit_adapt_step_free(fit_adapt_step_t *s);

/* The starting raster: the centres of an n0 x n0 split of the pixel [0, pitch]^2, row by row
 * from the top, each row the opposite way to the one before (a short path), leaving out those
 * outside box_um (NULL: none). x, y get up to n0 * n0 positions; returns their count, or -EINVAL
 * for n0 < 1 or a pitch <= 0. */
int fit_adapt_start(double pitch_um, int n0, const double *box_um, double *x, double *y);

/* The candidates of o for a pixel of pitch_um (the lattice's nodes in the region and the box), in
 * row-major order of the lattice. *x, *y are allocated (the caller frees them, also when the
 * count is 0); returns the count, -EINVAL (bad lattice or pitch) or -ENOMEM. */
long fit_adapt_candidates(double pitch_um, const fit_adapt_opts_t *o, double **x, double **y);

/* The order of n positions that keeps the path from (x0, y0) through all of them short: the
 * nearest neighbour first, then local moves while one shortens the path (or-opt: one position
 * moved elsewhere; 2-opt: a stretch reversed), and never longer than the positions' own order. perm (n) gets the order (a permutation
 * of 0..n-1); returns the path's length, or NAN for a non-finite position. */
double fit_adapt_order(size_t n, const double *x, const double *y, double x0, double y0,
                       size_t *perm);

#endif
