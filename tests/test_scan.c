/* test_scan.c: the paper's scan procedure (instrument/scan.h) on the simulated bench: centring and
 * focus from random starts (fixed seeds) within 0.1 um and the focus depth tolerance, the
 * exposure choice, the raster geometry of the paper (51 x 51 points, 9 x 9 inside each pixel),
 * extracted scan files of the POI and of neighbours against fit_box_integral (noiseless uniform
 * pixels), stopping and resuming a raster, and bad configurations. */
#include <errno.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_rng.h>

#include "fit/airy.h"
#include "fit/box.h"
#include "check.h"
#include "instrument/scan.h"
#include "instrument/scanfile.h"
#include "instrument/sim.h"

#define POI 128

static sim_t *open_sim(const char *scene, int noiseless, unsigned long seed)
{
    sim_config_t c = sim_config_default();
    c.scene = scene;
    c.noiseless = noiseless;
    c.seed = seed;
    c.design_tol = 1e-12;
    sim_t *s = NULL;
    err_t err;
    if (sim_open(&c, &s, &err)) fprintf(stderr, "sim_open: %s\n", err.msg);
    return s;
}

static scan_config_t config_for(sim_t *s)
{
    scan_config_t c = scan_config_default();
    c.poi_col = c.poi_row = POI;
    c.spot_radius_um = sim_spot_radius0(s);
    c.start = sim_pixel_centre(s, POI, POI);
    return c;
}

/* DN of a noiseless uniform pixel for a spot at (u, v) from its corner (sim.h photometry). */
static double uniform_dn(double u, double v)
{
    double R = 1.22 * 0.55 / (2 * 0.25), val = NAN, eb;
    fit_rect_t r = {0, 6, 0, 6};
    fit_box_integral(R, &r, u, v, 1e-14, &val, &eb, NULL);
    return 100 + sim_config_default().flux_e * val / fit_airy_total(fit_airy_a(R)) / 3.153;
}

/* Setup from starts up to 1.5 um off in x and y (one on the right neighbour) and 8 um in z. */
static void test_setup(const char *scene, int runs, unsigned long seed)
{
    gsl_rng *rng = gsl_rng_alloc(gsl_rng_mt19937);
    gsl_rng_set(rng, seed);
    for (int k = 0; k < runs; k++) {
        sim_t *s = open_sim(scene, 0, seed + (unsigned long)k);
        scan_config_t c = config_for(s);
        stage_pos_t truth = c.start;
        c.start.x_um += k == 0 ? 4.5 : 3 * (gsl_rng_uniform(rng) - 0.5);
        c.start.y_um += 3 * (gsl_rng_uniform(rng) - 0.5);
        c.start.z_um += 16 * (gsl_rng_uniform(rng) - 0.5);
        scan_setup_t su;
        err_t err;
        int rc = scan_prepare(sim_camera(s), sim_stage(s), &c, NULL, &su, &err);
        CHECK(rc == 0);
        if (rc) fprintf(stderr, "scan_prepare: %s\n", err.msg);
        double ex = su.centre.x_um - truth.x_um, ey = su.centre.y_um - truth.y_um;
        double ez = su.centre.z_um - truth.z_um, target = 100 + 0.4 * (16000 - 100);
        printf("%s start (%+.2f %+.2f %+.2f): centre off by (%+.4f %+.4f) um, focus by %+.4f um "
               "(tolerance %.3f), peak %.0f DN, %d evaluations\n",
               scene, c.start.x_um - truth.x_um, c.start.y_um - truth.y_um,
               c.start.z_um - truth.z_um, ex, ey, ez, sim_focus_tolerance(s), su.peak_dn,
               su.focus_evaluations);
        CHECK(fabs(ex) < 0.1 && fabs(ey) < 0.1);
        CHECK(fabs(ez) < sim_focus_tolerance(s));
        CHECK(fabs(su.peak_dn - target) < 0.05 * target && su.peak_dn < 16000);
        sim_close(s);
    }
    gsl_rng_free(rng);
}

static int stop_after(const scan_point_t *pt, void *user)
{
    int *left = user;
    (void)pt;
    return --*left <= 0;
}

/* Stopped after 100 points by the point handler, then resumed from point 100 on another bench:
 * the same raster as r (noiseless). */
static void test_resume(const scan_config_t *c, const scan_raster_t *r)
{
    err_t err;
    sim_t *s2 = open_sim("uniform", 1, 1);
    scan_raster_t r2;
    CHECK(scan_raster_init(&r2, c, &r->setup, NULL) == 0);
    int left = 100;
    scan_hooks_t hooks = {.point = stop_after, .user = &left};
    CHECK(scan_raster_run(sim_camera(s2), sim_stage(s2), c, &r->setup, 0, &hooks, &r2, &err) ==
          -ECANCELED);
    CHECK(r2.captured == 100 && r2.have[99] && !r2.have[100]);
    atomic_int stop = 1;
    scan_hooks_t halt = {.stop = &stop};
    CHECK(scan_raster_run(sim_camera(s2), sim_stage(s2), c, &r->setup, 100, &halt, &r2, &err) ==
          -ECANCELED);
    CHECK(r2.captured == 100);
    sim_close(s2);
    s2 = open_sim("uniform", 1, 1);
    CHECK(scan_raster_run(sim_camera(s2), sim_stage(s2), c, &r->setup, 100, NULL, &r2, &err) == 0);
    CHECK(r2.captured == 2601);
    /* the same raster to the integration accuracy (which misses share a design build changes
     * the last bits) */
    double diff = 0;
    for (size_t k = 0; k < 2601 * 81; k++)
        diff = fmax(diff, fabs(r->mean_dn[k] - r2.mean_dn[k]) / r->mean_dn[k]);
    printf("resumed raster vs uninterrupted: largest relative difference %.2e\n", diff);
    CHECK(diff < 1e-11);
    scan_raster_free(&r2);
    sim_close(s2);
}

