/* test_interp.c: fit_interp_bicubic (interp.h) against analytic truths: maps sampled from a
 * linear or bilinear function of the sub-pixel centres are reproduced exactly where the
 * interpolant's family contains that function, the sub-pixel centres return the map itself,
 * points beyond the outermost centres take the value at the clamped position, bilinear results
 * stay within the map's range, a constant stays constant, a profile along one axis is the natural
 * cubic spline through it (values worked by hand), and bad arguments are refused. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/interp.h"

/* The position (in pitch units) where output point k of n is evaluated: its centre, moved onto
 * the outermost sub-pixel centres of an r x r map when outside them (interp.h's contract). */
static double expected_pos(int k, int n, int r)
{
    double p = (k + 0.5) / n, c0 = 0.5 / r, c1 = (r - 0.5) / r;
    return p < c0 ? c0 : p > c1 ? c1 : p;
}

static double linear_f(double x, double y) { return 0.75 + 2.5 * x - 1.25 * y; }
static double bilinear_f(double x, double y) { return -0.5 + 1.5 * x + 0.25 * y + 3.0 * x * y; }

/* Samples f at the r x r sub-pixel centres, interpolates to n x n and compares with f at the
 * expected positions; returns the largest error. */
static double max_error(double (*f)(double, double), int r, int n)
{
    double *map = malloc(sizeof(double) * r * r), *out = malloc(sizeof(double) * n * n), e = 0;
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) map[j * r + i] = f((i + 0.5) / r, (j + 0.5) / r);
    err_t err;
    CHECK(fit_interp_bicubic(map, r, n, out, &err) == 0);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double d = fabs(out[j * n + i] - f(expected_pos(i, n, r), expected_pos(j, n, r)));
            if (d > e) e = d;
        }
    free(map);
    free(out);
    return e;
}

static void test_exact_families(void)
{
    const int ns[] = {1, 2, 5, 13, 40};
    for (int k = 0; k < 5; k++) {
        int n = ns[k];
        /* bilinear interpolation (r = 2, 3) contains every bilinear function */
        for (int r = 2; r <= 3; r++) {
            CHECK_NEAR(max_error(bilinear_f, r, n), 0, 0, 1e-12);
            CHECK_NEAR(max_error(linear_f, r, n), 0, 0, 1e-12);
        }
        /* GSL's bicubic estimates derivatives by splines, exact for a linear function (and,
         * since zx and zxy come from splines of linear data too, for a bilinear one) */
        for (int r = 4; r <= 9; r++) {
            CHECK_NEAR(max_error(linear_f, r, n), 0, 0, 1e-12);
            CHECK_NEAR(max_error(bilinear_f, r, n), 0, 0, 1e-12);
        }
    }
    /* a quadratic is not in the bilinear family: the check above can fail (sanity of the test) */
    double e = 0;
    {
        double map[9], out[49];
        for (int j = 0; j < 3; j++)
            for (int i = 0; i < 3; i++) map[j * 3 + i] = ((i + 0.5) / 3) * ((i + 0.5) / 3);
        CHECK(fit_interp_bicubic(map, 3, 7, out, NULL) == 0);
        double p = expected_pos(1, 7, 3); /* between centres: chord above the parabola */
        e = out[1] - p * p;
    }
    CHECK(e > 1e-3);
}

/* r >= 4 is really cubic: on f = x^2 the output at the quarter points between interior centres
 * (n = 2r) is far closer than any bilinear interpolant, whose error there is 3 h^2 / 16. */
static void test_cubic_order(void)
{
    for (int r = 4; r <= 8; r++) {
        int n = 2 * r;
        double map[64], out[256], h = 1.0 / r, worst = 0;
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) map[j * r + i] = ((i + 0.5) / r) * ((i + 0.5) / r);
        CHECK(fit_interp_bicubic(map, r, n, out, NULL) == 0);
        for (int i = 0; i < n; i++) {
            double p = (i + 0.5) / n;
            if (p > 1.5 * h && p < 1 - 1.5 * h) /* away from the spline's end conditions */
                worst = fmax(worst, fabs(out[n + i] - p * p));
        }
        CHECK(worst < 0.3 * 3 * h * h / 16);
    }
}

/* n == r: the output points are the sub-pixel centres, where every interpolant equals the map. */
static void test_identity_at_centres(void)
{
    srand(7);
    for (int r = 1; r <= 9; r++) {
        double map[81], out[81];
        for (int k = 0; k < r * r; k++) map[k] = 0.5 + (double)rand() / RAND_MAX;
        CHECK(fit_interp_bicubic(map, r, r, out, NULL) == 0);
        for (int k = 0; k < r * r; k++) CHECK_NEAR(out[k], map[k], 1e-14, 0);
    }
}

