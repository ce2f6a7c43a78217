/* test_shrink.c: the shrunk map (fit/shrink.h) against analytic cases: the area overlaps of two
 * grids, the projection of a coarse map onto a finer grid, the positive-part James-Stein factor
 * and its limits (no noise: the fine map; no detail or all noise: the coarse map), the noise
 * scale, the S_err bound, and in a sweep: present for the recommended r, absent at r = 1. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "check.h"
#include "fit/shrink.h"

static fit_result_t map_of(int r, double *S, double *E)
{
    fit_result_t f;
    memset(&f, 0, sizeof f);
    f.r = r, f.S = S, f.S_err = E;
    return f;
}

static void overlaps(void)
{
    double w[12 * 12];
    for (int r = 2; r <= 12; r++)
        for (int q = 1; q < r; q++) {
            fit_grid_overlap(r, q, w);
            for (int a = 0; a < r; a++) { /* each fine cell is covered once */
                double s = 0;
                for (int b = 0; b < q; b++) s += w[a * q + b];
                CHECK_NEAR(s, 1, 1e-12, 0);
            }
            for (int b = 0; b < q; b++) { /* each coarse cell's width, r/q fine cells */
                double s = 0;
                for (int a = 0; a < r; a++) s += w[a * q + b];
                CHECK_NEAR(s, (double)r / q, 1e-12, 0);
            }
        }
    fit_grid_overlap(3, 2, w); /* [0,1/3) in [0,1/2); [1/3,2/3) half in each; [2/3,1) in [1/2,1) */
    CHECK(w[0] == 1 && w[1] == 0 && w[4] == 0 && w[5] == 1);
    CHECK_NEAR(w[2], 0.5, 1e-12, 0);
    CHECK_NEAR(w[3], 0.5, 1e-12, 0);
}

/* A 2 x 2 coarse map onto 3 x 3: corners keep their cell, edge middles average two cells, the
 * centre all four. A fine map equal to that projection has no detail, so with any noise the
 * factor is 0; a detail without noise is kept whole. */
static void projection(void)
{
    double Sc[4] = {1, 2, 3, 4}, Ec[4] = {0.1, 0.2, 0.3, 0.4};
    double Sf[9] = {1, 1.5, 2, 2, 2.5, 3, 3, 3.5, 4}, Ef[9];
    for (int j = 0; j < 9; j++) Ef[j] = 0.01;
    fit_result_t c = map_of(2, Sc, Ec), f = map_of(3, Sf, Ef);
    fit_shrunk_t s;
    err_t err;
    /* the fine map equals the projection: no detail, so the coarse map on the fine grid */
    CHECK(fit_shrink(&f, &c, 1, &s, &err) == 0);
    CHECK(s.r == 3 && s.toward_r == 2 && s.factor == 0);
    for (int j = 0; j < 9; j++) CHECK_NEAR(s.S[j], Sf[j], 1e-12, 1e-15);
    /* S_err with factor 0: the coarse S_err averaged over each fine cell (a bound) */
    CHECK_NEAR(s.S_err[0], 0.1, 1e-12, 0);
    CHECK_NEAR(s.S_err[1], 0.15, 1e-12, 0);
    CHECK_NEAR(s.S_err[4], 0.25, 1e-12, 0);
    CHECK_NEAR(s.S_err[8], 0.4, 1e-12, 0);
    CHECK_NEAR(s.detail, 0, 0, 1e-15);
    fit_shrunk_free(&s);
    /* a detail with no noise: kept as it is */
    Sf[4] = 3.5;
    memset(Ef, 0, sizeof Ef);
    CHECK(fit_shrink(&f, &c, 1, &s, &err) == 0);
    CHECK(s.factor == 1);
    for (int j = 0; j < 9; j++) CHECK_NEAR(s.S[j], Sf[j], 1e-12, 1e-15);
    CHECK_NEAR(s.detail, 1.0 / 3, 1e-12, 0); /* one cell off by 1: sqrt(1 / 9) */
    fit_shrunk_free(&s);
}

