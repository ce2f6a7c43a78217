/* jitter.h: jitter photometry, what IPS maps are for. A star imaged with a point-spread function
 * (PSF) on pixels with intra-pixel sensitivity S moves with the telescope's pointing jitter; its
 * flux in the pixel (or an aperture of pixels) changes with the position even when the PSF's
 * flux does not. Given the maps, the PSF and the jitter, this predicts that change and corrects
 * a measured flux series for it (docs/numerics.md, "Jitter photometry").
 *
 * The flux fraction of a star at (x, y) in an aperture of pixels p with maps S^p on r_p x r_p
 * cells is  F_S(x, y) = sum_p sum_ij S^p_ij integral_cell(p,i,j) PSF(x' - x, y' - y) / PSF total,
 * S piecewise constant, so each term is a box integral of the PSF; F_1 is the same with S = 1
 * (a flat sensor). The relative response rho = F_S / F_1 is what the sensitivity multiplies the
 * star's flux by, relative to a flat pixel of the same mean (S has mean 1): rho -> 1 (the map's
 * mean) for a PSF much larger than the pixel and rho -> S(x, y) for a PSF much smaller than a
 * cell. The relative flux error of sample k is e_k = rho_k / rho_0 - 1, rho_0 at the nominal
 * position (a photometry calibrated with the star at its nominal pointing); the corrected flux of
 * a measured series is measured_k / rho_k.
 *
 * PSFs: the paper's Airy spot (eq. 2, first-zero radius R, eq. 1), integrated by fit/design.h's
 * cell integrals, or a circular Gaussian of standard deviation sigma, whose box integral is the
 * product of two error-function differences. Coordinates: micrometres, the star's position in the
 * frame of the aperture's reference pixel (dcol = drow = 0): that pixel is [0, pitch]^2, x to the
 * right, y downward. Thread-safe, no I/O, no globals. */
#ifndef IPSD_FIT_JITTER_H
#define IPSD_FIT_JITTER_H

#include <stddef.h>

#include "base/err.h"

typedef enum fit_psf_kind { FIT_PSF_AIRY = 0, FIT_PSF_GAUSS = 1 } fit_psf_kind_t;

typedef struct fit_psf {
    fit_psf_kind_t kind;
    double width_um; /* Airy: first-zero radius R (eq. 1); Gaussian: standard deviation sigma */
} fit_psf_t;

/* One pixel of the aperture: its offset from the reference pixel and its map (S NULL: flat,
 * S = 1; r is then ignored). */
typedef struct fit_jitter_pixel {
    int dcol, drow;
    int r;           /* map r x r, 1..256 */
    const double *S; /* r*r, row-major y then x: S[j*r + i]; borrowed */
} fit_jitter_pixel_t;

typedef struct fit_jitter_setup {
    double pitch_um;
    fit_psf_t psf;
    const fit_jitter_pixel_t *pixels; /* the aperture, n_pixels >= 1; borrowed */
    size_t n_pixels;
    double x0_um, y0_um; /* the star's nominal position (jitter offsets are added to it) */
} fit_jitter_setup_t;

/* Flux fractions F_S (flux_map) and F_1 (flux_flat) of a star at (x[k], y[k]), k < n, in the
 * aperture; either output may be NULL. Returns 0, or -EINVAL naming a bad argument (pitch,
 * width, r, a non-finite position, no pixel), -ENOMEM. */
int fit_jitter_flux(const fit_jitter_setup_t *s, const double *x, const double *y, size_t n,
                    double *flux_map, double *flux_flat, err_t *err);

/* What the jitter series does to the photometry. */
typedef struct fit_jitter_stats {
    size_t n;
    double rho0;        /* relative response at the nominal position */
    double flux0;       /* F_S there: the fraction of the star's flux the aperture records */
    double flat0;       /* F_1 there */
    double err_mean;    /* mean of e_k = rho_k / rho0 - 1 */
    double err_rms;     /* sqrt(mean e_k^2): the relative flux error intra-pixel sensitivity adds */
    double err_max;     /* max |e_k| */
    double rho_mean;    /* mean of rho_k */
    double rho_scatter; /* standard deviation of rho_k / its mean: the photometric scatter the
                           sensitivity adds to a series with this jitter (rms about the mean) */
    double flat_scatter; /* the same of F_1: the aperture's own loss as the star moves, which a
                            flat sensor has too (not caused by IPS; for comparison) */
} fit_jitter_stats_t;

/* The response to a jitter series: the star at (x0 + dx[k], y0 + dy[k]). rho and rel_err
 * (n each, may be NULL) get rho_k and e_k; *stats the summary. n >= 1. Errors as
 * fit_jitter_flux. */
int fit_jitter_run(const fit_jitter_setup_t *s, const double *dx, const double *dy, size_t n,
                   double *rho, double *rel_err, fit_jitter_stats_t *stats, err_t *err);

/* What fit_jitter_run of this series costs at most, in radial evaluations of the Airy PSF's
 * cell integrals (fit_design_cost over the aperture's pixels, the nominal position included),
 * those by Hankel's expansion counted 2.5 times (their measured cost): it grows with the spot's
 * a x the samples' distance from each pixel, so a caller can bound a run before starting it.
 * 19-26 ns each, measured over spots of 0.012-1.34 um and maps of r 1-64 (docs/operations.md;
 * the API's default bound, 4e7, is about a second). 0 for the Gaussian PSF (closed form) or bad
 * arguments. */
double fit_jitter_cost(const fit_jitter_setup_t *s, const double *dx, const double *dy, size_t n);

/* How far the samples reach from the nominal position: the largest hypot(dx, dy) (um), what a
 * refusal by fit_jitter_cost's bound names. */
double fit_jitter_reach(const double *dx, const double *dy, size_t n);

/* n jitter offsets drawn from a circular Gaussian of rms rms_um per axis (GSL mt19937 seeded with
 * seed, gsl_ran_gaussian_ziggurat): the same seed gives the same series. */
int fit_jitter_draw(double rms_um, size_t n, unsigned long seed, double *dx, double *dy,
                    err_t *err);

/* The corrected flux of a measured series: corrected[k] = measured[k] / rho[k] (in place
 * allowed). -EINVAL naming the first rho that is not > 0. */
int fit_jitter_correct(const double *measured, const double *rho, size_t n, double *corrected,
                       err_t *err);

#endif
