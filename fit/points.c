/* points.c: the usable points of a scan (points.h). */
#include "points.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

void fit_points_free(fit_points_t *p)
{
    free(p->idx);
    free(p->x);
    free(p->sigma);
    memset(p, 0, sizeof *p);
}

int fit_points_select(const fit_scan_t *scan, fit_noise_t noise, fit_points_t *p,
                      size_t *n_nonfinite, size_t *n_saturated)
{
    size_t n = scan->n ? scan->n : 1;
    memset(p, 0, sizeof *p);
    *n_nonfinite = *n_saturated = 0;
    p->idx = malloc(sizeof(size_t) * n);
    p->x = malloc(sizeof(double) * 3 * n);
    p->sigma = malloc(sizeof(double) * 2 * n);
    if (!p->idx || !p->x || !p->sigma) return -ENOMEM;
    p->y = p->x + n;
    p->d = p->y + n;
    p->w = p->sigma + n;
    /* sigma floor: the rounding of each frame to whole DN, variance 1/12 DN^2 (only reached
     * with zero read noise at zero signal, where the models give 0) */
    double floor = sqrt(1.0 / 12 / scan->frames);
    for (size_t k = 0; k < scan->n; k++) {
        double x = scan->x_um[k], y = scan->y_um[k], s = scan->signal_dn[k];
        if (!isfinite(x) || !isfinite(y) || !isfinite(s)) {
            ++*n_nonfinite;
            continue;
        }
        if (scan->full_scale_dn > 0 && s >= scan->full_scale_dn) {
            ++*n_saturated;
            continue;
        }
        size_t q = p->n++;
        p->idx[q] = k;
        p->x[q] = x;
        p->y[q] = y;
        p->d[q] = s - scan->bias_dn;
        p->sigma[q] = fmax(fit_noise_sigma(noise, scan, s), floor);
        p->w[q] = 1 / (p->sigma[q] * p->sigma[q]);
    }
    return 0;
}
