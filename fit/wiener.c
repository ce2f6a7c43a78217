/* wiener.c: the paper's baseline (section "Results", last paragraphs: "We applied Wiener
 * deconvolution to remove the instrumental PSF from the pixel response data"), the classical
 * Wiener filter S = F^-1[ D conj(K) / (|K|^2 + nsr) ] on the scan raster.
 *
 * Model. The raster samples d_m = sum_n S_n K_{n-m}: spot position m sees the pixel's
 * sensitivity S, discretised on cells of the scan grid centred on the grid points, through the
 * Airy spot of eq. 2. K_l is the integral of the unit-peak Airy centred at the origin over the
 * grid cell at lag l (design.h, box.h), even in l, so the correlation is also a convolution. The
 * kernel covers every lag between two raster points, |l| <= n - 1 (it would stop earlier where
 * its rigorous bound falls below KERNEL_REL_CUT of its peak, but an Airy spot decays like
 * rho^-3 and only gets there thousands of rings out).
 *
 * Boundary. What the spot would see beyond the raster is not measured. Zero-padding (data 0
 * outside) is the wrong guess for a scan inside a pixel: the data jump from thousands of DN to 0
 * at the raster edge, a step no blur by the Airy can make, and the filter answers with edge
 * spikes and ringing through the whole map (tried: on the reference scan the edges come out at
 * 1.3 to 2.9 times the centre with negative values inside, and a noiseless field is missed by
 * O(1) even with nsr = 1e-12, because the kernel's rho^-3 tails spill across any border). So the
 * data are extended by mirroring at the raster edges (half-sample symmetric, the Neumann
 * boundary condition of Ng, Chan and Tang, SIAM J. Sci. Comput. 21 (1999) 851): d(-1-i) = d(i)
 * and d(2n-1-i) = d(i), period 2n per axis, no jump anywhere. For a field mirrored the same way
 * the model is then exact, so a noiseless raster is recovered as nsr -> 0.
 *
 * Units of nsr. The kernel is normalised to unit sum, so a uniform S gives d = S: the field has
 * the data's scale and |K|^2 <= 1 with K(0) = 1. Then nsr is a true noise-to-signal power ratio
 * per frequency for white noise and signal: mean sigma^2 / mean d^2 (sigma of eq. 5, the
 * paper's noise model, divided by sqrt(frames) as for eq. 4).
 *
 * Choosing nsr per frequency (FIT_WIENER_NSR_SPECTRAL, the default of fit_wiener_run_opts). The
 * Wiener filter minimising the expected squared error is conj(K) / (|K|^2 + N(f) / P_S(f)), with
 * N the noise power and P_S the field's power at frequency f. One nsr for all frequencies, mean
 * sigma^2 / mean d^2 (FIT_WIENER_NSR_WHITE, the original choice), takes the signal as white with
 * the power of the mean level: about 1e-5 for a pixel at 0.7 % noise, so every frequency the
 * blur has not quite erased is restored at a noise gain up to 1/|K|, and a flat pixel's map
 * varies by 10 % (9 x 9) to 39 % (13 x 13) (docs/numerics.md). Here both spectra come from what
 * is known: N(f) from the paper's noise model, P_S(f) |K(f)|^2 from the data's own periodogram:
 *   N(f)       = mean sigma^2 * c_x(k) c_y(l), the exact noise power of white noise of variance
 *                mean sigma^2 in bin (k, l) of the mirrored 2n-periodic array: per axis c(0) =
 *                4n, c(n) = 0, c(k) = 2n otherwise (the mirrored DFT is a DCT-II: X_k =
 *                2 e^{i pi k / 2n} sum_m x_m cos(pi k (m + 1/2) / n), and sum_m cos^2 = n / 2);
 *   Pbar_D(f)  = |D|^2 averaged over the 3 x 3 bins around f (a periodogram bin of noise alone
 *                is exponential with mean N: one bin is too noisy to decide anything), Nbar(f)
 *                = N averaged the same way;
 *   Q(f)       = Pbar_D - Nbar where Pbar_D > SPECTRAL_TAU Nbar, else 0: the signal power in the
 *                data, counted only where it is significant. The mean of 9 exponentials of
 *                mean N exceeds 5 N with probability P(Gamma(9, 1) > 45) ~ 1e-12 per bin, so a
 *                frequency where the blur left only noise is essentially never passed; without
 *                that guard a chance excess at a frequency where |K| ~ 1e-3 would come back
 *                multiplied by 1000;
 *   P_S(f)     = Q / |K|^2, the field's power, capped by its values at the next lower
 *                frequency along x and along y (nonincreasing from the DC outward; the cap by
 *                the larger of the two instead measured worse, docs/numerics.md):
 *                where the blur has all but erased a frequency (|K| ~ 1e-4 beyond the Airy's
 *                cutoff 2 NA / lambda on fine rasters), data power there cannot be the field's
 *                (it would need a field far stronger at high than at low frequencies); it is
 *                what no model term explains, e.g. the kink the mirror makes of a raster that
 *                ends inside the pixel, and uncapped it came back 1e4 times amplified (a 13 x 13
 *                raster's map at rms 30);
 *   G(f)       = conj(K) / (|K|^2 + Nbar / P_S), the Wiener filter with nsr(f) = Nbar / P_S(f),
 *                and 0 where P_S = 0.
 * A flat pixel then passes only the lowest frequencies (the DC's power leaks into its 3 x 3
 * neighbours), so its map is flat within the data's own noise (test_wiener.c). The reported nsr
 * is sum Nbar / sum |K|^2 P_S, the noise-to-signal power of the data over all frequencies.
 *
 * Whole raster and crop (fit_wiener_opts_t.crop). A raster inside the pixel holds the pixel's
 * edges at its border, where the mirror guesses what lies beyond. The paper deconvolves the whole
 * raster (51 x 51 over 5 x 5 pixels, the spots outside the pixel see its edges through their
 * wings) and keeps the part in the pixel: the grid nodes inside (0, pitch)^2, by the fit's
 * region test (region.h), renormalised to mean 1.
 *
 * Every point enters, saturated ones too (the filter needs a complete grid; the model fit of
 * model.h is the place that leaves points out).
 *
 * FFT. GSL's complex mixed-radix FFT on the 2nx x 2ny mirrored array, by rows then by columns
 * (strided, in place); the kernel's lag l sits at index l mod 2n, so the result is not shifted.
 * The data and the kernel are transformed together as one complex array d + i k and split by
 * Hermitian symmetry, so a run costs two 2-D transforms. Thread-safe: everything is local. */
