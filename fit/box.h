/* box.h: the integral of the unit-peak Airy spot over any rectangle, for any spot centre
 * (inside the box, on an edge or corner, or far outside), to a requested relative tolerance
 * with a returned error bound. The accurate reference path: adaptive Gauss-Kronrod (GSL QAG)
 * on each corner wedge (see corner.h). The design matrix uses the faster fixed-order path of
 * design.h. Thread-safe. */
#ifndef IPSD_FIT_BOX_H
#define IPSD_FIT_BOX_H

#include "base/err.h"

typedef struct fit_rect {
    double x0, x1, y0, y1; /* um; x0 > x1 (or y0 > y1) gives the signed integral */
} fit_rect_t;

/* Integral over rect of the unit-peak Airy of first-zero radius R_um centred at (xk, yk), in
 * um^2. rel_tol: requested relative accuracy (clamped to >= 1e-15). *err_bound (may be NULL):
 * bound on |value - exact| from the Gauss-Kronrod error estimates plus rounding.
 * Returns 0, or -EINVAL for bad arguments, -ERANGE if the tolerance could not be reached (the
 * value and its honest bound are still returned). */
int fit_box_integral(double R_um, const fit_rect_t *rect, double xk, double yk, double rel_tol,
                     double *value, double *err_bound, err_t *err);

#endif
