/* jitter.c: the flux of a star in pixels with intra-pixel sensitivity as the pointing jitters
 * (jitter.h; docs/numerics.md, "Jitter photometry"). S is piecewise constant on r x r cells, so
 * the flux is a weighted sum of the PSF's box integrals: fit/design.h's cell integrals for the
 * Airy PSF (every cell of a pixel for a batch of positions in one call), error functions for the
 * Gaussian. */
#include "fit/jitter.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

#include "fit/airy.h"
#include "fit/design.h"
#include "fit/gslerr.h"

#define CHUNK 512        /* positions per design-matrix call: bounds memory at CHUNK r^2 */
#define DESIGN_TOL 1e-10 /* cell integrals relative to the largest cell (design.h) */

static const double one = 1.0;

/* ---- Gaussian PSF ---- */

/* P(a < X < b) for X ~ N(0, 1/2) scaled: the mass of a unit Gaussian between the edges at
 * u = (edge - centre) / (sigma sqrt 2), taken on the side where erfc keeps its relative
 * precision (far tails would cancel in erf(b) - erf(a)). */
static double gauss_mass(double ua, double ub)
{
    if (ua >= 0) return 0.5 * (erfc(ua) - erfc(ub));
    if (ub <= 0) return 0.5 * (erfc(-ub) - erfc(-ua));
    return 0.5 * (erf(ub) - erf(ua));
}

/* F_S and F_1 of pixel px at the positions x, y (relative to that pixel's corner), added to fm,
 * ff. The box integral of a circular Gaussian is the product of its x and y masses, and the
 * whole-plane integral is 1, so no normalisation is needed. px (r*r cells, row-major). */
static int gauss_pixel(const fit_jitter_pixel_t *px, double pitch, double sigma, const double *x,
                       const double *y, size_t n, double *fm, double *ff)
{
    int r = px->S ? px->r : 1;
    const double *S = px->S ? px->S : &one;
    double *mx = malloc(sizeof(double) * 2 * (size_t)r);
    if (!mx) return -ENOMEM;
    double *my = mx + r, s2 = sigma * M_SQRT2, d = pitch / r;
    for (size_t k = 0; k < n; k++) {
        for (int i = 0; i < r; i++) {
            mx[i] = gauss_mass((i * d - x[k]) / s2, ((i + 1) * d - x[k]) / s2);
            my[i] = gauss_mass((i * d - y[k]) / s2, ((i + 1) * d - y[k]) / s2);
        }
        double sm = 0, sf = 0;
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) {
                double b = mx[i] * my[j];
                sm += S[j * r + i] * b;
                sf += b;
            }
        fm[k] += sm;
        ff[k] += sf;
    }
    free(mx);
    return 0;
}

/* ---- Airy PSF ---- */

/* The same for the Airy spot of radius R: the cell integrals of the unit-peak Airy (design.h)
 * divided by its whole-plane integral 4 pi / a^2 (airy.h). */
static int airy_pixel(const fit_jitter_pixel_t *px, double pitch, double R, const double *x,
                      const double *y, size_t n, double *fm, double *ff, err_t *err)
{
    int r = px->S ? px->r : 1;
    const double *S = px->S ? px->S : &one;
    size_t cells = (size_t)r * r, chunk = n < CHUNK ? n : CHUNK;
    double *A = malloc(sizeof(double) * cells * chunk);
    if (!A) return err_set(err, -ENOMEM, "out of memory for %zu cell integrals", cells * chunk);
    double total = fit_airy_total(fit_airy_a(R));
    fit_design_opts_t o = fit_design_opts_for_tol(DESIGN_TOL);
    int ret = 0;
    for (size_t k0 = 0; k0 < n && !ret; k0 += chunk) {
        size_t m = n - k0 < chunk ? n - k0 : chunk;
        ret = fit_design_build(R, pitch, r, x + k0, y + k0, m, &o, A, NULL, err);
        for (size_t k = 0; k < m && !ret; k++) {
            const double *row = A + k * cells;
            double sm = 0, sf = 0;
            for (size_t c = 0; c < cells; c++) {
                sm += S[c] * row[c];
                sf += row[c];
            }
            fm[k0 + k] += sm / total;
            ff[k0 + k] += sf / total;
        }
    }
    free(A);
    return ret;
}

/* ---- the aperture ---- */