static void test_constant_and_range(void)
{
    for (int r = 1; r <= 8; r++) {
        double map[64], out[31 * 31], mean = 0;
        for (int k = 0; k < r * r; k++) map[k] = 1.375;
        CHECK(fit_interp_bicubic(map, r, 31, out, NULL) == 0);
        for (int k = 0; k < 31 * 31; k++) mean += out[k];
        CHECK_NEAR(mean / (31 * 31), 1.375, 1e-14, 0);
        for (int k = 0; k < 31 * 31; k++) CHECK_NEAR(out[k], 1.375, 1e-14, 0);
    }
    /* bilinear values are convex combinations of the map's values */
    srand(11);
    double map[9], out[400], lo = 1e300, hi = -1e300;
    for (int k = 0; k < 9; k++) {
        map[k] = (double)rand() / RAND_MAX;
        lo = fmin(lo, map[k]);
        hi = fmax(hi, map[k]);
    }
    CHECK(fit_interp_bicubic(map, 3, 20, out, NULL) == 0);
    for (int k = 0; k < 400; k++) CHECK(out[k] >= lo - 1e-15 && out[k] <= hi + 1e-15);
    /* r = 1: the single value everywhere */
    double one = 0.8125, o4[16];
    CHECK(fit_interp_bicubic(&one, 1, 4, o4, NULL) == 0);
    for (int k = 0; k < 16; k++) CHECK(o4[k] == one);
}

/* A map that varies along one axis only is interpolated along it by the natural cubic spline
 * through its values (GSL's bicubic takes its x-derivatives from natural splines, and zy = zxy =
 * 0 here, so each patch is the spline's cubic). Worked by hand for r = 4 (knots h = 1/4 apart)
 * and values (0, 1, 0, 0): the second derivatives M0 = M3 = 0 and
 *   M0 + 4 M1 + M2 = 6/h^2 (y0 - 2 y1 + y2) = -192,  M1 + 4 M2 + M3 = 6/h^2 (y1 - 2 y2 + y3) = 96
 * give M1 = -57.6, M2 = 38.4; at the middle of a knot interval the spline is
 *   (y_i + y_i+1) / 2 - h^2/16 (M_i + M_i+1):  0.725, 0.575, -0.15
 * at x = 1/4, 1/2, 3/4 (the output points of n = 2 and n = 1). Checked along x and along y. */
static void test_natural_spline_profile(void)
{
    const double prof[4] = {0, 1, 0, 0};
    double along_x[16], along_y[16], out[4], one;
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
            along_x[j * 4 + i] = prof[i];
            along_y[j * 4 + i] = prof[j];
        }
    CHECK(fit_interp_bicubic(along_x, 4, 2, out, NULL) == 0);
    for (int j = 0; j < 2; j++) { /* every row the same: x is the column */
        CHECK_NEAR(out[j * 2 + 0], 0.725, 1e-13, 0);
        CHECK_NEAR(out[j * 2 + 1], -0.15, 1e-13, 0);
    }
    CHECK(fit_interp_bicubic(along_x, 4, 1, &one, NULL) == 0);
    CHECK_NEAR(one, 0.575, 1e-13, 0);
    CHECK(fit_interp_bicubic(along_y, 4, 2, out, NULL) == 0);
    for (int i = 0; i < 2; i++) { /* every column the same: y is the row */
        CHECK_NEAR(out[0 * 2 + i], 0.725, 1e-13, 0);
        CHECK_NEAR(out[1 * 2 + i], -0.15, 1e-13, 0);
    }
}

/* Outside the outermost sub-pixel centres the map is constant along the outward direction: with
 * n = 4r the first two points of an axis (at 1/(8r) and 3/(8r)) lie before the first centre
 * 1/(2r), so the 2 x 2 corner block is S[0] and the first two rows equal each other. */
static void test_constant_extension(void)
{
    srand(5);
    for (int r = 2; r <= 8; r++) {
        int n = 4 * r;
        double map[64], out[32 * 32];
        for (int k = 0; k < r * r; k++) map[k] = 0.5 + (double)rand() / RAND_MAX;
        CHECK(fit_interp_bicubic(map, r, n, out, NULL) == 0);
        for (int k = 0; k < 4; k++) CHECK_NEAR(out[(k / 2) * n + k % 2], map[0], 1e-14, 0);
        for (int i = 0; i < n; i++) {
            CHECK(out[i] == out[n + i]);                     /* rows 0, 1: y clamped */
            CHECK(out[i * n] == out[i * n + 1]);             /* columns 0, 1: x clamped */
            CHECK(out[(n - 1) * n + i] == out[(n - 2) * n + i]); /* the far edges too */
            CHECK(out[i * n + n - 1] == out[i * n + n - 2]);
        }
    }
}

static void test_bad_arguments(void)
{
    double map[16] = {0}, out[16];
    err_t err;
    CHECK(fit_interp_bicubic(map, 0, 4, out, &err) == -EINVAL);
    CHECK(strstr(err.msg, "r must be >= 1") != NULL);
    CHECK(fit_interp_bicubic(map, -3, 4, out, &err) == -EINVAL);
    CHECK(fit_interp_bicubic(map, 4, 0, out, &err) == -EINVAL);
    CHECK(strstr(err.msg, "n must be >= 1") != NULL);
    CHECK(fit_interp_bicubic(NULL, 4, 4, out, &err) == -EINVAL);
    CHECK(strstr(err.msg, "NULL") != NULL);
    CHECK(fit_interp_bicubic(map, 4, 4, NULL, NULL) == -EINVAL);
}

int main(void)
{
    test_exact_families();
    test_cubic_order();
    test_identity_at_centres();
    test_constant_and_range();
    test_natural_spline_profile();
    test_constant_extension();
    test_bad_arguments();
    CHECK_DONE();
}
