/* test_krige_prior.c: the kriged map's prior from the sweep (fit/krige.h,
 * fit_krige_prior_for_sweep; docs/numerics.md "The prior from the sweep"). The prior is the
 * recommended r's divisor grids on that r's fine grid; and on pixels whose structure lies on no
 * grid of the sweep (scene families ring, busline, diagedge, bowl, twodips; the simulator's map
 * is the truth, shot+read noise, r = 1..10 as the benchmark), the map the fit job stores is
 * within 1.1x of the rms error of the best r in hindsight (rms below 0.1 % counts as 0.1 %), two
 * small dips at a tenth of the light on the 9 x 9 raster included, and on the smooth ones (a bowl,
 * a ring, two dips at full light) below 0.8x of it: closer to the truth than any one grid. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "fit/krige.h"
#include "instrument/fidelity.h"

static void test_prior_grids(void)
{
    fit_sweep_t sw = {.r_min = 1, .r_max = 8, .recommended_r = 6};
    fit_krige_prior_t p = fit_krige_prior_for_sweep(&sw);
    CHECK(p.r == 6 && p.n_grids == 3 && p.grids[0] == 2 && p.grids[1] == 3 && p.grids[2] == 6);
    sw.recommended_r = 7;
    p = fit_krige_prior_for_sweep(&sw);
    CHECK(p.r == 7 && p.n_grids == 1 && p.grids[0] == 7);
    sw.recommended_r = 0; /* no recommendation: the flat prior */
    p = fit_krige_prior_for_sweep(&sw);
    CHECK(p.r == 1 && p.n_grids == 0);
    p = fit_krige_prior_for_sweep(NULL);
    CHECK(p.r == 1 && p.n_grids == 0);
}

static const struct {
    const char *scene;
    int grid;
    double step, flux;
    unsigned long seed;
    double bound; /* of the kriged map's rms over the best r's */
} cases[] = {
    {"twodips", 9, 0.6, 0.1, 202, 1.1}, /* the smooth part dropped: the 5 x 5 grid's map */
    {"twodips", 9, 0.6, 0.1, 200, 1.1},
    {"twodips", 9, 0.6, 1.0, 200, 0.8},
    {"ring", 9, 0.6, 1.0, 200, 0.8},
    {"bowl", 9, 0.6, 1.0, 200, 0.8},
    {"diagedge", 9, 0.6, 0.1, 200, 1.1},
    {"busline", 13, 0.42, 1.0, 200, 1.1},
};

int main(void)
{
    test_prior_grids();
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        fid_case_t c = {.scene = cases[i].scene, .grid = cases[i].grid, .step_um = cases[i].step,
                        .flux_scale = cases[i].flux, .seed = cases[i].seed,
                        .noise = FIT_NOISE_SHOT_READ, .krige = 1};
        fid_result_t f;
        err_t err;
        CHECK(fid_run(&c, 10, &f, &err) == 0);
        CHECK(f.r_best >= 1 && isfinite(f.rms_kriged));
        if (f.r_best < 1) continue;
        double best = fmax(f.rms[f.r_best], 1e-3), q = f.rms_kriged / best;
        fprintf(stderr, "%s %dx%d light %.1f seed %lu: kriged rms %.4f (F = %d, smooth %d), best "
                        "r = %d rms %.4f: %.3fx\n", c.scene, c.grid, c.grid, c.flux_scale, c.seed,
                f.rms_kriged, f.kriged_grid, f.kriged_smooth, f.r_best, f.rms[f.r_best], q);
        CHECK(q <= cases[i].bound);
    }
    CHECK_DONE();
}
