/* test_wiener.c: the Wiener baseline of wiener.h against independent truths.
 *
 * The rasters are made here by direct summation, d_m = sum_l S(m + l) K(l), with the kernel K
 * built here cell by cell with the accurate box integral (box.h; wiener.c takes its kernel from
 * the design matrix of design.h) and the field S mirrored at the raster edges, the boundary
 * condition wiener.c assumes (see its header). Truths: a known field comes back as nsr -> 0; a
 * delta comes back on its own grid point; a uniform field gives 1; a cosine that is an
 * eigenfunction of the blur comes back attenuated by exactly |K|^2 / (|K|^2 + nsr), which pins
 * down the units of nsr (unit-sum kernel); nsr from the paper's noise model (eq. 5, eq. 4);
 * malformed grids are refused with a message naming the problem; and on the reference scan the
 * map shows the scene's fill-factor dips at the top, left and bottom edges but not the right. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/box.h"
#include "check.h"
#include "refdata.h"
#include "fit/wiener.h"

#define R_SPOT 1.34 /* um, the paper's spot */
#define BIAS 100.0
#define SCALE 1000.0 /* DN per unit of sensitivity */

/* A raster scene: grid, kernel quadrant (unit sum over all lags |l| <= n - 1) and the data. */
typedef struct scene {
    int nx, ny;
    double sx, sy, x0, y0;
    double *K;         /* (nx) x (ny) quadrant: K[j * nx + i] for lags (+-i, +-j) */
    double *x, *y, *s; /* nx*ny points in a shuffled order */
    fit_scan_t scan;
} scene_t;

static int mirror(int i, int n)
{
    i %= 2 * n;
    if (i < 0) i += 2 * n;
    return i < n ? i : 2 * n - 1 - i;
}

static void scene_init(scene_t *sc, int nx, int ny, double sx, double sy)
{
    *sc = (scene_t){.nx = nx, .ny = ny, .sx = sx, .sy = sy, .x0 = 0.45, .y0 = 0.8};
    sc->K = malloc(sizeof(double) * nx * ny);
    double sum = 0;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            fit_rect_t cell = {(i - 0.5) * sx, (i + 0.5) * sx, (j - 0.5) * sy, (j + 0.5) * sy};
            double v;
            CHECK(fit_box_integral(R_SPOT, &cell, 0, 0, 1e-12, &v, NULL, NULL) == 0);
            sc->K[j * nx + i] = v;
            sum += v * (i ? 2 : 1) * (j ? 2 : 1);
        }
    for (int k = 0; k < nx * ny; k++) sc->K[k] /= sum;
    size_t n = (size_t)nx * ny;
    sc->x = malloc(sizeof(double) * n);
    sc->y = malloc(sizeof(double) * n);
    sc->s = malloc(sizeof(double) * n);
    sc->scan = (fit_scan_t){.n = n, .x_um = sc->x, .y_um = sc->y, .signal_dn = sc->s,
                            .pitch_um = 6, .spot_radius_um = R_SPOT, .bias_dn = BIAS,
                            .gain_e_per_dn = 3.153, .read_noise_e = 5.67, .frames = 12};
}

static void scene_free(scene_t *sc)
{
    free(sc->K);
    free(sc->x);
    free(sc->y);
    free(sc->s);
}

/* Blurs field S (nx*ny, row-major) by direct summation and stores the raster as scan points in
 * a fixed pseudo-random order (the grid may come in any order). */
static void scene_blur(scene_t *sc, const double *S)
{
    int nx = sc->nx, ny = sc->ny, N = nx * ny;
    int *perm = malloc(sizeof(int) * N);
    for (int k = 0; k < N; k++) perm[k] = k;
    srand(12345);
    for (int k = N - 1; k > 0; k--) {
        int r = rand() % (k + 1), t = perm[k];
        perm[k] = perm[r];
        perm[r] = t;
    }
    for (int m = 0; m < N; m++) {
        int mi = m % nx, mj = m / nx;
        double acc = 0;
        for (int lj = -(ny - 1); lj <= ny - 1; lj++)
            for (int li = -(nx - 1); li <= nx - 1; li++)
                acc += S[mirror(mj + lj, ny) * nx + mirror(mi + li, nx)] *
                       sc->K[abs(lj) * nx + abs(li)];
        int k = perm[m];
        sc->x[k] = sc->x0 + mi * sc->sx;
        sc->y[k] = sc->y0 + mj * sc->sy;
        sc->s[k] = BIAS + SCALE * acc;
    }
    free(perm);
}

