/* interp.h: bicubic interpolation of an r x r map for display (the paper's "interpolated IPS
 * map"), sampled at the sub-pixel centres and evaluated on an n x n grid of points covering the
 * pixel. Thread-safe, no I/O. */
#ifndef IPSD_FIT_INTERP_H
#define IPSD_FIT_INTERP_H

#include "base/err.h"

/* map: r*r values, row-major y then x. out: n*n values (caller-allocated) at the centres of an
 * n x n split of the pixel, row-major y then x. Points outside the outermost sub-pixel centres
 * take the value at the nearest one of them (constant extension). r >= 1, n >= 1; r < 4 falls
 * back to bilinear (r = 1: constant). Returns 0, -EINVAL or -ENOMEM. */
int fit_interp_bicubic(const double *map, int r, int n, double *out, err_t *err);

#endif