#include "fit/wiener.h"

#include <errno.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_fft_complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/airy.h"
#include "fit/box.h"
#include "fit/design.h"
#include "fit/noise.h"
#include "fit/region.h"
#include "fit/gslerr.h"

#define GRID_REL_TOL 1e-6     /* a point may be this many steps off its grid node */
#define KERNEL_REL_CUT 1e-12  /* kernel entries below this fraction of the peak are left out */
#define KERNEL_ACCURACY 1e-13 /* accuracy of the kernel's cell integrals (relative to the peak) */
/* design.h takes r <= 256; 255 cells out, the Airy's rho^-3 tail is far below any noise */
#define KERNEL_MAX_HALF 255
#define SPECTRAL_HALF 1    /* the periodogram is averaged over (2h+1)^2 bins (see top) */
#define SPECTRAL_TAU 5.0   /* a bin carries signal where its average exceeds TAU x the noise's */

/* ---- the regular grid of scan positions ---- */

struct axis {
    int n;              /* number of grid lines */
    double step, start; /* spacing and position of line 0 */
};

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Finds the grid lines of one coordinate: sorted values are split where consecutive ones differ
 * by more than half the smallest possible step (range / (n - 1)); the lines are the means of
 * the groups, which must be evenly spaced (checked per point by grid_map). buf: n doubles. */
static int axis_detect(const double *v, size_t n, const char *name, double *buf, struct axis *ax,
                       err_t *err)
{
    memcpy(buf, v, sizeof(double) * n);
    qsort(buf, n, sizeof(double), cmp_double);
    double range = buf[n - 1] - buf[0], gap = 0.5 * range / (double)(n - 1);
    if (!(range > 0))
        return err_set(err, -EINVAL,
                       "scan grid: all %zu points have the same %s (%g um); Wiener deconvolution "
                       "needs at least 2 grid points along each axis",
                       n, name, buf[0]);
    double first = 0, last = 0, sum = buf[0];
    size_t group = 1;
    int lines = 1;
    for (size_t k = 1; k <= n; k++) {
        if (k == n || buf[k] - buf[k - 1] > gap) { /* end of a group of equal coordinates */
            if (lines == 1) first = sum / (double)group;
            last = sum / (double)group;
            if (k == n) break;
            lines++;
            sum = 0;
            group = 0;
        }
        sum += buf[k];
        group++;
    }
    ax->n = lines;
    ax->start = first;
    ax->step = (last - first) / (lines - 1);
    return 0;
}

/* Index of coordinate c on axis ax, or -1 when it is more than GRID_REL_TOL steps off a line. */
static int axis_index(const struct axis *ax, double c)
{
    double f = (c - ax->start) / ax->step, i = nearbyint(f);
    if (fabs(f - i) > GRID_REL_TOL || i < 0 || i >= ax->n) return -1;
    return (int)i;
}

/* Places signal - bias of every point on the nx x ny grid (d, row-major y then x); each grid
 * node must get exactly one point. slot: nx*ny longs of scratch. */
