/* test_fidelity.c: the short form of the fidelity harness (instrument/fidelity.h): a few scenes
 * and rasters with fixed seeds, where the simulator's own map is the truth. On each, the
 * recommended map (fit/recommend.h) must be within 1.2x of the rms error of the best r in
 * hindsight (rms below 0.1 % counts as 0.1 %: a flat pixel's r = 1 map is exact), and never the
 * checkerboard that AIC and BIC pick on the denser rasters (its noise is below 0.1 of the mean,
 * and where BIC's map is over 2x the best error, the recommendation is another r). The shrunk
 * map (fit/shrink.h), where there is one, must be within 1.1x of the best r on each, and no
 * farther from the truth than the recommended map by more than 0.001; three more cases, misses
 * of the rule, check the shrunk map alone. And the error bars against the truth's sub-pixel means
 * over all cases: with the resolution error S_res (fit/shrink.h) added in quadrature to S_err,
 * the recommended map's z = (S - truth) / error has rms within [0.7, 1.4] and |z| <= 2 for at
 * least 85 % of the sub-pixels, 8 points more than with S_err alone (these are hard cases, most
 * of them misses of the rule: 77.7 % -> 90.6 %; over the benchmark's 1008 cases 87.5 % -> 95.4 %,
 * a Gaussian's 95.4 %). The kriged map (fit/krige.h) must be within 1.1x of the best r on every
 * case, the rule's misses included, and on the graded scenes closer to the truth than the shrunk
 * map; the one r nearest it (the Bayes pick of one grid) is r = 1 on the flat pixel and r = 3 on
 * the dead corners, the grids that hold those truths exactly. Where the kriged map drops its
 * smooth part (a dip), its S_err still covers the truth (rms z <= 1.1, 92 % within 2 sigma).
 * The full table is a benchmark (build/bench/ipsd-bench-fidelity, docs/studies/maps.md). */
#include <math.h>
#include <string.h>

#include "check.h"
#include "instrument/fidelity.h"

static const struct {
    const char *scene;
    int grid;
    double step;
    unsigned long seed; /* 0: seed 1 under the paper's noise model; else this seed, shot+read */
    double flux;        /* photon level relative to the bench's default */
    int shrunk_only;    /* a miss of the rule: only the shrunk map is checked */
} cases[] = {
    {"paperlike", 9, 0.6, 0, 1, 0},   /* the paper's raster: AIC and BIC pick r = 8 here */
    {"paperlike", 13, 0.42, 0, 1, 0}, /* a finer raster: BIC picks the r = 9 checkerboard */
    {"uniform", 9, 0.6, 0, 1, 0},     {"deadcorner", 9, 0.6, 0, 1, 0}, {"edge", 19, 0.3, 0, 1, 0},
    {"dip", 13, 0.42, 0, 1, 0},
    {"gradient", 9, 0.6, 0, 1, 0},    /* smooth: the leave-one-out pick alone stops one r short */
    {"paperlike", 19, 0.3, 9, 1, 0},  /* r = 9 once passed step 4 here (noise 11x r = 8's): 5.3x */
    /* a held-out miss of the 1.1x target at a tenth of the light: one r short (r = 5 against
     * r = 6, 1.12x), the two expected errors 7 % apart; kept within 1.2x */
    {"gradient", 13, 0.42, 9, 0.1, 0},
    /* r_cv = 8 and r = 7 both misfit the points (reduced chi2 2.84, 3.08, scatter 1.03): r = 7
     * is the better map (0.036 against 0.057), once vetoed as misfitting: 1.58x */
    {"edge", 19, 0.3, 10, 1, 0},
    /* a dead corner r = 3 represents exactly (rms 0.001): r_cv = 6, the same map with five times
     * the noise (4.8x), predicts left-out points within one standard error of r = 3, which the
     * one-standard-error rule of step 2 then picks (its reduced chi2 0.822 within 1.5 x the
     * scatter^2 0.550) */
    {"deadcorner", 9, 0.6, 13, 1, 0},
    /* the same on the procedure's raster (seed 37): r = 3's leave-one-out chi2 0.19 above r_cv =
     * 6's (one standard error 15.5) but its reduced chi2 1.107 above 1.5 x the scatter^2 0.717:
     * kept at r = 6 (5.87x) until step 2's guard was waived for an r dividing r_cv */
    {"deadcorner", 0, 0.6, 37, 1, 0},
    /* misses of the rule (1.32x, 1.32x, 1.14x: one r too fine at a low scatter, one r too
     * coarse; docs/studies/maps.md) that the shrunk map (fit/shrink.h) brings within 1.1x: the shrunk map's
     * cases only */
    {"softedge", 9, 0.6, 5, 0.1, 1},
    {"softedge", 0, 0.6, 4, 0.1, 1},
    {"dip", 9, 0.6, 15, 0.1, 1},
};

