/* region.c: ipsd-bench-region, the evidence for fits that use spot positions outside the pixel
 * and for the whole-raster Wiener baseline (docs/numerics.md, "Regions and the fair Wiener").
 * Every scene family of the simulated bench is scanned by the paper's full procedure (the 51 x 51
 * raster over 5 x 5 pixels) and fitted with the points of each region (fit/region.h): inside
 * (the paper's), margins of 0.6, 1.34 (the spot radius) and 2.7 um, and all. Per region it prints
 * the mean rms error against the simulator's truth of the recommended map (fit/recommend.h) and
 * of the best map in hindsight, and the map's own noise (rms S_err) on the outer ring of
 * sub-pixels and inside it at the recommended r. Then the Wiener baseline per raster: the old
 * one (one nsr, the points inside the pixel, mirrored) against the fair one (nsr per frequency,
 * whole raster cropped to the pixel). A benchmark: it prints, it never fails on numbers.
 * Usage: ipsd-bench-region [--quick] [--seeds N] [--r-max R] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parse.h"
#include "instrument/fidelity.h"

static const char *const scenes[] = {"paperlike", "uniform", "gradient", "dip",
                                     "deadcorner", "edge",   "softedge"};
#define N_SCENES (sizeof scenes / sizeof scenes[0])

static const struct {
    const char *name;
    fit_region_t rg;
} regions[] = {
    {"inside", {FIT_REGION_INSIDE, 0}},    {"margin 0.6", {FIT_REGION_MARGIN, 0.6}},
    {"margin 1.34", {FIT_REGION_MARGIN, 1.34}}, {"margin 2.7", {FIT_REGION_MARGIN, 2.7}},
    {"all", {FIT_REGION_ALL, 0}},
};
#define N_REGIONS (sizeof regions / sizeof regions[0])

static const struct {
    const char *name;
    int grid;
    double step;
} rasters[] = {
    {"9x9 @0.6", 9, 0.6}, {"13x13 @0.42", 13, 0.42}, {"19x19 @0.3", 19, 0.3},
    {"51x51 full", 0, 0.6},
};
#define N_RASTERS (sizeof rasters / sizeof rasters[0])

struct acc {
    int n;
    double rec, best, edge, inner, points;
};

static void region_table(int seeds, int r_max)
{
    struct acc a[N_REGIONS] = {0};
    printf("Fits by region, full 51x51 raster @0.6 um, flux 1, %d seeds, r = 1..%d\n", seeds,
           r_max);
    printf("%-11s %-12s %6s %4s %8s %8s %9s %9s\n", "scene", "region", "N", "rec", "rms_rec",
           "rms_best", "Serr_edge", "Serr_in");
    for (size_t si = 0; si < N_SCENES; si++)
        for (size_t gi = 0; gi < N_REGIONS; gi++)
            for (int seed = 1; seed <= seeds; seed++) {
                fid_case_t c = {.scene = scenes[si], .grid = 0, .step_um = 0.6, .area_px = 5,
                                .flux_scale = 1, .seed = (unsigned long)seed,
                                .noise = FIT_NOISE_SHOT_READ, .region = regions[gi].rg};
                fid_result_t f;
                err_t err;
                if (fid_run(&c, r_max, &f, &err)) {
                    printf("%-11s %-12s failed: %s\n", scenes[si], regions[gi].name, err.msg);
                    continue;
                }
                int r = f.r_rec[0];
                printf("%-11s %-12s %6zu %4d %8.4f %8.4f %9.4f %9.4f\n", scenes[si],
                       regions[gi].name, f.n_points, r, r ? f.rms[r] : NAN,
                       f.r_best ? f.rms[f.r_best] : NAN, r ? f.serr_edge[r] : NAN,
                       r ? f.serr_inner[r] : NAN);
                fflush(stdout);
                if (!r) continue;
                struct acc *k = &a[gi];
                k->n++;
                k->rec += f.rms[r];
                k->best += f.rms[f.r_best];
                k->edge += f.serr_edge[r];
                k->inner += isfinite(f.serr_inner[r]) ? f.serr_inner[r] : 0;
                k->points += (double)f.n_points;
            }
    printf("\nSummary by region (means over scenes and seeds)\n");
    printf("| region | points | rms of the recommended map | rms best in hindsight | S_err edge | "
           "S_err inner |\n|---|---|---|---|---|---|\n");
    for (size_t gi = 0; gi < N_REGIONS; gi++) {
        const struct acc *k = &a[gi];
        if (!k->n) continue;
        printf("| %s | %.0f | %.4f | %.4f | %.4f | %.4f |\n", regions[gi].name, k->points / k->n,
               k->rec / k->n, k->best / k->n, k->edge / k->n, k->inner / k->n);
    }
}

static void wiener_table(int seeds)
{
    printf("\nWiener baseline: rms error against the truth, old (one nsr, inside points, mirrored)"
           " / fair (nsr per frequency, whole raster, cropped); flux 1, %d seeds\n",
           seeds);
    printf("| scene |");
    for (size_t ri = 0; ri < N_RASTERS; ri++) printf(" %s |", rasters[ri].name);
    printf("\n|---|");
    for (size_t ri = 0; ri < N_RASTERS; ri++) printf("---|");
    printf("\n");
    double so[N_RASTERS] = {0}, sn[N_RASTERS] = {0};
    int cnt[N_RASTERS] = {0};
    for (size_t si = 0; si < N_SCENES; si++) {
        printf("| %s |", scenes[si]);
        for (size_t ri = 0; ri < N_RASTERS; ri++) {
            double o = 0, n = 0;
            int k = 0;
            for (int seed = 1; seed <= seeds; seed++) {
                fid_case_t c = {.scene = scenes[si], .grid = rasters[ri].grid,
                                .step_um = rasters[ri].step, .area_px = 5, .flux_scale = 1,
                                .seed = (unsigned long)seed, .noise = FIT_NOISE_SHOT_READ};
                fid_result_t f;
                err_t err;
                if (fid_run(&c, 1, &f, &err)) continue; /* r = 1 only: the fits are not read */
                o += f.rms_wiener;
                n += f.rms_wiener_whole;
                k++;
            }
            printf(" %.4f / %.4f |", k ? o / k : NAN, k ? n / k : NAN);
            fflush(stdout);
            so[ri] += k ? o / k : 0, sn[ri] += k ? n / k : 0, cnt[ri] += k > 0;
        }
        printf("\n");
    }
    printf("| mean |");
    for (size_t ri = 0; ri < N_RASTERS; ri++)
        printf(" %.4f / %.4f |", cnt[ri] ? so[ri] / cnt[ri] : NAN,
               cnt[ri] ? sn[ri] / cnt[ri] : NAN);
    printf("\n");
}

int main(int argc, char **argv)
{
    int seeds = 2, r_max = 10, quick = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--quick") == 0) quick = 1;
        else if (strcmp(argv[i], "--seeds") == 0 && i + 1 < argc &&
                 parse_int(argv[i + 1], &seeds) == 0 && seeds >= 1)
            i++;
        else if (strcmp(argv[i], "--r-max") == 0 && i + 1 < argc &&
                 parse_int(argv[i + 1], &r_max) == 0 && r_max >= 1 && r_max <= FID_R_MAX)
            i++;
        else {
            fprintf(stderr, "usage: ipsd-bench-region [--quick] [--seeds N] [--r-max R]\n");
            return 2;
        }
    }
    if (quick) seeds = 1, r_max = r_max < 6 ? r_max : 6;
    wiener_table(seeds);
    printf("\n");
    region_table(seeds, r_max);
    return 0;
}