static int grid_map(const fit_scan_t *sc, const struct axis *gx, const struct axis *gy, double *d,
                    long *slot, err_t *err)
{
    size_t cells = (size_t)gx->n * (size_t)gy->n;
    for (size_t c = 0; c < cells; c++) slot[c] = -1;
    for (size_t k = 0; k < sc->n; k++) {
        int i = axis_index(gx, sc->x_um[k]), j = axis_index(gy, sc->y_um[k]);
        if (i < 0 || j < 0)
            return err_set(err, -EINVAL,
                           "scan grid: point %zu at (%g, %g) um is not on a regular grid (%d x %d "
                           "lines, steps %g x %g um from (%g, %g) um)",
                           k, sc->x_um[k], sc->y_um[k], gx->n, gy->n, gx->step, gy->step,
                           gx->start, gy->start);
        size_t c = (size_t)j * (size_t)gx->n + (size_t)i;
        if (slot[c] >= 0)
            return err_set(err, -EINVAL,
                           "scan grid: points %ld and %zu are both at grid node (%d, %d), "
                           "(%g, %g) um",
                           slot[c], k, i, j, sc->x_um[k], sc->y_um[k]);
        slot[c] = (long)k;
        d[c] = sc->signal_dn[k] - sc->bias_dn;
    }
    for (size_t c = 0; c < cells; c++)
        if (slot[c] < 0) {
            int i = (int)(c % (size_t)gx->n), j = (int)(c / (size_t)gx->n);
            return err_set(err, -EINVAL,
                           "scan grid: incomplete, %zu points for a %d x %d grid; node (%d, %d) "
                           "at (%g, %g) um has no point",
                           sc->n, gx->n, gy->n, i, j, gx->start + i * gx->step,
                           gy->start + j * gy->step);
        }
    return 0;
}

static int check_scan(const fit_scan_t *sc, double nsr, err_t *err)
{
    if (!sc || !sc->x_um || !sc->y_um || !sc->signal_dn)
        return err_set(err, -EINVAL, "wiener: no scan data");
    if (sc->n < 4)
        return err_set(err, -EINVAL, "wiener: %zu scan points, need a grid of at least 2 x 2",
                       sc->n);
    if (!(sc->spot_radius_um > 0) || !isfinite(sc->spot_radius_um))
        return err_set(err, -EINVAL, "wiener: spot radius must be positive and finite (got %g)",
                       sc->spot_radius_um);
    if (!isfinite(sc->bias_dn))
        return err_set(err, -EINVAL, "wiener: bias is not finite");
    if (!isfinite(nsr))
        return err_set(err, -EINVAL, "wiener: noise-to-signal ratio is not finite");
    if (nsr <= 0 && (!(sc->gain_e_per_dn > 0) || !isfinite(sc->gain_e_per_dn) ||
                     !(sc->read_noise_e >= 0) || !isfinite(sc->read_noise_e)))
        return err_set(err, -EINVAL,
                       "wiener: choosing nsr from the noise needs gain > 0 and read noise >= 0 "
                       "(got %g e/DN, %g e)",
                       sc->gain_e_per_dn, sc->read_noise_e);
    for (size_t k = 0; k < sc->n; k++)
        if (!isfinite(sc->x_um[k]) || !isfinite(sc->y_um[k]) || !isfinite(sc->signal_dn[k]))
            return err_set(err, -EINVAL, "wiener: point %zu has a non-finite %s", k,
                           !isfinite(sc->x_um[k])   ? "x position"
                           : !isfinite(sc->y_um[k]) ? "y position"
                                                    : "signal");
    return 0;
}

/* ---- the kernel ---- */

/* The stop poll of the run's loops (stop.h's site "wiener"); stop may be NULL. */
static int wstop(const fit_stop_t *stop)
{
    return stop && fit_stop_at(stop, FIT_STOP_SITE_WIENER);
}

/* Kernel half-width along an axis of n points: n - 1 (the longest lag between two raster
 * points; at most KERNEL_MAX_HALF), or less where the rigorous bound of a cell's integral (its
 * area times the Airy envelope at its nearest point, airy.h) is below KERNEL_REL_CUT of the
 * peak cell. */
static int kernel_half_width(double a, double step, double area, double peak, int n)
{
    int h = 0, hmax = n - 1 < KERNEL_MAX_HALF ? n - 1 : KERNEL_MAX_HALF;
    while (h < hmax && area * fit_airy_envelope(a, (h + 0.5) * step) >= KERNEL_REL_CUT * peak)
        h++;
    return h;
}

/* Quadrant q[(j)*(hx+1) + i] = integral of the unit-peak Airy at the origin over the cell
 * [(i-1/2) sx, (i+1/2) sx] x [(j-1/2) sy, (j+1/2) sy], i = 0..hx, j = 0..hy (the kernel is even
 * in both lags). Square cells: one call of the fast design matrix with the spot at the centre of
 * the corner cell of a "pixel" of (h+1) x (h+1) cells. Otherwise one accurate box integral per
 * cell (box.h): correct for any aspect, but some tens of microseconds per cell. */