int main(void)
{
    long z_n = 0, in2 = 0, in2_res = 0;
    double z2_res = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        fid_case_t c = {.scene = cases[i].scene, .grid = cases[i].grid, .step_um = cases[i].step,
                        .flux_scale = cases[i].flux, .seed = cases[i].seed ? cases[i].seed : 1,
                        .noise = cases[i].seed ? FIT_NOISE_SHOT_READ : FIT_NOISE_PAPER,
                        .krige = 1};
        fid_result_t f;
        err_t err;
        CHECK(fid_run(&c, 10, &f, &err) == 0);
        z_n += f.z_n, in2 += f.z_in2_rec, in2_res += f.z_in2_rec_res, z2_res += f.z2_rec_res;
        int rec = f.r_rec[0];
        CHECK(rec >= 1 && f.r_best >= 1);
        if (rec < 1 || f.r_best < 1) continue;
        double floor = fmax(f.rms[f.r_best], 1e-3);
        if (!(f.rms_kriged <= 1.1 * floor))
            fprintf(stderr, "%s %dx%d seed %lu: kriged map rms %.4f, best r = %d (rms %.4f)\n",
                    c.scene, c.grid, c.grid, c.seed, f.rms_kriged, f.r_best, f.rms[f.r_best]);
        CHECK(f.rms_kriged <= 1.1 * floor);
        /* the Bayes pick of one grid (fidelity.h r_post): a flat pixel's kriged map is exactly
         * flat, as r = 1's map is, so nothing is nearer; on a dead corner the kriged map keeps
         * the r = 3 grid that holds it (no smooth part), and r = 3's map is the nearest */
        CHECK(f.r_post >= 1 && f.r_post <= 10 && isfinite(f.rms[f.r_post]));
        if (strcmp(c.scene, "uniform") == 0) CHECK(f.r_post == 1);
        if (strcmp(c.scene, "deadcorner") == 0) CHECK(f.r_post == 3);
        if (strcmp(c.scene, "uniform") != 0 && strcmp(c.scene, "deadcorner") != 0 &&
            isfinite(f.rms_shrunk))
            CHECK(f.rms_kriged < f.rms_shrunk);
        if (!cases[i].shrunk_only) {
            if (!(f.rms[rec] <= 1.2 * floor))
                fprintf(stderr, "%s %dx%d: recommended r = %d (rms %.4f), best r = %d (rms %.4f)\n",
                        c.scene, c.grid, c.grid, rec, f.rms[rec], f.r_best, f.rms[f.r_best]);
            CHECK(f.rms[rec] <= 1.2 * floor);
            /* never the checkerboard: the recommended map's own noise (S_err, whose scale the
             * paper's sigma inflates by at most sqrt(G) ~ 1.6 here) stays below its error
             * bound, and where BIC's map is a checkerboard (over 2x the best error) the pick is
             * not it */
            CHECK(f.serr_rms[rec] <= 0.1);
            if (f.r_bic > 0 && f.rms[f.r_bic] > 2 * floor) CHECK(rec != f.r_bic);
        }
        /* the shrunk map exists unless the recommendation is r = 1 (a flat pixel) */
        CHECK(isfinite(f.rms_shrunk) == (rec > 1));
        if (!isfinite(f.rms_shrunk)) continue;
        if (!(f.rms_shrunk <= 1.1 * floor))
            fprintf(stderr, "%s %dx%d seed %lu: shrunk map rms %.4f, best r = %d (rms %.4f)\n",
                    c.scene, c.grid, c.grid, c.seed, f.rms_shrunk, f.r_best, f.rms[f.r_best]);
        CHECK(f.rms_shrunk <= 1.1 * floor);
        CHECK(f.shrunk_factor >= 0 && f.shrunk_factor <= 1);
        CHECK(f.rms_shrunk <= f.rms[rec] + 1e-3);
    }
    /* a dip the smooth part's test drops (likelihood ratio below FIT_KRIGE_LR): the map is the
     * divisor grids' (piecewise on the recommended grid), its S_err the smooth model's second
     * moment about it. Against the truth's fine-cell means: rms z within [0.6, 1.1] and at least
     * 92 % within 2 sigma (the divisor grids' own S_err gives 3.60 and 70 % here, 2.69 and 74 %
     * over the dips of seeds 1-7 and 22-28 that drop the smooth part) */
    fid_case_t dip = {.scene = "dip", .grid = 9, .step_um = 0.6, .flux_scale = 1, .seed = 6,
                      .noise = FIT_NOISE_SHOT_READ, .krige = 1};
    fid_result_t f;
    err_t err;
    CHECK(fid_run(&dip, 10, &f, &err) == 0);
    CHECK(f.kriged_smooth == 0 && f.z_n_kriged > 500);
    if (f.z_n_kriged > 0) {
        double rms = sqrt(f.z2_kriged / f.z_n_kriged), frac = (double)f.z_in2_kriged / f.z_n_kriged;
        fprintf(stderr, "dip 9x9 seed 6, kriged without the smooth part: rms z %.3f, %.1f %% "
                        "within 2 sigma\n", rms, 100 * frac);
        CHECK(rms >= 0.6 && rms <= 1.1);
        CHECK(frac >= 0.92);
    }
    CHECK(z_n > 300);
    if (z_n > 0) {
        double rms = sqrt(z2_res / (double)z_n), frac = (double)in2_res / (double)z_n;
        fprintf(stderr, "S_err + S_res against the truth: %ld sub-pixels, rms z %.3f, |z| <= 2 in "
                        "%.1f %% (S_err alone: %.1f %%)\n", z_n, rms, 100 * frac,
                100.0 * (double)in2 / (double)z_n);
        CHECK(rms >= 0.7 && rms <= 1.4);
        CHECK(frac >= 0.85);
        CHECK(in2_res >= in2 + 0.08 * (double)z_n);
    }
    CHECK_DONE();
}