static int check_setup(const fit_jitter_setup_t *s, err_t *err)
{
    if (!s || !s->pixels || s->n_pixels < 1)
        return err_set(err, -EINVAL, "pixels: need at least one pixel");
    if (!(s->pitch_um > 0) || !isfinite(s->pitch_um))
        return err_set(err, -EINVAL, "pitch_um: %g, need > 0", s->pitch_um);
    if (s->psf.kind != FIT_PSF_AIRY && s->psf.kind != FIT_PSF_GAUSS)
        return err_set(err, -EINVAL, "psf: unknown kind %d", (int)s->psf.kind);
    if (!(s->psf.width_um > 0) || !isfinite(s->psf.width_um))
        return err_set(err, -EINVAL, "psf width_um: %g, need > 0", s->psf.width_um);
    if (!isfinite(s->x0_um) || !isfinite(s->y0_um))
        return err_set(err, -EINVAL, "position: the nominal position is not finite");
    for (size_t p = 0; p < s->n_pixels; p++) {
        const fit_jitter_pixel_t *px = &s->pixels[p];
        if (px->S && (px->r < 1 || px->r > 256))
            return err_set(err, -EINVAL, "pixels[%zu] r: %d, need 1..256", p, px->r);
    }
    return 0;
}

/* Positions x, y (n; relative to the star pixel's corner) into pixel px's frame: xs, ys. */
static void pixel_frame(const fit_jitter_setup_t *s, const fit_jitter_pixel_t *px, const double *x,
                        const double *y, size_t n, double *xs, double *ys)
{
    for (size_t k = 0; k < n; k++) {
        xs[k] = x[k] - px->dcol * s->pitch_um;
        ys[k] = y[k] - px->drow * s->pitch_um;
    }
}

int fit_jitter_flux(const fit_jitter_setup_t *s, const double *x, const double *y, size_t n,
                    double *flux_map, double *flux_flat, err_t *err)
{
    fit_gsl_policy();
    int ret = check_setup(s, err);
    if (ret) return ret;
    for (size_t k = 0; k < n; k++)
        if (!isfinite(x[k]) || !isfinite(y[k]))
            return err_set(err, -EINVAL, "position %zu is not finite", k);
    /* fm, ff: the sums; xs, ys: the positions relative to one pixel's corner */
    double *buf = malloc(sizeof(double) * 4 * (n ? n : 1));
    if (!buf) return err_set(err, -ENOMEM, "out of memory for %zu positions", n);
    double *fm = buf, *ff = buf + n, *xs = buf + 2 * n, *ys = buf + 3 * n;
    memset(buf, 0, sizeof(double) * 2 * n);
    for (size_t p = 0; p < s->n_pixels && !ret; p++) {
        const fit_jitter_pixel_t *px = &s->pixels[p];
        pixel_frame(s, px, x, y, n, xs, ys);
        if (s->psf.kind == FIT_PSF_GAUSS) {
            ret = gauss_pixel(px, s->pitch_um, s->psf.width_um, xs, ys, n, fm, ff);
            if (ret) err_set(err, ret, "out of memory for the Gaussian PSF");
        } else {
            ret = airy_pixel(px, s->pitch_um, s->psf.width_um, xs, ys, n, fm, ff, err);
        }
    }
    if (!ret) {
        if (flux_map) memcpy(flux_map, fm, sizeof(double) * n);
        if (flux_flat) memcpy(flux_flat, ff, sizeof(double) * n);
    }
    free(buf);
    return ret;
}

double fit_jitter_reach(const double *dx, const double *dy, size_t n)
{
    double reach = 0;
    for (size_t k = 0; k < n; k++) reach = fmax(reach, hypot(dx[k], dy[k]));
    return reach;
}

double fit_jitter_cost(const fit_jitter_setup_t *s, const double *dx, const double *dy, size_t n)
{
    if (check_setup(s, NULL) || s->psf.kind != FIT_PSF_AIRY) return 0;
    /* the nominal position and the samples, then the same in one pixel's frame */
    size_t m = n + 1;
    double *x = malloc(sizeof(double) * 4 * m), cost = 0;
    if (!x) return INFINITY; /* cannot tell: as if too much */
    double *y = x + m, *xs = x + 2 * m, *ys = x + 3 * m;
    x[0] = s->x0_um, y[0] = s->y0_um;
    for (size_t k = 0; k < n; k++) x[k + 1] = s->x0_um + dx[k], y[k + 1] = s->y0_um + dy[k];
    fit_design_opts_t o = fit_design_opts_for_tol(DESIGN_TOL);
    for (size_t p = 0; p < s->n_pixels; p++) {
        const fit_jitter_pixel_t *px = &s->pixels[p];
        pixel_frame(s, px, x, y, m, xs, ys);
        double far;
        cost += fit_design_cost(s->psf.width_um, s->pitch_um, px->S ? px->r : 1, xs, ys, m, &o,
                                &far);
        cost += 1.5 * far; /* Hankel's expansion: a sincos and its series, ~2.5 table lookups */
    }
    free(x);
    return cost;
}