static int kernel_quadrant(double R, double sx, double sy, int hx, int hy, double *q,
                           const fit_stop_t *stop, err_t *err)
{
    int w = hx + 1, rc = 0;
    if (fabs(sx - sy) <= 1e-9 * sx) {
        int r = (hx > hy ? hx : hy) + 1;
        double c = 0.5 * sx, *A = malloc(sizeof(double) * (size_t)r * (size_t)r);
        if (!A) return err_set(err, -ENOMEM, "wiener: out of memory for the kernel");
        fit_design_opts_t o = fit_design_opts_for_tol(KERNEL_ACCURACY);
        o.skip_tol = 0; /* every cell integrated: the tails are what the FFT must see */
        if (stop) o.stop = *stop; /* polled in its batches */
        rc = fit_design_build(R, r * sx, r, &c, &c, 1, &o, A, NULL, err);
        for (int j = 0; rc == 0 && j <= hy; j++)
            memcpy(q + (size_t)j * w, A + (size_t)j * r, sizeof(double) * (size_t)w);
        free(A);
        return rc;
    }
    for (int j = 0; j <= hy; j++) {
        if (wstop(stop)) return err_set(err, -ECANCELED, "wiener: stopped");
        for (int i = 0; i <= hx; i++) {
            fit_rect_t cell = {(i - 0.5) * sx, (i + 0.5) * sx, (j - 0.5) * sy, (j + 0.5) * sy};
            /* relative to the cell itself, so far finer than KERNEL_ACCURACY of the peak */
            rc = fit_box_integral(R, &cell, 0, 0, 1e-12, &q[(size_t)j * w + i], NULL, err);
            if (rc == -ERANGE) rc = 0; /* the honest value is still far inside our needs */
            if (rc) return rc;
        }
    }
    return 0;
}

/* ---- FFT ---- */

struct fft2 {
    int px, py;
    gsl_fft_complex_wavetable *wx, *wy;
    gsl_fft_complex_workspace *sx, *sy;
};

/* Frees what fft2_alloc got (GSL's free functions accept NULL). */
static void fft2_free(struct fft2 *f)
{
    if (f->wy != f->wx) gsl_fft_complex_wavetable_free(f->wy);
    if (f->sy != f->sx) gsl_fft_complex_workspace_free(f->sy);
    gsl_fft_complex_wavetable_free(f->wx);
    gsl_fft_complex_workspace_free(f->sx);
}

static int fft2_alloc(struct fft2 *f, int px, int py)
{
    *f = (struct fft2){.px = px, .py = py};
    f->wx = gsl_fft_complex_wavetable_alloc((size_t)px);
    f->sx = gsl_fft_complex_workspace_alloc((size_t)px);
    f->wy = py == px ? f->wx : gsl_fft_complex_wavetable_alloc((size_t)py);
    f->sy = py == px ? f->sx : gsl_fft_complex_workspace_alloc((size_t)py);
    return f->wx && f->sx && f->wy && f->sy ? 0 : -ENOMEM;
}

/* In-place 2-D transform of z (py rows of px complex numbers, interleaved re/im): rows, then
 * columns (stride px). inverse != 0: the inverse transform, including the 1/(px py). Returns 0,
 * -ECANCELED (stop answered, before a pass) or GSL's nonzero status. */
static int fft2_run(const struct fft2 *f, double *z, int inverse, const fit_stop_t *stop)
{
    int st = 0;
    if (wstop(stop)) return -ECANCELED;
    for (int j = 0; j < f->py; j++) {
        double *row = z + 2 * (size_t)j * f->px;
        st |= inverse ? gsl_fft_complex_inverse(row, 1, f->px, f->wx, f->sx)
                      : gsl_fft_complex_forward(row, 1, f->px, f->wx, f->sx);
    }
    if (wstop(stop)) return -ECANCELED;
    for (int i = 0; i < f->px; i++) {
        double *col = z + 2 * (size_t)i;
        st |= inverse ? gsl_fft_complex_inverse(col, f->px, f->py, f->wy, f->sy)
                      : gsl_fft_complex_forward(col, f->px, f->py, f->wy, f->sy);
    }
    return st;
}

/* z holds FFT(d + i k) of real d (raster data) and k (kernel). Replaces it by the Wiener
 * estimate's spectrum D conj(K) / (|K|^2 + nsr), where, with Z' = conj(Z(-f)),
 * D = (Z + Z') / 2 and K = (Z - Z') / (2i) (both transforms of real arrays are Hermitian). */
static void wiener_filter(double *z, int px, int py, double nsr)
{
    /* each pair (f, -f) is read before either is written: visit f <= -f in linear order */
    for (int j = 0; j < py; j++)
        for (int i = 0; i < px; i++) {
            size_t a = (size_t)j * px + i, b = (size_t)((py - j) % py) * px + (px - i) % px;
            if (b < a) continue;
            double zr = z[2 * a], zi = z[2 * a + 1], wr = z[2 * b], wi = z[2 * b + 1];
            /* at f: D = ((zr + wr) + i (zi - wi)) / 2, K = ((zi + wi) - i (zr - wr)) / 2;
             * at -f: D and K are the conjugates */
            double dr = 0.5 * (zr + wr), di = 0.5 * (zi - wi);
            double kr = 0.5 * (zi + wi), ki = -0.5 * (zr - wr);
            double g = 1.0 / (kr * kr + ki * ki + nsr);
            double xr = (dr * kr + di * ki) * g, xi = (di * kr - dr * ki) * g; /* D conj(K) */
            z[2 * a] = xr;
            z[2 * a + 1] = xi;
            z[2 * b] = xr;
            z[2 * b + 1] = -xi;
        }
}