/* Runs the filter; a failure is a failed check (with the message) and returns 0. */
static int run_ok(const fit_scan_t *s, double nsr, fit_wiener_t *w)
{
    err_t err = {{0}};
    int rc = fit_wiener_run(s, nsr, w, &err);
    if (rc) fprintf(stderr, "fit_wiener_run: %d %s\n", rc, err.msg);
    CHECK(rc == 0);
    return rc == 0;
}

static double mean_of(const double *v, int n)
{
    double m = 0;
    for (int k = 0; k < n; k++) m += v[k];
    return m / n;
}

/* (a) a known field is recovered with a tiny nsr; both kernel paths (square and oblong cells) */
static void test_known_field(int nx, int ny, double sx, double sy)
{
    scene_t sc;
    scene_init(&sc, nx, ny, sx, sy);
    int N = nx * ny;
    double *S = malloc(sizeof(double) * N);
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++)
            S[j * nx + i] = 1 + 0.4 * sin(1.3 * i + 0.7 * j) + 0.2 * cos(2.1 * i * j) +
                            (i == 0 || j == ny - 1 ? -0.3 : 0); /* edge dips, as in a pixel */
    scene_blur(&sc, S);
    fit_wiener_t w;
    if (!run_ok(&sc.scan, 1e-14, &w)) goto out;
    CHECK(w.nx == nx && w.ny == ny);
    CHECK_NEAR(w.step_x_um, sx, 1e-12, 0);
    CHECK_NEAR(w.step_y_um, sy, 1e-12, 0);
    CHECK_NEAR(w.x0_um, sc.x0, 1e-12, 0);
    CHECK_NEAR(w.y0_um, sc.y0, 1e-12, 0);
    CHECK(w.nsr == 1e-14);
    double m = mean_of(S, N);
    for (int k = 0; k < N; k++) CHECK_NEAR(w.S[k], S[k] / m, 0, 1e-6);
    fit_wiener_free(&w);
out:
    free(S);
    scene_free(&sc);
}

/* (b) a delta comes back as a delta on the same grid point (no shift, no transposition) */
static void test_delta(int di, int dj)
{
    scene_t sc;
    int nx = 9, ny = 7, N = nx * ny;
    scene_init(&sc, nx, ny, 0.6, 0.6);
    double S[63] = {0};
    S[dj * nx + di] = 1;
    scene_blur(&sc, S);
    fit_wiener_t w;
    if (!run_ok(&sc.scan, 1e-14, &w)) goto out;
    int best = 0;
    for (int k = 1; k < N; k++)
        if (w.S[k] > w.S[best]) best = k;
    CHECK(best == dj * nx + di);
    for (int k = 0; k < N; k++) CHECK_NEAR(w.S[k], k == dj * nx + di ? N : 0, 0, 1e-5);
    fit_wiener_free(&w);
out:
    scene_free(&sc);
}

/* (c) uniform data: uniform 1 everywhere; nsr <= 0 picks mean sigma^2 / mean d^2 with the
 * paper's sigma^2 = ((I - B) + (R/G)^2) / frames (eq. 5 and the 1/sqrt(12) of eq. 4) */
static void test_uniform(void)
{
    scene_t sc;
    scene_init(&sc, 8, 6, 0.5, 0.5);
    double S[48];
    for (int k = 0; k < 48; k++) S[k] = 1;
    scene_blur(&sc, S);
    fit_wiener_t w;
    if (!run_ok(&sc.scan, 0, &w)) goto out;
    double rg = 5.67 / 3.153;
    CHECK_NEAR(w.nsr, (SCALE + rg * rg) / 12 / (SCALE * SCALE), 1e-12, 0);
    for (int k = 0; k < 48; k++) CHECK_NEAR(w.S[k], 1, 0, 1e-12);
    fit_wiener_free(&w);
out:
    scene_free(&sc);
}

/* Standard normal deviates from a fixed 64-bit LCG (Knuth's MMIX constants) by Box-Muller:
 * deterministic, independent of the C library. */
static double gauss(unsigned long long *st)
{
    double u[2];
    for (int i = 0; i < 2; i++) {
        *st = *st * 6364136223846793005ULL + 1442695040888963407ULL;
        u[i] = ((double)(*st >> 11) + 0.5) / 9007199254740992.0; /* (0, 1) */
    }
    return sqrt(-2 * log(u[0])) * cos(2 * M_PI * u[1]);
}

