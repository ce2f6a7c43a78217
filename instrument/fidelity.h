/* fidelity.h: how close ipsd's maps come to the truth, measured on the simulated bench. A case is
 * a scene family (scene.h) scanned by a raster (the paper's n x n grid inside the pixel, or the
 * full procedure's raster around it) at a photon level and a noise seed; the scan is fitted for
 * r = 1..r_max (fit/model.h) and every map is compared with the scene's own map, the simulator's
 * truth: the rms difference of the two mean-1 sensitivities over the pixel, sampled on a fine
 * grid. Reported beside it: the r AIC and BIC pick, the best r in hindsight, the Wiener baseline's
 * rms, and what the fits cost. The evidence for scientific choices (which r to recommend, which
 * Wiener NSR) and the figures of `ips bench --fidelity`. */
#ifndef IPSD_INSTRUMENT_FIDELITY_H
#define IPSD_INSTRUMENT_FIDELITY_H

#include <stddef.h>

#include "base/err.h"
#include "fit/model.h"
#include "fit/noise.h"
#include "fit/recommend.h"
#include "fit/region.h"

#define FID_R_MAX 12
#define FID_MAX_RULES 16 /* recommend-rule settings measured in one run */

typedef struct fid_case {
    const char *scene;   /* scene spec (scene.h), e.g. "paperlike", "edge" */
    int grid;            /* n: n x n points inside the pixel from its true centre; 0: the full
                            raster of the paper's procedure (area_px pixels, subframe 3) */
    double step_um;      /* raster step */
    int area_px;         /* full raster only: pixels a side (5) */
    double flux_scale;   /* photo-electrons relative to the bench's default (1: ~2e4 e- per point) */
    unsigned long seed;  /* noise of the frames */
    fit_noise_t noise;   /* noise model of the fit */
    const fit_recommend_opts_t *rules; /* settings of the recommended-r rule to measure (NULL:
                                          the default only) */
    int n_rules;
    fit_region_t region; /* the points fitted (fit/region.h; inside): the full raster keeps
                            every point of the raster, the fit takes the region's */
    /* called with the finished sweep before it is freed, with the points it fitted and its
     * options (NULL: none); the bench's --dump, --explain and --simcheck */
    void (*on_sweep)(const fit_scan_t *scan, const fit_options_t *opts, const fit_sweep_t *sw,
                     void *ctx);
    void *on_sweep_ctx;
    int krige;           /* also estimate the kriged map the fit job stores (fit/krige.h) */
} fid_case_t;

typedef struct fid_result {
    size_t n_points;           /* spot positions fitted */
    int r_max;                 /* fits r = 1..r_max */
    double rms[FID_R_MAX + 1]; /* rms[r]: map error of the r x r fit (NaN: no map) */
    double chi2_red[FID_R_MAX + 1];
    double cv_chi2[FID_R_MAX + 1];
    int r_aic, r_bic, r_best;  /* picks (0: none) and the smallest rms in hindsight */
    int r_cv;                  /* smallest leave-one-out prediction chi2 */
    int r_rec[FID_MAX_RULES];  /* the recommended r (recommend.h) under each rule setting */
    double serr_rms[FID_R_MAX + 1]; /* the map's own noise: rms of S_err over the sub-pixels */
    double rms_wiener;         /* the Wiener baseline's map error (NaN when it failed): one nsr
                                  (white), the points inside the pixel only, mirrored */
    double rms_wiener_whole;   /* the fair Wiener: nsr per frequency, the whole raster
                                  deconvolved and cropped to the pixel (wiener.h) */
    double serr_edge[FID_R_MAX + 1]; /* rms of S_err over the r x r map's outer ring */
    double serr_inner[FID_R_MAX + 1]; /* and over the sub-pixels inside it (NaN for r <= 2) */
    double rms_shrunk;         /* the shrunk map's error (fit/shrink.h; NaN: none, then the
                                  recommended map stands as it is) */
    double shrunk_factor;      /* the fraction of its detail kept (NaN: none) */
    /* how honest S_err is: z = (S - truth's sub-pixel mean) / (S_err x the data's scatter) over
     * the sub-pixels of the recommended map and of the shrunk map (both mean 1): the count, the
     * sum of z^2 and the count with |z| <= 2 (0 when there is no shrunk map) */
    int z_n;
    double z2_rec, z2_shrunk;
    int z_in2_rec, z_in2_shrunk;
    /* the same with the resolution error added, sqrt(S_err^2 x scatter^2 + S_res^2) */
    double z2_rec_res, z2_shrunk_res;
    int z_in2_rec_res, z_in2_shrunk_res;
    double rms_kriged;         /* the kriged map's error (NaN: none, not asked or failed) */
    int kriged_grid, kriged_smooth; /* its F and whether its smooth part was kept */
    double kriged_ms;          /* its cost */
    int r_post;                /* the sweep's r whose map is nearest the kriged map (0: none): the
                                  pick minimising the expected squared error under the kriged
                                  posterior, |S_r - mean|^2 + tr(cov), the Bayes pick of one r */
    int z_n_kriged, z_in2_kriged; /* its S_err against the truth's mean over each fine cell */
    double z2_kriged;
    size_t n_raster;           /* the points of the whole raster */
    double sim_ms, fit_ms;     /* cost of the simulated scan and of the whole sweep */
} fid_result_t;

/* The rms difference over the pixel [0, p]^2 between a piecewise-constant r x r map S (row-major,
 * y then x) and the truth map T (m x m, same layout), both scaled to mean 1 first, sampled at the
 * centres of a g x g grid. Returns NaN when either mean is not positive. */
double fid_map_rms(const double *S, int r, const double *T, int m, int g);

/* Runs one case: simulates the scan, fits r = 1..r_max (1..FID_R_MAX), measures. Returns 0 or a
 * negative errno with err. */
int fid_run(const fid_case_t *c, int r_max, fid_result_t *out, err_t *err);

#endif