/* Noise power factor of bin k of a mirrored axis of n points (period 2n): see top. */
static double mirror_noise_factor(int k, int n)
{
    return k == 0 ? 4.0 * n : k == n ? 0.0 : 2.0 * n;
}

/* Mean of v over the (2h+1)^2 bins around (i, j), periodic in px x py. */
static double box_mean(const double *v, int px, int py, int i, int j, int h)
{
    double acc = 0;
    for (int b = -h; b <= h; b++)
        for (int a = -h; a <= h; a++)
            acc += v[(size_t)((j + b + py) % py) * px + (size_t)((i + a + px) % px)];
    return acc / ((2.0 * h + 1) * (2.0 * h + 1));
}

/* The spectral choice (see top) on z = FFT(d + i k) of the 2nx x 2ny mirrored array; sig2 is
 * the mean noise variance of a point. Writes the estimate's spectrum into z, the summary nsr and
 * the fraction of bins passed. -ENOMEM, or -ECANCELED when stop answered (at each row of the
 * signal power's box means, its costly part). */
static int spectral_filter(double *z, int nx, int ny, double sig2, double *nsr, double *frac,
                           const fit_stop_t *stop)
{
    int px = 2 * nx, py = 2 * ny;
    size_t P = (size_t)px * py;
    double *kr = malloc(sizeof(double) * P), *ki = malloc(sizeof(double) * P);
    double *pd = malloc(sizeof(double) * P), *pn = malloc(sizeof(double) * P);
    if (!kr || !ki || !pd || !pn) {
        free(kr), free(ki), free(pd), free(pn);
        return -ENOMEM;
    }
    /* split into D (left in z) and K, as in wiener_filter */
    for (int j = 0; j < py; j++)
        for (int i = 0; i < px; i++) {
            size_t a = (size_t)j * px + i, b = (size_t)((py - j) % py) * px + (px - i) % px;
            if (b < a) continue;
            double zr = z[2 * a], zi = z[2 * a + 1], wr = z[2 * b], wi = z[2 * b + 1];
            double dr = 0.5 * (zr + wr), di = 0.5 * (zi - wi);
            kr[a] = kr[b] = 0.5 * (zi + wi);
            ki[a] = -0.5 * (zr - wr);
            ki[b] = -ki[a];
            z[2 * a] = z[2 * b] = dr;
            z[2 * a + 1] = di;
            z[2 * b + 1] = -di;
            pd[a] = pd[b] = dr * dr + di * di;
        }
    for (int j = 0; j < py; j++)
        for (int i = 0; i < px; i++)
            pn[(size_t)j * px + i] = sig2 * mirror_noise_factor(i < nx ? i : px - i, nx) *
                                     mirror_noise_factor(j < ny ? j : py - j, ny);
    /* the signal power estimate on the quadrant of distinct frequencies (k, l), k = 0..nx,
     * l = 0..ny, capped by its values at the lower frequencies (see top) */
    int wq = nx + 1;
    double *E = malloc(sizeof(double) * (size_t)wq * (ny + 1));
    double *N = malloc(sizeof(double) * (size_t)wq * (ny + 1));
    if (!E || !N) {
        free(kr), free(ki), free(pd), free(pn), free(E), free(N);
        return -ENOMEM;
    }
    for (int l = 0; l <= ny; l++) {
        if (wstop(stop)) {
            free(kr), free(ki), free(pd), free(pn), free(E), free(N);
            return -ECANCELED;
        }
        for (int k = 0; k <= nx; k++) {
            size_t a = (size_t)l * px + k, q = (size_t)l * wq + k;
            double PD = box_mean(pd, px, py, k, l, SPECTRAL_HALF);
            double PN = box_mean(pn, px, py, k, l, SPECTRAL_HALF);
            double Q = PD > SPECTRAL_TAU * PN ? PD - PN : 0, k2 = kr[a] * kr[a] + ki[a] * ki[a];
            double Ps = Q > 0 && k2 > 0 ? Q / k2 : 0, cap = INFINITY;
            if (k || l) cap = fmin(k ? E[q - 1] : INFINITY, l ? E[q - wq] : INFINITY);
            E[q] = fmin(Ps, cap);
            N[q] = PN;
        }
    }
    double sum_n = 0, sum_q = 0;
    size_t passed = 0;
    for (int j = 0; j < py; j++)
        for (int i = 0; i < px; i++) {
            size_t a = (size_t)j * px + i;
            size_t q = (size_t)(j <= ny ? j : py - j) * wq + (size_t)(i <= nx ? i : px - i);
            double k2 = kr[a] * kr[a] + ki[a] * ki[a], Ps = E[q], PN = N[q];
            sum_n += PN;
            sum_q += k2 * Ps;
            if (!(Ps > 0) || !(k2 * Ps + PN > 0)) { /* nothing significant */
                z[2 * a] = z[2 * a + 1] = 0;
                continue;
            }
            passed++;
            /* conj(K) / (|K|^2 + PN / Ps): the Wiener filter with nsr(f) = PN / Ps */
            double g = Ps / (k2 * Ps + PN), dr = z[2 * a], di = z[2 * a + 1];
            z[2 * a] = (dr * kr[a] + di * ki[a]) * g; /* D conj(K) g */
            z[2 * a + 1] = (di * kr[a] - dr * ki[a]) * g;
        }
    free(E), free(N);
    *nsr = sum_q > 0 ? sum_n / sum_q : INFINITY;
    *frac = (double)passed / (double)P;
    free(kr), free(ki), free(pd), free(pn);
    return 0;
}

