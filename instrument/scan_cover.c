/* scan_cover.c: whether a raster covers a sub-frame pixel (the rule is in scan_cover.h). */
#include "instrument/scan_cover.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void scan_pixel_cover(const scan_setup_t *su, int dcol, int drow, double step_um, const double *sx,
                      const double *sy, size_t n, scan_cover_t *out)
{
    memset(out, 0, sizeof *out);
    out->x_min_um = out->y_min_um = INFINITY;
    out->x_max_um = out->y_max_um = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        double x, y;
        out->n_inside += (size_t)scan_pixel_coords(su, dcol, drow, sx[i], sy[i], &x, &y);
        out->x_min_um = fmin(out->x_min_um, x);
        out->x_max_um = fmax(out->x_max_um, x);
        out->y_min_um = fmin(out->y_min_um, y);
        out->y_max_um = fmax(out->y_max_um, y);
    }
    double p = su->pitch_um, tol = step_um / 2;
    const char *edge = out->x_min_um > tol       ? "left"
                       : out->x_max_um < p - tol ? "right"
                       : out->y_min_um > tol     ? "top"
                       : out->y_max_um < p - tol ? "bottom"
                                                 : NULL;
    if (n == 0) {
        snprintf(out->reason, sizeof out->reason, "the raster has no points");
    } else if (edge) {
        snprintf(out->reason, sizeof out->reason,
                 "the raster does not reach the pixel's %s edge (it spans x %.4g..%.4g um, "
                 "y %.4g..%.4g um of the pixel's 0..%.4g um, step %.4g um)",
                 edge, out->x_min_um, out->x_max_um, out->y_min_um, out->y_max_um, p, step_um);
    } else if (out->n_inside < SCAN_COVER_MIN_INSIDE) {
        snprintf(out->reason, sizeof out->reason,
                 "only %zu raster points lie inside the pixel (need at least %d)", out->n_inside,
                 SCAN_COVER_MIN_INSIDE);
    } else {
        out->covered = 1;
    }
}