/* (c2) a flat field with the paper's noise: the map must be flat within the data's own noise.
 * sigma of a point is eq. 5 with eq. 4's frames, computed here: sigma^2 = ((I - B) + (R/G)^2) /
 * frames DN^2, relative to the signal SCALE. A filter whose noise gain is at most 1 keeps every
 * node within 3 sigma_rel of 1 (and the spectral choice, which passes only the frequencies next
 * to the DC for flat data, far inside); the white choice (one nsr = mean sigma^2 / mean d^2 ~
 * 1e-5) restores nearly every frequency at a gain up to 1/|K| and breaks the bound: printed
 * beside, for the record. Rasters of the fidelity bench: 9 x 9 at 0.6 um, 13 x 13 at 0.42, 19 x
 * 19 at 0.3, 31 x 31 at 0.6 um; several noise seeds each. */
static void test_flat_noise(int n, double step)
{
    scene_t sc;
    scene_init(&sc, n, n, step, step);
    int N = n * n;
    double *S = malloc(sizeof(double) * N);
    for (int k = 0; k < N; k++) S[k] = 1;
    scene_blur(&sc, S);
    double rg = 5.67 / 3.153, sigma = sqrt((SCALE + rg * rg) / 12), rel = sigma / SCALE;
    double worst = 0, worst_white = 0;
    for (unsigned long long seed = 1; seed <= 4; seed++) {
        unsigned long long st = seed * 0x9E3779B97F4A7C15ULL;
        for (int k = 0; k < N; k++) sc.s[k] = BIAS + SCALE + sigma * gauss(&st);
        fit_wiener_t w, ww;
        err_t err = {{0}};
        fit_wiener_opts_t o = {.method = FIT_WIENER_NSR_SPECTRAL, .crop = 0};
        int rc = fit_wiener_run_opts(&sc.scan, &o, &w, &err);
        if (rc) fprintf(stderr, "fit_wiener_run_opts: %s\n", err.msg);
        CHECK(rc == 0);
        if (rc) break;
        CHECK(w.nsr_method == FIT_WIENER_NSR_SPECTRAL && w.nx == n && w.ny == n);
        double dev = 0;
        for (int k = 0; k < N; k++) dev = fmax(dev, fabs(w.S[k] - 1));
        CHECK(dev <= 3 * rel);
        worst = fmax(worst, dev);
        if (run_ok(&sc.scan, 0, &ww)) {
            for (int k = 0; k < N; k++) worst_white = fmax(worst_white, fabs(ww.S[k] - 1));
            fit_wiener_free(&ww);
        }
        fit_wiener_free(&w);
    }
    printf("flat %2d x %2d @ %.2f um: max |S - 1| spectral %.4f, white %.4f; 3 sigma_rel %.4f\n",
           n, n, step, worst, worst_white, 3 * rel);
    free(S);
    scene_free(&sc);
}

/* (c3) the whole raster cropped to the pixel: a grid from -3 to 9 um over a 6 um pixel keeps the
 * nodes strictly inside (0, 6) um, mean 1 over them; a grid with no node inside is refused. */
static void test_crop(void)
{
    scene_t sc;
    scene_init(&sc, 21, 21, 0.6, 0.6);
    sc.x0 = sc.y0 = -3.0;
    double S[441];
    for (int j = 0; j < 21; j++)
        for (int i = 0; i < 21; i++) S[j * 21 + i] = 1 + 0.3 * (i > 10); /* right half brighter */
    scene_blur(&sc, S);
    fit_wiener_t w;
    err_t err = {{0}};
    fit_wiener_opts_t o = {.method = FIT_WIENER_NSR_FIXED, .nsr = 1e-14, .crop = 1};
    int rc = fit_wiener_run_opts(&sc.scan, &o, &w, &err);
    CHECK(rc == 0);
    if (rc == 0) {
        /* nodes at -3 + 0.6 i: inside (0, 6) for i = 6..14 (0.6 .. 5.4 um) */
        CHECK(w.cropped && w.raster_nx == 21 && w.raster_ny == 21);
        CHECK(w.nx == 9 && w.ny == 9);
        CHECK_NEAR(w.x0_um, 0.6, 0, 1e-9);
        CHECK_NEAR(w.y0_um, 0.6, 0, 1e-9);
        /* the crop holds columns 6..14 of S: 5 at 1 (i <= 10), 4 at 1.3; mean 1 + 1.2 / 9 */
        double m = 1 + 0.3 * 4 / 9.0;
        for (int j = 0; j < 9; j++)
            for (int i = 0; i < 9; i++)
                CHECK_NEAR(w.S[j * 9 + i], (i + 6 > 10 ? 1.3 : 1) / m, 0, 1e-6);
        fit_wiener_free(&w);
    }
    sc.x0 = 7.0; /* every node beyond the pixel */
    scene_blur(&sc, S);
    rc = fit_wiener_run_opts(&sc.scan, &o, &w, &err);
    CHECK(rc == -EINVAL && strstr(err.msg, "inside the pixel"));
    scene_free(&sc);
}

