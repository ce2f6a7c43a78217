/* pipeline.h: the whole fit of one pixel scan as one call: the sweep over r with the best r by
 * AIC and by BIC, the F-test of an edge model, the Wiener baseline and the interpolated best-AIC
 * map, each step timed. `ips fit` and ipsd's fit workers both run this; fit_sweep_run
 * (model.h) is this pipeline with only the sweep, so the tree has one sweep loop.
 *
 * Watching a run follows GSL's driver callback (gsl_multifit_nlinear_driver's
 * `callback(iter, params, w)`): a progress function is called after every step with the steps
 * done and the steps in all and which step it was, and a stop function is consulted before every
 * step (the first one included); a stop returns -ECANCELED and keeps nothing. A step can take
 * seconds (r = 32 of a large scan, an LM fit), so a poll function, when given, is also called
 * inside the steps' long loops (stop.h: each batch of design-matrix rows, after each solve, each
 * LM iteration of the paper's fit and of the geometry fit): a nonzero answer there stops the run
 * the same way, within a fraction of one step.
 *
 * The scan given is the whole raster. The sweep and the F-test fit its points in the options'
 * region (region.h, by default the paper's: inside the pixel); the Wiener baseline deconvolves
 * every point and crops its map to the pixel (wiener.h). A region without points gives fits with
 * status no_points, as an empty scan does (n_region says so).
 *
 * Only the sweep can fail the run. The F-test, the Wiener baseline and the interpolation each
 * report their own outcome (fit_part_t): a scan too small for the F-test or not on a regular grid
 * for Wiener leaves that part with a negative errno and a message, and the caller decides (ipsd
 * stores {"error": ...} in its place, `ips fit` exits 2 when the part was asked for).
 *
 * Pure numerics: no I/O, no globals, thread-safe (the watch functions run on the caller's
 * thread). GSL errors never abort the process: see model.h on fit/'s GSL error policy. */
#ifndef IPSD_FIT_PIPELINE_H
#define IPSD_FIT_PIPELINE_H

#include "base/err.h"
#include "fit/geometry.h"
#include "fit/model.h"
#include "fit/region.h"
#include "fit/wiener.h"

#define FIT_R_MAX 32         /* largest r fit_map accepts */
#define FIT_INTERP_MAX 4096  /* largest interpolated grid */

/* What to run. */
typedef struct fit_pipeline_opts {
    int r_min, r_max;      /* the sweep, 1 <= r_min <= r_max <= FIT_R_MAX (1..8) */
    fit_options_t fit;     /* noise model, method, nonneg, design accuracy (model.h) */
    unsigned ftest_edges;  /* edges of the F-test's null model (enum fit_edge); 0: no F-test */
    int ftest_r;           /* r of the F-test, 1..FIT_R_MAX (7) */
    int wiener;            /* run the Wiener baseline (0) */
    double wiener_nsr;     /* its noise-to-signal ratio; <= 0 picks it from the noise (0) */
    int interp_n;          /* interpolate the best-AIC map on an n x n grid; 0: none (0) */
    fit_region_t region;   /* the points the sweep and the F-test fit (region.h; inside) */
    fit_wiener_nsr_t wiener_method; /* how Wiener picks nsr when wiener_nsr <= 0 (spectral) */
    int fit_geometry;      /* fit R, dx, dy first (geometry.h) and run every later step on the
                              scan as the fitted geometry says it was (0) */
    int geometry_r;        /* r of the geometry fit, 1..FIT_R_MAX; 0: picked from the data
                              (fit_geometry_pick) */
    int geometry_map_only; /* 1: keep the r x r fit's geometry; 0: refine it under the kriged
                              model (fit_geometry_krige), the default (0) */
    int threads;           /* fit the sweep's r on up to this many threads, the caller's
                              included, when the run has no watch (a watch's functions run on
                              the caller's thread, so a watched sweep runs there); 0 or 1: the
                              caller's only (0). The results are the same bit for bit: each r is
                              its own fit, and every thread's design cache gives the values a
                              fresh build would (design.h) */
    int krige;             /* also estimate the kriged map of the recommended r (krige.h) into
                              sweep.kriged (0); where it cannot be had (too many points, no
                              signal) sweep.kriged stays NULL and kriged_error says why */
    int krige_mix;         /* with krige: also its expected error under the neighbouring priors
                              (fit_krige_mix, the adaptive scan's expected error) into the map's
                              mix_* fields (0) */
} fit_pipeline_opts_t;

