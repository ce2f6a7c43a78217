/* fidelity.c: ipsd-bench-fidelity, the evidence table for the map's scientific choices: every
 * scene family of the simulated bench, scanned by the paper's rasters at two photon levels and
 * several seeds, fitted for r = 1..R; prints per case the rms error of each r's map against the
 * simulator's truth, the r AIC and BIC pick, the best r in hindsight, and the Wiener baseline,
 * then a summary per raster (instrument/fidelity.h). A benchmark: it prints, it never fails on
 * numbers. Usage: ipsd-bench-fidelity [--quick] [--r-max R] [--seeds N]. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/parse.h"
#include "instrument/fidelity.h"

static const char *const scenes[] = {"paperlike", "uniform", "gradient", "dip",
                                     "deadcorner", "edge",   "softedge"};
static const struct raster {
    const char *name;
    int grid;
    double step;
} rasters[] = {
    {"9x9 @0.6", 9, 0.6}, {"13x13 @0.42", 13, 0.42}, {"19x19 @0.3", 19, 0.3},
    {"51x51 full", 0, 0.6},
};
static const double fluxes[] = {1.0, 0.1};

#define N_SCENES (sizeof scenes / sizeof scenes[0])
#define N_RASTERS (sizeof rasters / sizeof rasters[0])
#define N_FLUXES (sizeof fluxes / sizeof fluxes[0])

/* Ratio of a pick's rms to the best in hindsight (1 = as good as can be). */
static double ratio(const fid_result_t *f, int r)
{
    /* floor 1e-3: a flat pixel's r = 1 map is exact (rms 0), and 0.1 % is below any noise */
    return r > 0 && f->r_best > 0 ? f->rms[r] / fmax(f->rms[f->r_best], 1e-3) : NAN;
}

struct tally {
    int cases, aic_ok, bic_ok, cv_ok; /* picks within 1.1x of the best */
    double aic_worst, bic_worst, cv_worst, wiener_sum, best_sum;
};

int main(int argc, char **argv)
{
    int quick = 0, r_max = 10, seeds = 3;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--quick") == 0) quick = 1;
        else if (strcmp(argv[i], "--r-max") == 0 && i + 1 < argc && parse_int(argv[i + 1], &r_max) == 0 &&
                 r_max >= 1 && r_max <= FID_R_MAX) i++;
        else if (strcmp(argv[i], "--seeds") == 0 && i + 1 < argc && parse_int(argv[i + 1], &seeds) == 0 &&
                 seeds >= 1) i++;
        else {
            fprintf(stderr, "usage: ipsd-bench-fidelity [--quick] [--r-max 1..%d] [--seeds N]\n",
                    FID_R_MAX);
            return 2;
        }
    }
    if (quick) seeds = 1;
    struct tally t[N_RASTERS];
    memset(t, 0, sizeof t);
    double t0 = clock_mono_s();
    printf("map rms error against the simulator's truth (mean-1 maps, %d x %d samples)\n", 240, 240);
    printf("%-11s %-12s %5s %4s %6s | %3s %3s %3s %3s | %7s %7s %7s %7s | %7s | rms by r = 1..%d\n",
           "scene", "raster", "flux", "seed", "N", "AIC", "BIC", "CV", "bst", "rmsAIC", "rmsBIC",
           "rmsCV", "rmsBest", "Wiener", r_max);
    for (size_t ri = 0; ri < N_RASTERS; ri++)
        for (size_t si = 0; si < N_SCENES; si++)
            for (size_t fi = 0; fi < (quick ? 1 : N_FLUXES); fi++)
                for (int seed = 1; seed <= seeds; seed++) {
                    fid_case_t c = {.scene = scenes[si], .grid = rasters[ri].grid,
                                    .step_um = rasters[ri].step, .area_px = 5,
                                    .flux_scale = fluxes[fi], .seed = (unsigned long)seed,
                                    .noise = FIT_NOISE_SHOT_READ};
                    fid_result_t f;
                    err_t err;
                    if (fid_run(&c, r_max, &f, &err)) {
                        printf("%-11s %-12s %5.2f %4d  error: %s\n", c.scene, rasters[ri].name,
                               c.flux_scale, seed, err.msg);
                        continue;
                    }
                    printf("%-11s %-12s %5.2f %4d %6zu | %3d %3d %3d %3d | %7.4f %7.4f %7.4f %7.4f | "
                           "%7.4f |",
                           c.scene, rasters[ri].name, c.flux_scale, seed, f.n_points, f.r_aic,
                           f.r_bic, f.r_cv, f.r_best, f.r_aic ? f.rms[f.r_aic] : NAN,
                           f.r_bic ? f.rms[f.r_bic] : NAN, f.r_cv ? f.rms[f.r_cv] : NAN,
                           f.r_best ? f.rms[f.r_best] : NAN, f.rms_wiener);
                    for (int r = 1; r <= r_max; r++) printf(" %.3f", f.rms[r]);
                    printf("\n");
                    fflush(stdout);
                    struct tally *k = &t[ri];
                    double ra = ratio(&f, f.r_aic), rb = ratio(&f, f.r_bic), rc = ratio(&f, f.r_cv);
                    k->cases++;
                    k->aic_ok += ra <= 1.1;
                    k->bic_ok += rb <= 1.1;
                    k->aic_worst = fmax(k->aic_worst, ra);
                    k->bic_worst = fmax(k->bic_worst, rb);
                    k->cv_ok += rc <= 1.1;
                    k->cv_worst = fmax(k->cv_worst, rc);
                    k->best_sum += f.r_best ? f.rms[f.r_best] : 0;
                    k->wiener_sum += isfinite(f.rms_wiener) ? f.rms_wiener : 0;
                }
    printf("\nsummary per raster: picks within 1.1x of the best r in hindsight, worst ratio, mean "
           "rms of the best map and of Wiener\n");
    printf("%-12s %5s | %9s %9s | %9s %9s | %9s %9s | %8s %8s\n", "raster", "cases", "AIC ok",
           "AIC worst", "BIC ok", "BIC worst", "CV ok", "CV worst", "best", "Wiener");
    for (size_t ri = 0; ri < N_RASTERS; ri++) {
        const struct tally *k = &t[ri];
        printf("%-12s %5d | %4d/%-4d %9.2f | %4d/%-4d %9.2f | %4d/%-4d %9.2f | %8.4f %8.4f\n",
               rasters[ri].name, k->cases, k->aic_ok, k->cases, k->aic_worst, k->bic_ok, k->cases,
               k->bic_worst, k->cv_ok, k->cases, k->cv_worst,
               k->cases ? k->best_sum / k->cases : NAN, k->cases ? k->wiener_sum / k->cases : NAN);
    }
    printf("\ntotal %.1f s\n", clock_mono_s() - t0);
    return 0;
}
