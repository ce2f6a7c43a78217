/* test_scan.c: the paper's scan procedure (instrument/scan.h) on the simulated bench: centring and
 * focus from random starts (fixed seeds) within 0.1 um and the focus depth tolerance, the
 * exposure choice, the raster geometry of the paper (51 x 51 points, 9 x 9 inside each pixel),
 * extracted scan files of the POI and of neighbours against fit_box_integral (noiseless uniform
 * pixels), stopping and resuming a raster, bad configurations, and the scan's limits
 * (scan_limits.h: points per axis, 10^6 points, samples a point, the grid, one field's range) and
 * eq. 1 both ways (fit/airy.h). */
#include <errno.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_rng.h>

#include "fit/airy.h"
#include "fit/box.h"
#include "check.h"
#include "instrument/scan.h"
#include "instrument/scan_limits.h"
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

/* The scan's rules (scan_limits.h) against numbers worked out by hand, and eq. 1 both ways. */
static void test_limits(void)
{
    err_t err;
    int nx = 0;
    /* points per axis: the paper's 5 pixels of 6 um in 0.6 um steps are 50 steps, 51 points */
    CHECK(scan_axis_points(6.0, 5, 0.6) == 51);
    CHECK(scan_axis_points(6.0, 3, 1.0) == 19);
    CHECK(scan_axis_points(6.0, 5, 0.7) == 0 && scan_axis_points(6.0, 5, -0.6) == 0);
    CHECK(scan_axis_points(NAN, 5, 0.6) == 0 && scan_axis_points(6.0, 0, 0.6) == 0);
    /* at most 10^6 points: 6 um in 999 steps is 1000^2 points, in 1000 steps 1001^2 */
    CHECK(scan_check_raster(6.0, 1, 6.0 / 999, "step", &nx, &err) == 0 && nx == 1000);
    CHECK(scan_check_raster(6.0, 1, 6.0 / 1000, "step", &nx, &err) == -EINVAL && nx == 1001);
    CHECK(strstr(err.msg, "step") == err.msg && strstr(err.msg, "1000000"));
    CHECK(scan_check_raster(6.0, 5, 0.7, "--step", NULL, &err) == -EINVAL);
    CHECK(strstr(err.msg, "--step") == err.msg && strstr(err.msg, "whole number"));
    /* samples a point: 2^26 = 67108864; 1032 x 255^2 = 67105800 fits, 1033 x 255^2 does not */
    CHECK(scan_check_samples(1032, 255, "frames", &err) == 0);
    CHECK(scan_check_samples(1033, 255, "frames", &err) == -EINVAL);
    /* a grid inside a 6 um pixel: 10 steps of 0.6 um span it all, which is not inside */
    CHECK(scan_check_grid(6.0, 10, 0.6, "grid", &err) == 0);
    CHECK(scan_check_grid(6.0, 11, 0.6, "grid", &err) == -EINVAL && strstr(err.msg, "grid"));
    /* one field: its ends, just outside, oddness, whole numbers, the name in the message */
    const scan_field_t *area = &scan_fields[SCAN_F_AREA_PX], *step = &scan_fields[SCAN_F_STEP_UM];
    CHECK(scan_field_by_api("raster.area_px") == area && scan_field_by_api("raster.nope") == NULL);
    CHECK(scan_field_check(area, area->min, "--area", &err) == 0);
    CHECK(scan_field_check(area, area->max, "--area", &err) == 0);
    CHECK(scan_field_check(area, area->max + 2, "--area", &err) == -EINVAL);
    CHECK(scan_field_check(area, 4, "--area", &err) == -EINVAL && strstr(err.msg, "odd"));
    CHECK(strstr(err.msg, "--area") == err.msg);
    CHECK(scan_field_check(area, 2.5, "--area", &err) == -EINVAL && strstr(err.msg, "integer"));
    CHECK(scan_field_check(step, 0, "step_um", &err) == -EINVAL); /* exclusive minimum */
    CHECK(scan_field_check(step, NAN, "step_um", &err) == -EINVAL);
    CHECK(scan_field_check(step, step->max, "step_um", &err) == 0);
    /* the paper's scan is the default (section II.B), and within its own limits */
    scan_config_t c = scan_config_default();
    CHECK(c.area_px == 5 && c.step_um == 0.6 && c.subframe_px == 9 && c.frames == 12);
    CHECK(scan_fields[SCAN_F_WAVELENGTH_NM].def == 550 && scan_fields[SCAN_F_NA].def == 0.25);
    CHECK(scan_config_check(&c, NULL, &err) == 0);
    c.area_px = 4;
    CHECK(scan_config_check(&c, NULL, &err) == -EINVAL && strstr(err.msg, "area_px"));
    c = scan_config_default();
    c.subframe_px = 255, c.frames = 1033;
    CHECK(scan_config_check(&c, NULL, &err) == -EINVAL && strstr(err.msg, "frames"));
    /* eq. 1 both ways: the paper's 550 nm and NA 0.25 give R = 1.22 x 0.55 / 0.5 = 1.342 um */
    CHECK(fabs(fit_spot_radius_um(0.55, 0.25) - 1.342) < 1e-12);
    CHECK(fabs(fit_spot_na(0.55, 1.342) - 0.25) < 1e-12);
    CHECK(fabs(fit_spot_na(0.55, fit_spot_radius_um(0.55, 1.3)) - 1.3) < 1e-12);
}

int main(void)
{
    test_setup("uniform", 4, 11);
    test_setup("paperlike", 2, 21);
    test_raster();
    test_bad_config();
    test_limits();
    CHECK_DONE();
}