int fit_jitter_run(const fit_jitter_setup_t *s, const double *dx, const double *dy, size_t n,
                   double *rho, double *rel_err, fit_jitter_stats_t *stats, err_t *err)
{
    if (n < 1) return err_set(err, -EINVAL, "jitter: need at least one sample");
    int ret = check_setup(s, err);
    if (ret) return ret;
    /* position 0 is the nominal one, 1..n the jittered ones */
    size_t m = n + 1;
    double *buf = malloc(sizeof(double) * 4 * m);
    if (!buf) return err_set(err, -ENOMEM, "out of memory for %zu samples", n);
    double *x = buf, *y = buf + m, *fm = buf + 2 * m, *ff = buf + 3 * m;
    x[0] = s->x0_um;
    y[0] = s->y0_um;
    for (size_t k = 0; k < n; k++) {
        x[k + 1] = s->x0_um + dx[k];
        y[k + 1] = s->y0_um + dy[k];
    }
    ret = fit_jitter_flux(s, x, y, m, fm, ff, err);
    if (ret) goto out;
    for (size_t k = 0; k < m; k++)
        if (!(ff[k] > 0)) {
            ret = err_set(err, -ERANGE,
                          "%s %zu: the star puts no light in the aperture (%.3g um, %.3g um)",
                          k ? "sample" : "nominal position", k ? k - 1 : 0, x[k], y[k]);
            goto out;
        }
    fit_jitter_stats_t st = {.n = n, .flux0 = fm[0], .flat0 = ff[0], .rho0 = fm[0] / ff[0]};
    double se = 0, se2 = 0, sr = 0, sf = 0;
    for (size_t k = 1; k < m; k++) {
        double rk = fm[k] / ff[k], ek = rk / st.rho0 - 1;
        if (rho) rho[k - 1] = rk;
        if (rel_err) rel_err[k - 1] = ek;
        se += ek;
        se2 += ek * ek;
        if (fabs(ek) > st.err_max) st.err_max = fabs(ek);
        sr += rk;
        sf += ff[k];
    }
    st.err_mean = se / n;
    st.err_rms = sqrt(se2 / n);
    st.rho_mean = sr / n;
    /* scatters about the series' means, two-pass for accuracy (both are small relative numbers) */
    double vr = 0, vf = 0, mf = sf / n;
    for (size_t k = 1; k < m; k++) {
        double a = fm[k] / ff[k] - st.rho_mean, b = ff[k] - mf;
        vr += a * a;
        vf += b * b;
    }
    st.rho_scatter = sqrt(vr / n) / st.rho_mean;
    st.flat_scatter = sqrt(vf / n) / mf;
    if (stats) *stats = st;
out:
    free(buf);
    return ret;
}

int fit_jitter_draw(double rms_um, size_t n, unsigned long seed, double *dx, double *dy, err_t *err)
{
    if (!(rms_um >= 0) || !isfinite(rms_um))
        return err_set(err, -EINVAL, "jitter rms_um: %g, need >= 0", rms_um);
    fit_gsl_policy();
    gsl_rng *g = gsl_rng_alloc(gsl_rng_mt19937);
    if (!g) return err_set(err, -ENOMEM, "out of memory for the random generator");
    gsl_rng_set(g, seed);
    for (size_t k = 0; k < n; k++) {
        dx[k] = gsl_ran_gaussian_ziggurat(g, rms_um);
        dy[k] = gsl_ran_gaussian_ziggurat(g, rms_um);
    }
    gsl_rng_free(g);
    return 0;
}

int fit_jitter_correct(const double *measured, const double *rho, size_t n, double *corrected,
                       err_t *err)
{
    for (size_t k = 0; k < n; k++)
        if (!(rho[k] > 0) || !isfinite(rho[k]))
            return err_set(err, -EINVAL, "rho[%zu]: %g, need > 0", k, rho[k]);
    for (size_t k = 0; k < n; k++)
        corrected[k] = measured[k] / rho[k];
    return 0;
}
