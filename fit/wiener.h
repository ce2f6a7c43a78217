/* wiener.h: the paper's baseline, Wiener deconvolution of a scan raster (a regular grid of spot
 * positions) by the Airy kernel sampled on the same grid, returned on the scan grid and
 * normalised to mean 1. The raster is extended by mirroring at its edges (Neumann boundary),
 * not by zeros: the Airy kernel decays only like distance^-3, so a zero border would be a jump
 * no blur can produce and the filter would ring. The fair use (the paper's): deconvolve the whole
 * raster, spots outside the pixel too, and crop the map to the pixel, with the noise-to-signal
 * ratio chosen per frequency from the noise model and the data. Thread-safe, no I/O. */
#ifndef IPSD_FIT_WIENER_H
#define IPSD_FIT_WIENER_H

#include <stddef.h>

#include "base/err.h"
#include "fit/scandata.h"
#include "fit/stop.h"

/* How the noise-to-signal ratio is chosen (wiener.c explains each; docs/numerics.md measures). */
typedef enum fit_wiener_nsr {
    FIT_WIENER_NSR_SPECTRAL = 0, /* per frequency: the noise model's power over the signal
                                    power the data show at that frequency (the default) */
    FIT_WIENER_NSR_WHITE = 1,    /* one nsr: mean sigma^2 / mean (signal - bias)^2 (eq. 5) */
    FIT_WIENER_NSR_FIXED = 2,    /* the nsr given */
} fit_wiener_nsr_t;

typedef struct fit_wiener_opts {
    fit_wiener_nsr_t method;
    double nsr; /* FIT_WIENER_NSR_FIXED: the ratio, > 0 */
    int crop;   /* keep only the grid nodes inside the pixel (0, pitch)^2 (mean 1 again):
                   the whole raster is deconvolved, the map is the pixel's */
    fit_stop_t stop; /* polled inside the run's loops (stop.h's site "wiener": each row of the
                        kernel, of the FFT passes and of the spectral filter); zeroed: never */
} fit_wiener_opts_t;

/* Spectral nsr, cropped to the pixel. */
fit_wiener_opts_t fit_wiener_opts_default(void);

/* "white", "spectral" or "fixed" (static string). */
const char *fit_wiener_nsr_name(fit_wiener_nsr_t m);

typedef struct fit_wiener {
    int nx, ny;          /* grid size (columns, rows) of the map S */
    double step_x_um, step_y_um;
    double x0_um, y0_um; /* position of grid point (0, 0) of S */
    double nsr;          /* noise-to-signal power ratio used; spectral: the noise power over the
                            signal power the filter found, summed over all frequencies */
    double *S;           /* nx*ny, row-major y then x, mean 1; owned */
    /* additions */
    fit_wiener_nsr_t nsr_method;
    double signal_fraction;    /* spectral: fraction of the frequencies passed (others 0); 1 */
    int raster_nx, raster_ny;  /* the grid deconvolved (the whole raster given) */
    int cropped;               /* S is the part of that grid in the pixel */
} fit_wiener_t;

/* Detects the regular grid of scan's positions (any order of points; -EINVAL naming the problem
 * when they are not a complete regular grid), builds the kernel, and deconvolves signal - bias.
 * nsr <= 0 picks it from the noise: mean sigma^2 / mean (signal - bias)^2 (paper noise model). */
int fit_wiener_run(const fit_scan_t *scan, double nsr, fit_wiener_t *out, err_t *err);

/* The same with options (NULL: fit_wiener_opts_default()): every point of scan is deconvolved,
 * inside the pixel or not; with crop the map is cut to the grid nodes inside the pixel (region.h's
 * "inside" test; -EINVAL when none is). -ECANCELED when opts' stop answered. fit_wiener_run is
 * method white (nsr <= 0) or fixed, no crop. */
int fit_wiener_run_opts(const fit_scan_t *scan, const fit_wiener_opts_t *opts, fit_wiener_t *out,
                        err_t *err);

void fit_wiener_free(fit_wiener_t *w);

#endif