/* The Wiener gain at one frequency. S = 1 + eps cos(pi k (i + 1/2) / nx) is mirror-symmetric,
 * so the blur maps it to 1 + eps L cos(..) with L = sum_l K(l) cos(pi k l_x / nx) (K even, unit
 * sum). The filter multiplies by L / (L^2 + nsr) and the mean by 1 / (1 + nsr), so after
 * normalising to mean 1: S = 1 + eps (1 + nsr) L^2 / (L^2 + nsr) cos(..). With nsr = L^2 / 4 the
 * cosine must come back at 0.8 (1 + nsr) of its amplitude: nsr is a power ratio of |K|^2 with
 * K(0) = 1. The data are made from the formula, the gain L by direct summation. */
static void test_nsr_units(void)
{
    scene_t sc;
    int nx = 10, ny = 6, kf = 3;
    scene_init(&sc, nx, ny, 0.6, 0.6);
    double L = 0, eps = 0.3;
    for (int lj = -(ny - 1); lj <= ny - 1; lj++)
        for (int li = -(nx - 1); li <= nx - 1; li++)
            L += sc.K[abs(lj) * nx + abs(li)] * cos(M_PI * kf * li / nx);
    CHECK(L > 0.05 && L < 0.95); /* a frequency the blur attenuates but keeps */
    double S[60];
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) S[j * nx + i] = 1 + eps * cos(M_PI * kf * (i + 0.5) / nx);
    scene_blur(&sc, S);
    double nsr = L * L / 4;
    fit_wiener_t w;
    if (!run_ok(&sc.scan, nsr, &w)) goto out;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++)
            CHECK_NEAR(w.S[j * nx + i],
                       1 + eps * 0.8 * (1 + nsr) * cos(M_PI * kf * (i + 0.5) / nx), 0, 1e-9);
    fit_wiener_free(&w);
out:
    scene_free(&sc);
}

/* Runs the scan expecting -EINVAL with a message containing what. */
static void expect_einval(const fit_scan_t *s, const char *what)
{
    fit_wiener_t w;
    err_t err = {{0}};
    int rc = fit_wiener_run(s, 0, &w, &err);
    CHECK(rc == -EINVAL);
    CHECK(w.S == NULL);
    if (!strstr(err.msg, what)) {
        fprintf(stderr, "message \"%s\" does not mention \"%s\"\n", err.msg, what);
        CHECK(0);
    }
}

/* (d) malformed grids and values */
static void test_bad_grids(void)
{
    scene_t sc;
    scene_init(&sc, 5, 4, 0.6, 0.6);
    double S[20];
    for (int k = 0; k < 20; k++) S[k] = 1;
    scene_blur(&sc, S);
    fit_scan_t s = sc.scan;
    double keep = sc.x[7];
    sc.x[7] += 0.1 * 0.6; /* off its node by a tenth of a step */
    expect_einval(&s, "not on a regular grid");
    sc.x[7] = keep + 1e-9 * 0.6; /* within the 1e-6 step tolerance: accepted */
    fit_wiener_t w;
    if (run_ok(&s, 0, &w)) fit_wiener_free(&w);
    sc.x[7] = keep;
    s.n = 19; /* a missing point */
    expect_einval(&s, "incomplete");
    s.n = 20;
    double y7 = sc.y[7];
    sc.x[7] = sc.x[8]; /* two points on one node, so another node is empty */
    sc.y[7] = sc.y[8];
    expect_einval(&s, "both at grid node");
    sc.x[7] = keep;
    sc.y[7] = y7;
    sc.s[3] = NAN;
    expect_einval(&s, "non-finite signal");
    sc.s[3] = BIAS;
    double y2 = sc.y[2];
    sc.y[2] = INFINITY;
    expect_einval(&s, "non-finite y");
    sc.y[2] = y2;
    double row_y[5] = {1, 1, 1, 1, 1}, row_x[5] = {0, 1, 2, 3, 4};
    fit_scan_t row = s;
    row.n = 5;
    row.x_um = row_x;
    row.y_um = row_y;
    expect_einval(&row, "same y"); /* a single row */
    row.x_um = row_y;
    row.y_um = row_x;
    expect_einval(&row, "same x"); /* a single column */
    double ux[6] = {0, 1, 3, 0, 1, 3}, uy[6] = {0, 0, 0, 1, 1, 1};
    fit_scan_t uneven = row;
    uneven.n = 6;
    uneven.x_um = ux;
    uneven.y_um = uy;
    expect_einval(&uneven, "not on a regular grid"); /* columns at 0, 1, 3 */
    double dg[5] = {0, 1, 2, 3, 4};
    fit_scan_t diagonal = row;
    diagonal.x_um = dg;
    diagonal.y_um = dg;
    expect_einval(&diagonal, "incomplete"); /* 5 points spanning a 5 x 5 grid */
    fit_scan_t small = s;
    small.n = 3;
    expect_einval(&small, "at least 2 x 2");
    fit_scan_t nospot = s;
    nospot.spot_radius_um = 0;
    expect_einval(&nospot, "spot radius");
    CHECK(fit_wiener_run(NULL, 0, &w, NULL) == -EINVAL);
    CHECK(fit_wiener_run(&s, 0, NULL, NULL) == -EINVAL);
    CHECK(fit_wiener_run(&s, NAN, &w, NULL) == -EINVAL);
    scene_free(&sc);
}

