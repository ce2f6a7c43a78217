/* interp.c: the paper's "interpolated IPS map" (Fig. IPSV_3D (b)): an r x r sub-pixel map
 * resampled on an n x n grid for display, by GSL's 2-D interpolation (gsl_spline2d): bicubic for
 * r >= 4 (GSL's bicubic needs 4 points per axis), bilinear for r = 2..3, constant for r = 1.
 *
 * Coordinates are in units of the pitch: sub-pixel i has its centre at (i + 1/2) / r, output
 * point k sits at (k + 1/2) / n. Output points outside the outermost sub-pixel centres are moved
 * onto them (constant extension), since GSL does not extrapolate. Thread-safe: all state local. */
#include "fit/interp.h"

#include <errno.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_interp2d.h>
#include <gsl/gsl_spline2d.h>
#include <stdlib.h>

#include "fit/gslerr.h"

/* Output coordinate k of n, clamped to the sample centres [c0, c1]. */
static double clamped_point(int k, int n, double c0, double c1)
{
    double p = (k + 0.5) / n;
    return p < c0 ? c0 : p > c1 ? c1 : p;
}

int fit_interp_bicubic(const double *map, int r, int n, double *out, err_t *err)
{
    fit_gsl_policy();
    if (!map || !out) return err_set(err, -EINVAL, "interp: map and output must not be NULL");
    if (r < 1) return err_set(err, -EINVAL, "interp: map size r must be >= 1 (got %d)", r);
    if (n < 1) return err_set(err, -EINVAL, "interp: output size n must be >= 1 (got %d)", n);
    size_t nn = (size_t)n * (size_t)n;
    if (r == 1) { /* one sub-pixel: the map is its value everywhere */
        for (size_t k = 0; k < nn; k++) out[k] = map[0];
        return 0;
    }
    const gsl_interp2d_type *type = r >= 4 ? gsl_interp2d_bicubic : gsl_interp2d_bilinear;
    int rc = 0;
    double *c = malloc(sizeof(double) * (size_t)r), *p = malloc(sizeof(double) * (size_t)n);
    gsl_spline2d *sp = gsl_spline2d_alloc(type, (size_t)r, (size_t)r);
    gsl_interp_accel *ax = gsl_interp_accel_alloc(), *ay = gsl_interp_accel_alloc();
    if (!c || !p || !sp || !ax || !ay) {
        rc = err_set(err, -ENOMEM, "interp: out of memory (r = %d, n = %d)", r, n);
        goto out;
    }
    for (int i = 0; i < r; i++) c[i] = (i + 0.5) / r;
    for (int k = 0; k < n; k++) p[k] = clamped_point(k, n, c[0], c[r - 1]);
    /* gsl_spline2d takes z[j * xsize + i] = z(x_i, y_j): row-major y then x, like our maps */
    int st = gsl_spline2d_init(sp, c, c, map, (size_t)r, (size_t)r);
    for (int j = 0; st == GSL_SUCCESS && j < n; j++)
        for (int i = 0; st == GSL_SUCCESS && i < n; i++)
            st = gsl_spline2d_eval_e(sp, p[i], p[j], ax, ay, &out[(size_t)j * n + i]);
    if (st != GSL_SUCCESS)
        rc = err_set(err, -EDOM, "interp: GSL interpolation failed: %s", gsl_strerror(st));
out:
    gsl_spline2d_free(sp);
    gsl_interp_accel_free(ax);
    gsl_interp_accel_free(ay);
    free(c);
    free(p);
    return rc;
}