/* ---- the run ---- */

/* nsr from the paper's noise model (eq. 5 with the 1/sqrt(frames) of eq. 4): the mean noise
 * power over the mean signal power of the data d (the field has the data's scale, see top). */
static double mean_sigma2(const fit_scan_t *sc)
{
    double ns = 0;
    for (size_t k = 0; k < sc->n; k++) {
        double s = fit_noise_sigma(FIT_NOISE_PAPER, sc, sc->signal_dn[k]);
        ns += s * s;
    }
    return ns / (double)sc->n;
}

static int auto_nsr(const fit_scan_t *sc, const double *d, size_t cells, double *nsr, err_t *err)
{
    double ns = mean_sigma2(sc) * (double)sc->n, ss = 0;
    for (size_t c = 0; c < cells; c++) ss += d[c] * d[c];
    if (!(ss > 0))
        return err_set(err, -EINVAL, "wiener: the signal equals the bias everywhere, no data");
    *nsr = (ns / (double)sc->n) / (ss / (double)cells);
    if (!(*nsr > 0)) /* no noise at all (read noise 0 and signal at bias): a tiny floor */
        *nsr = 1e-300;
    return 0;
}

/* Kernel half-widths (hx, hy) for the grid: see kernel_half_width; the peak cell is computed
 * accurately (box.h) so the cut is relative to the true peak. */
static int kernel_extent(const fit_scan_t *sc, const struct axis *gx, const struct axis *gy,
                         int *hx, int *hy, err_t *err)
{
    double a = fit_airy_a(sc->spot_radius_um), area = gx->step * gy->step, peak;
    fit_rect_t c = {-0.5 * gx->step, 0.5 * gx->step, -0.5 * gy->step, 0.5 * gy->step};
    int rc = fit_box_integral(sc->spot_radius_um, &c, 0, 0, 1e-6, &peak, NULL, err);
    if (rc && rc != -ERANGE) return rc;
    *hx = kernel_half_width(a, gx->step, area, peak, gx->n);
    *hy = kernel_half_width(a, gy->step, area, peak, gy->n);
    return 0;
}

/* Index in 0..n-1 of position i of the half-sample mirrored extension with period 2n. */
static int mirror(int i, int n)
{
    i %= 2 * n;
    if (i < 0) i += 2 * n;
    return i < n ? i : 2 * n - 1 - i;
}

/* Fills z (2nx x 2ny complex) with d + i k: the raster data d mirrored at the raster edges
 * (see top), and the kernel normalised to unit sum with lag (l, m) at (l mod 2nx, m mod 2ny). */
static int fill_input(const fit_scan_t *sc, const struct axis *gx, const struct axis *gy,
                      const double *d, int hx, int hy, double *z, const fit_stop_t *stop,
                      err_t *err)
{
    int nx = gx->n, ny = gy->n, px = 2 * nx, py = 2 * ny;
    size_t w = (size_t)hx + 1;
    double *q = malloc(sizeof(double) * w * ((size_t)hy + 1));
    if (!q) return err_set(err, -ENOMEM, "wiener: out of memory for the kernel");
    int rc = kernel_quadrant(sc->spot_radius_um, gx->step, gy->step, hx, hy, q, stop, err);
    if (rc) goto out;
    double sum = 0;
    for (int j = -hy; j <= hy; j++)
        for (int i = -hx; i <= hx; i++) sum += q[(size_t)abs(j) * w + (size_t)abs(i)];
    memset(z, 0, sizeof(double) * 2 * (size_t)px * (size_t)py);
    for (int j = 0; j < py; j++)
        for (int i = 0; i < px; i++)
            z[2 * ((size_t)j * px + i)] = d[(size_t)mirror(j, ny) * nx + mirror(i, nx)];
    for (int j = -hy; j <= hy; j++) /* hx < nx, hy < ny: no two lags share a slot */
        for (int i = -hx; i <= hx; i++) {
            size_t at = (size_t)((j + py) % py) * px + (size_t)((i + px) % px);
            z[2 * at + 1] = q[(size_t)abs(j) * w + (size_t)abs(i)] / sum;
        }
out:
    free(q);
    return rc;
}