/* The paper's 9 x 9 directly inside the POI. */
static void test_grid(sim_t *s, const scan_config_t *c)
{
    scan_setup_t su;
    scanfile_t sf;
    err_t err;
    CHECK(scan_prepare(sim_camera(s), sim_stage(s), c, NULL, &su, NULL) == 0);
    CHECK(scan_grid_pixel(sim_camera(s), sim_stage(s), c, &su, 9, NULL, &sf, &err) == 0);
    CHECK(sf.scan.n == 81);
    for (size_t k = 0; k < sf.scan.n; k++)
        CHECK_NEAR(sf.signal_dn[k], uniform_dn(sf.x_um[k], sf.y_um[k]), 1e-9, 0);
    CHECK_NEAR(sf.x_um[80], 5.4, 0, 1e-9);
    scanfile_free(&sf);
    CHECK(scan_grid_pixel(sim_camera(s), sim_stage(s), c, &su, 11, NULL, &sf, &err) == -EINVAL);
    CHECK(strstr(err.msg, "inside") != NULL);
}

/* The paper's raster on a noiseless uniform sensor: geometry, extraction, resume, grid. */
static void test_raster(void)
{
    sim_t *s = open_sim("uniform", 1, 1);
    scan_config_t c = config_for(s);
    c.do_centre = c.do_focus = c.do_exposure = 0;
    c.frames = 1;
    c.use_expected = 1;
    scan_raster_t r;
    err_t err;
    CHECK(scan_run(sim_camera(s), sim_stage(s), &c, NULL, &r, &err) == 0);
    CHECK(r.nx == 51 && r.count == 2601 && r.captured == 2601 && r.m == 9);
    stage_pos_t p0 = scan_raster_position(&c, &r.setup, r.nx, 0);
    CHECK_NEAR(p0.x_um, c.start.x_um - 15, 0, 1e-12); /* 15 um left and up, as the paper */
    CHECK_NEAR(p0.y_um, c.start.y_um - 15, 0, 1e-12);
    int pix[][2] = {{0, 0}, {1, 0}, {-2, 2}, {2, -1}};
    for (size_t q = 0; q < sizeof pix / sizeof pix[0]; q++) {
        scanfile_t sf;
        CHECK(scan_extract_pixel(&r, pix[q][0], pix[q][1], &sf, &err) == 0);
        CHECK(sf.scan.n == 81); /* 9 x 9 inside every pixel of the 5 x 5 area */
        double worst = 0;
        for (size_t k = 0; k < sf.scan.n; k++) {
            CHECK(sf.x_um[k] > 0.5 && sf.x_um[k] < 5.5 && sf.y_um[k] > 0.5 && sf.y_um[k] < 5.5);
            double want = uniform_dn(sf.x_um[k], sf.y_um[k]);
            worst = fmax(worst, fabs(sf.signal_dn[k] - want) / want);
        }
        CHECK(worst < 1e-9);
        CHECK_NEAR(sf.x_um[0], 0.6, 0, 1e-9);
        CHECK(sf.scan.frames == 1 && sf.scan.pitch_um == 6 && sf.scan.bias_dn == 100);
        CHECK(sf.scan.gain_e_per_dn == 3.153 && sf.scan.read_noise_e == 5.67);
        scanfile_free(&sf);
    }
    scanfile_t sf;
    CHECK(scan_extract_pixel(&r, 3, 0, &sf, &err) == 0 && sf.scan.n == 0); /* outside the area */
    scanfile_free(&sf);
    CHECK(scan_extract_pixel(&r, 5, 0, &sf, &err) == -EINVAL && strstr(err.msg, "sub-frame"));
    test_resume(&c, &r);
    scan_raster_free(&r);
    test_grid(s, &c);
    sim_close(s);
}

static void test_bad_config(void)
{
    sim_t *s = open_sim("uniform", 1, 1);
    scan_config_t c = config_for(s);
    scan_setup_t su;
    scan_raster_t r;
    err_t err;
    c.spot_radius_um = NAN;
    CHECK(scan_prepare(sim_camera(s), sim_stage(s), &c, NULL, &su, &err) == -EINVAL);
    CHECK(strstr(err.msg, "spot_radius_um") != NULL);
    c = config_for(s);
    c.subframe_px = 8;
    CHECK(scan_prepare(sim_camera(s), sim_stage(s), &c, NULL, &su, &err) == -EINVAL);
    c = config_for(s);
    c.poi_col = 2;
    CHECK(scan_prepare(sim_camera(s), sim_stage(s), &c, NULL, &su, &err) == -EINVAL);
    CHECK(strstr(err.msg, "leaves") != NULL);
    c = config_for(s);
    c.do_centre = c.do_focus = c.do_exposure = 0;
    CHECK(scan_prepare(sim_camera(s), sim_stage(s), &c, NULL, &su, &err) == 0);
    c.step_um = 0.7;
    CHECK(scan_raster_init(&r, &c, &su, &err) == -EINVAL && strstr(err.msg, "whole number"));
    atomic_int stop = 1;
    scan_hooks_t halt = {.stop = &stop};
    c = config_for(s);
    CHECK(scan_prepare(sim_camera(s), sim_stage(s), &c, &halt, &su, &err) == -ECANCELED);
    sim_close(s);
}

int main(void)
{
    gsl_set_error_handler_off();
    test_setup("uniform", 4, 11);
    test_setup("paperlike", 2, 21);
    test_raster();
    test_bad_config();
    CHECK_DONE();
}
