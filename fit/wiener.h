/* wiener.h: the paper's baseline, Wiener deconvolution of a scan raster (a regular grid of spot
 * positions) by the Airy kernel sampled on the same grid, returned on the scan grid and
 * normalised to mean 1. The raster is extended by mirroring at its edges (Neumann boundary),
 * not by zeros: the Airy kernel decays only like distance^-3, so a zero border would be a jump
 * no blur can produce and the filter would ring. Thread-safe, no I/O. */
#ifndef IPSD_FIT_WIENER_H
#define IPSD_FIT_WIENER_H

#include <stddef.h>

#include "base/err.h"
#include "fit/scandata.h"

typedef struct fit_wiener {
    int nx, ny;          /* grid size (columns, rows) */
    double step_x_um, step_y_um;
    double x0_um, y0_um; /* position of grid point (0, 0) */
    double nsr;          /* noise-to-signal power ratio used */
    double *S;           /* nx*ny, row-major y then x, mean 1; owned */
} fit_wiener_t;

/* Detects the regular grid of scan's positions (any order of points; -EINVAL naming the problem
 * when they are not a complete regular grid), builds the kernel, and deconvolves signal - bias.
 * nsr <= 0 picks it from the noise: mean sigma^2 / mean (signal - bias)^2 (paper noise model). */
int fit_wiener_run(const fit_scan_t *scan, double nsr, fit_wiener_t *out, err_t *err);

void fit_wiener_free(fit_wiener_t *w);

#endif