/* Replaces the raster data d (nx*ny, row-major) by the Wiener estimate normalised to mean 1.
 * spectral: the per-frequency choice, *nsr and *frac get its summary; else the constant *nsr. */
static int deconvolve(const fit_scan_t *sc, const struct axis *gx, const struct axis *gy,
                      int spectral, double *nsr, double *frac, double *d, const fit_stop_t *stop,
                      err_t *err)
{
    if (wstop(stop)) return err_set(err, -ECANCELED, "wiener: stopped"); /* the first poll */
    int hx, hy, rc = kernel_extent(sc, gx, gy, &hx, &hy, err);
    if (rc) return rc;
    int px = 2 * gx->n, py = 2 * gy->n; /* one period of the mirrored data */
    struct fft2 f = {0};
    double *z = malloc(sizeof(double) * 2 * (size_t)px * (size_t)py);
    if (!z || fft2_alloc(&f, px, py)) {
        rc = err_set(err, -ENOMEM, "wiener: out of memory for a %d x %d FFT", px, py);
        goto out;
    }
    if ((rc = fill_input(sc, gx, gy, d, hx, hy, z, stop, err))) goto out;
    int st = fft2_run(&f, z, 0, stop);
    if (st) {
        rc = st == -ECANCELED ? err_set(err, st, "wiener: stopped")
                              : err_set(err, -EDOM, "wiener: GSL FFT failed");
        goto out;
    }
    if (!spectral)
        wiener_filter(z, px, py, *nsr);
    else if ((st = spectral_filter(z, gx->n, gy->n, mean_sigma2(sc), nsr, frac, stop))) {
        rc = st == -ECANCELED ? err_set(err, st, "wiener: stopped")
                              : err_set(err, -ENOMEM, "wiener: out of memory for the spectra");
        goto out;
    }
    if ((st = fft2_run(&f, z, 1, stop))) {
        rc = st == -ECANCELED ? err_set(err, st, "wiener: stopped")
                              : err_set(err, -EDOM, "wiener: GSL FFT failed");
        goto out;
    }
    double mean = 0;
    for (int j = 0; j < gy->n; j++)
        for (int i = 0; i < gx->n; i++)
            mean += d[(size_t)j * gx->n + i] = z[2 * ((size_t)j * px + i)]; /* real part */
    mean /= (double)gx->n * gy->n;
    if (!(mean > 0) || !isfinite(mean)) {
        rc = err_set(err, -EDOM, "wiener: the deconvolved map has mean %g, cannot normalise",
                     mean);
        goto out;
    }
    for (size_t c = 0; c < (size_t)gx->n * gy->n; c++) d[c] /= mean;
out:
    fft2_free(&f);
    free(z);
    return rc;
}

fit_wiener_opts_t fit_wiener_opts_default(void)
{
    return (fit_wiener_opts_t){.method = FIT_WIENER_NSR_SPECTRAL, .crop = 1};
}

const char *fit_wiener_nsr_name(fit_wiener_nsr_t m)
{
    switch (m) {
    case FIT_WIENER_NSR_WHITE: return "white";
    case FIT_WIENER_NSR_SPECTRAL: return "spectral";
    case FIT_WIENER_NSR_FIXED: return "fixed";
    }
    return "unknown";
}

/* Cuts w (the whole grid) to its nodes inside the pixel (0, p)^2, by the test of the fit's
 * region "inside" (region.h: 1e-6 p from the edges), renormalised to mean 1. A node on a pixel
 * edge stands for a cell half outside the pixel, so it is not part of the pixel's map. */
static int crop_to_pixel(fit_wiener_t *w, double p, err_t *err)
{
    fit_region_t inside = {FIT_REGION_INSIDE, 0};
    int i0 = w->nx, i1 = -1, j0 = w->ny, j1 = -1;
    double mid = 0.5 * p;
    for (int i = 0; i < w->nx; i++)
        if (fit_region_contains(&inside, p, w->x0_um + i * w->step_x_um, mid))
            i0 = i < i0 ? i : i0, i1 = i;
    for (int j = 0; j < w->ny; j++)
        if (fit_region_contains(&inside, p, mid, w->y0_um + j * w->step_y_um))
            j0 = j < j0 ? j : j0, j1 = j;
    if (i1 < 0 || j1 < 0)
        return err_set(err, -EINVAL,
                       "wiener: no node of the %d x %d scan grid (from (%g, %g) um, steps %g x %g "
                       "um) lies inside the pixel (0, %g)^2",
                       w->nx, w->ny, w->x0_um, w->y0_um, w->step_x_um, w->step_y_um, p);
    int cx = i1 - i0 + 1, cy = j1 - j0 + 1;
    double mean = 0;
    for (int j = 0; j < cy; j++) /* in place: row j of the crop never overtakes its source */
        for (int i = 0; i < cx; i++)
            mean += w->S[(size_t)j * cx + i] = w->S[(size_t)(j + j0) * w->nx + (i + i0)];
    mean /= (double)cx * cy;
    if (!(mean > 0) || !isfinite(mean))
        return err_set(err, -EDOM, "wiener: the map in the pixel has mean %g, cannot normalise",
                       mean);
    for (size_t c = 0; c < (size_t)cx * cy; c++) w->S[c] /= mean;
    w->x0_um += i0 * w->step_x_um;
    w->y0_um += j0 * w->step_y_um;
    w->nx = cx;
    w->ny = cy;
    w->cropped = 1;
    return 0;
}

