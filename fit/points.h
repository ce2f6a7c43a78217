/* points.h (internal to fit/): the usable points of a scan as the fits see them: finite, below
 * full scale, with the signal above bias and the noise model's sigma per point. Shared by the
 * r x r fits (model.c) and the kriged map (krige.c), so both fit the same points with the same
 * weights. */
#ifndef IPSD_FIT_POINTS_H
#define IPSD_FIT_POINTS_H

#include <stddef.h>

#include "fit/noise.h"
#include "fit/scandata.h"

typedef struct fit_points {
    size_t n, *idx;                /* usable points and their index in the scan */
    double *x, *y, *d, *sigma, *w; /* position, signal - bias, uncertainty, 1/sigma^2 */
} fit_points_t;

/* Selects the usable points of scan (checked by fit_scan_check) into p, counting the points
 * left out as non-finite (position or signal) and at or above full scale. 0 or -ENOMEM (p is
 * then still safe to free). */
int fit_points_select(const fit_scan_t *scan, fit_noise_t noise, fit_points_t *p,
                      size_t *n_nonfinite, size_t *n_saturated);

void fit_points_free(fit_points_t *p);

#endif