/* A checkerboard of amplitude a on a flat coarse map: D = +-a in each of d = 4 cells, so
 * c = 1 - (d - 2) sigma^2 / (d a^2) = 1 - sigma^2 / (2 a^2). */
static void factor(void)
{
    double one = 1, zero = 0, a = 0.1;
    double Sf[4] = {1 + a, 1 - a, 1 - a, 1 + a}, Ef[4];
    fit_result_t c = map_of(1, &one, &zero), f = map_of(2, Sf, Ef);
    fit_shrunk_t s;
    err_t err;
    static const struct {
        double sigma, scale, c;
    } cases[] = {
        {0.1, 1, 0.5},      /* 1 - 0.01 / 0.02 */
        {0.05, 1, 0.875},   /* 1 - 0.0025 / 0.02 */
        {0.05, 2, 0.5},     /* the scatter doubles sigma */
        {0.2, 1, 0},        /* 1 - 0.04 / 0.02 < 0: the positive part */
        {0, 1, 1},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        for (int j = 0; j < 4; j++) Ef[j] = cases[k].sigma;
        CHECK(fit_shrink(&f, &c, cases[k].scale, &s, &err) == 0);
        CHECK_NEAR(s.factor, cases[k].c, 1e-12, 1e-15);
        CHECK_NEAR(s.S[0], 1 + cases[k].c * a, 1e-12, 0);
        CHECK_NEAR(s.S[1], 1 - cases[k].c * a, 1e-12, 0);
        /* the mean stays 1: the projection keeps the coarse map's mean, the detail's is 0 */
        CHECK_NEAR((s.S[0] + s.S[1] + s.S[2] + s.S[3]) / 4, 1, 1e-12, 0);
        CHECK_NEAR(s.S_err[0], cases[k].c * cases[k].sigma, 1e-12, 1e-15); /* coarse: 0 */
        CHECK_NEAR(s.noise, cases[k].sigma * cases[k].scale, 1e-12, 1e-15);
        fit_shrunk_free(&s);
    }
    /* refused: no coarser map, r = 1, a missing map */
    CHECK(fit_shrink(&c, &f, 1, &s, &err) == -EINVAL && s.S == NULL);
    CHECK(fit_shrink(&f, &f, 1, &s, &err) == -EINVAL);
    fit_result_t none = map_of(1, NULL, NULL);
    CHECK(fit_shrink(&f, &none, 1, &s, &err) == -EINVAL);
}

/* In a sweep: the recommended r's map toward r - 1; none when the recommendation is r = 1 or
 * r - 1 is outside the sweep. */
static void in_sweep(void)
{
    double one = 1, zero = 0, S2[4] = {0.9, 1.1, 1.1, 0.9}, E2[4] = {0.01, 0.01, 0.01, 0.01};
    fit_result_t f[2] = {map_of(1, &one, &zero), map_of(2, S2, E2)};
    fit_sweep_t sw = {.r_min = 1, .r_max = 2, .fits = f, .recommended_r = 2};
    fit_shrunk_t s;
    err_t err;
    CHECK(fit_shrink_recommended(&sw, 1, &s, &err) == 0);
    CHECK(s.r == 2 && s.toward_r == 1);
    CHECK_NEAR(s.factor, 1 - 2 * 1e-4 / (4 * 0.01), 1e-12, 0); /* d = 4, sigma 0.01, D = 0.1 */
    fit_shrunk_free(&s);
    sw.recommended_r = 1;
    CHECK(fit_shrink_recommended(&sw, 1, &s, &err) == 0 && s.r == 0 && s.S == NULL);
    sw = (fit_sweep_t){.r_min = 2, .r_max = 2, .fits = f + 1, .recommended_r = 2};
    CHECK(fit_shrink_recommended(&sw, 1, &s, &err) == 0 && s.r == 0);
}

int main(void)
{
    overlaps();
    projection();
    factor();
    in_sweep();
    CHECK_DONE();
}