/* The geometry fit's r before it was picked from the data; kept for callers that name it. */
#define FIT_GEOMETRY_R_DEFAULT 5

/* r 1..8 with fit_options_default(), no F-test (ftest_r 7), no Wiener, no interpolation. */
fit_pipeline_opts_t fit_pipeline_opts_default(void);

/* The steps of a run, in the order they run: the geometry fit when asked, the sweep's
 * r_min..r_max, then the F-test, the Wiener baseline and the interpolation when asked. */
typedef enum fit_step_kind {
    FIT_STEP_SWEEP = 0, /* the fit at one r of the sweep */
    FIT_STEP_FTEST = 1,
    FIT_STEP_WIENER = 2,
    FIT_STEP_INTERP = 3,
    FIT_STEP_GEOMETRY = 4, /* the geometry fit (runs first) */
} fit_step_kind_t;

typedef struct fit_step {
    fit_step_kind_t kind;
    int r;            /* the r fitted (sweep, geometry), tested (F-test) or interpolated; 0 for
                         Wiener */
    int index, total; /* 0-based position of the step among the run's total steps */
} fit_step_t;

/* "sweep", "ftest", "wiener", "interp" or "geometry" (static string). */
const char *fit_step_name(fit_step_kind_t kind);

/* How a run is watched; every member may be NULL. */
typedef struct fit_watch {
    /* After each finished step: done = step->index + 1 of step->total steps. */
    void (*progress)(int done, int total, const fit_step_t *step, void *params);
    /* Before each step: nonzero stops the run (-ECANCELED). */
    int (*stop)(const fit_step_t *next, void *params);
    void *params;
    /* Inside the steps' long loops (stop.h): nonzero stops the run (-ECANCELED). Keep it cheap
     * (an atomic load): it runs many times per step. NULL: only the stop above. */
    int (*poll)(void *params);
    /* Optional: the same poll at a named place (stop.h's poll_at, FIT_STOP_SITE_*). */
    int (*poll_at)(void *params, const char *site);
} fit_watch_t;

/* The outcome of an optional part. */
typedef struct fit_part {
    int asked; /* the options asked for it */
    int rc;    /* 0 done; a negative errno when it failed, err saying why */
    err_t err;
    double ms; /* time it took (0 when not asked) */
} fit_part_t;

typedef struct fit_pipeline {
    fit_sweep_t sweep;      /* fits r_min..r_max and best_aic / best_bic (model.h) */
    double sweep_ms;
    fit_part_t ftest_part;  /* ftest valid when asked and rc == 0 */
    fit_ftest_t ftest;
    fit_part_t wiener_part; /* wiener valid when asked and rc == 0 */
    fit_wiener_t wiener;
    fit_part_t interp_part; /* interp valid when asked, rc == 0 and interp_r > 0 */
    int interp_r, interp_n; /* r of the best-AIC map interpolated (0: no fit has a map), n */
    double *interp;         /* interp_n^2 values, row-major y then x; NULL without one */
    double total_ms;        /* the whole run */
    fit_region_t region;    /* the region fitted */
    size_t n_region;        /* the scan's points in it: the points the sweep saw */
    fit_part_t geometry_part; /* geometry valid when asked and rc == 0; a geometry fit with
                                 flags is a failed part (rc -EDOM) and the later steps use the
                                 written geometry */
    fit_geometry_t geometry;
    char kriged_error[256]; /* why sweep.kriged is NULL although asked (no recommended r, too
                               many points, no signal); "" otherwise */
} fit_pipeline_t;

/* Runs the steps opts asks for on scan. Returns 0 (check the parts), -EINVAL for a bad scan or
 * bad options (err names them: r_min/r_max, ftest_r, interp_n, region), -ECANCELED when watch->stop
 * stopped it, or an error of the sweep's fit_map (-ENOMEM, -EDOM). Except on 0, *out holds
 * nothing (fit_pipeline_free is still allowed); on 0, release it with fit_pipeline_free. */
int fit_pipeline_run(const fit_scan_t *scan, const fit_pipeline_opts_t *opts,
                     const fit_watch_t *watch, fit_pipeline_t *out, err_t *err);

void fit_pipeline_free(fit_pipeline_t *pl);

#endif