int fit_wiener_run_opts(const fit_scan_t *scan, const fit_wiener_opts_t *opts, fit_wiener_t *out,
                        err_t *err)
{
    fit_gsl_policy();
    if (!out) return err_set(err, -EINVAL, "wiener: no output");
    *out = (fit_wiener_t){0};
    fit_wiener_opts_t o = opts ? *opts : fit_wiener_opts_default();
    if ((unsigned)o.method > FIT_WIENER_NSR_FIXED)
        return err_set(err, -EINVAL, "wiener: unknown nsr method %d", (int)o.method);
    if (o.method == FIT_WIENER_NSR_FIXED && !(o.nsr > 0))
        return err_set(err, -EINVAL, "wiener: a fixed nsr must be positive (got %g)", o.nsr);
    double nsr = o.method == FIT_WIENER_NSR_FIXED ? o.nsr : 0, frac = 1;
    int rc = check_scan(scan, nsr, err);
    if (rc) return rc;
    if (o.crop && (!(scan->pitch_um > 0) || !isfinite(scan->pitch_um)))
        return err_set(err, -EINVAL, "wiener: cropping to the pixel needs a positive pitch (got %g)",
                       scan->pitch_um);
    struct axis gx, gy;
    double *buf = malloc(sizeof(double) * scan->n), *d = NULL;
    long *slot = NULL;
    if (!buf) return err_set(err, -ENOMEM, "wiener: out of memory");
    if ((rc = axis_detect(scan->x_um, scan->n, "x", buf, &gx, err)) ||
        (rc = axis_detect(scan->y_um, scan->n, "y", buf, &gy, err)))
        goto out;
    size_t cells = (size_t)gx.n * (size_t)gy.n;
    if (cells > 2 * scan->n) { /* far from a grid: say so before allocating the grid */
        rc = err_set(err, -EINVAL,
                     "scan grid: incomplete, %zu points cannot fill the %d x %d grid of their "
                     "distinct coordinates",
                     scan->n, gx.n, gy.n);
        goto out;
    }
    d = malloc(sizeof(double) * cells);
    slot = malloc(sizeof(long) * cells);
    if (!d || !slot) {
        rc = err_set(err, -ENOMEM, "wiener: out of memory for a %d x %d grid", gx.n, gy.n);
        goto out;
    }
    if ((rc = grid_map(scan, &gx, &gy, d, slot, err))) goto out;
    int spectral = o.method == FIT_WIENER_NSR_SPECTRAL;
    if (o.method == FIT_WIENER_NSR_WHITE && (rc = auto_nsr(scan, d, cells, &nsr, err))) goto out;
    if ((rc = deconvolve(scan, &gx, &gy, spectral, &nsr, &frac, d, &o.stop, err))) goto out;
    *out = (fit_wiener_t){.nx = gx.n, .ny = gy.n, .step_x_um = gx.step, .step_y_um = gy.step,
                          .x0_um = gx.start, .y0_um = gy.start, .nsr = nsr, .S = d,
                          .nsr_method = o.method, .signal_fraction = frac, .raster_nx = gx.n,
                          .raster_ny = gy.n};
    d = NULL; /* handed to out */
    if (o.crop && (rc = crop_to_pixel(out, scan->pitch_um, err))) fit_wiener_free(out);
out:
    free(buf);
    free(d);
    free(slot);
    return rc;
}

int fit_wiener_run(const fit_scan_t *scan, double nsr, fit_wiener_t *out, err_t *err)
{
    if (!isfinite(nsr)) { /* check_scan's message, before the options would reject it */
        if (out) *out = (fit_wiener_t){0};
        return err_set(err, -EINVAL, "wiener: noise-to-signal ratio is not finite");
    }
    fit_wiener_opts_t o = {.method = nsr > 0 ? FIT_WIENER_NSR_FIXED : FIT_WIENER_NSR_WHITE,
                           .nsr = nsr};
    return fit_wiener_run_opts(scan, &o, out, err);
}

void fit_wiener_free(fit_wiener_t *w)
{
    if (!w) return;
    free(w->S);
    w->S = NULL;
}