/* (e) the reference scan: the scene has fill-factor dips at the top, left and bottom edges and
 * none at the right (paper, "Results"); the raster also loses flux at every edge because the spot
 * there overhangs the pixel, so the right edge sits below the centre too, but above the left. */
static void test_reference_scan(void)
{
    ref_scan_t rs;
    if (ref_scan_load("paperlike_scan.json", &rs)) {
        CHECK(0);
        return;
    }
    fit_wiener_t w;
    if (!run_ok(&rs.scan, 0, &w)) goto out;
    CHECK(w.nx == 9 && w.ny == 9);
    CHECK_NEAR(w.step_x_um, 0.6, 1e-12, 0);
    CHECK_NEAR(w.y0_um, 0.6, 1e-12, 0);
    /* nsr = mean sigma^2 / mean (I - B)^2 from the file's own constants */
    const fit_scan_t *s = &rs.scan;
    double rg = s->read_noise_e / s->gain_e_per_dn, ns = 0, ss = 0;
    for (size_t k = 0; k < s->n; k++) {
        double d = s->signal_dn[k] - s->bias_dn;
        ns += ((d > 0 ? d : 0) + rg * rg) / s->frames;
        ss += d * d;
    }
    CHECK_NEAR(w.nsr, ns / ss, 1e-12, 0);
    CHECK_NEAR(mean_of(w.S, 81), 1, 1e-12, 0);
    double left = 0, right = 0, top = 0, bottom = 0, centre = 0;
    for (int k = 0; k < 9; k++) {
        left += w.S[k * 9] / 9;
        right += w.S[k * 9 + 8] / 9;
        top += w.S[k] / 9;
        bottom += w.S[72 + k] / 9;
    }
    for (int j = 3; j < 6; j++)
        for (int i = 3; i < 6; i++) centre += w.S[j * 9 + i] / 9;
    CHECK(left < 0.85 * centre && top < 0.85 * centre && bottom < 0.85 * centre);
    CHECK(left < right && top < right && bottom < right);
    CHECK(right < centre);
    /* any order of the points gives the same map: reverse the file's order */
    size_t n = s->n;
    double *rev = malloc(sizeof(double) * 3 * n);
    for (size_t k = 0; k < n; k++) {
        rev[k] = s->x_um[n - 1 - k];
        rev[n + k] = s->y_um[n - 1 - k];
        rev[2 * n + k] = s->signal_dn[n - 1 - k];
    }
    fit_scan_t r = *s;
    r.x_um = rev;
    r.y_um = rev + n;
    r.signal_dn = rev + 2 * n;
    fit_wiener_t w2;
    if (run_ok(&r, 0, &w2)) {
        for (int k = 0; k < 81; k++) CHECK_NEAR(w2.S[k], w.S[k], 0, 1e-14);
        fit_wiener_free(&w2);
    }
    free(rev);
    fit_wiener_free(&w);
    fit_wiener_free(NULL);
out:
    ref_scan_free(&rs);
}

int main(void)
{
    test_known_field(9, 7, 0.6, 0.6); /* square cells: kernel from the design matrix */
    test_known_field(7, 6, 0.5, 0.7); /* oblong cells: kernel from box integrals */
    test_delta(3, 2);
    test_delta(0, 6); /* a corner: the mirrored boundary */
    test_uniform();
    test_flat_noise(9, 0.6);
    test_flat_noise(13, 0.42);
    test_flat_noise(19, 0.3);
    test_flat_noise(31, 0.6);
    test_crop();
    test_nsr_units();
    test_bad_grids();
    test_reference_scan();
    CHECK_DONE();
}
