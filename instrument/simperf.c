/* simperf.c: the simulated bench's speed and leave-out figures for `ips bench` (see simperf.h). */
#include "instrument/simperf.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "instrument/scan.h"
#include "instrument/sim.h"

/* The paper's scan configuration for the bench: the POI in the middle of its sensor, its spot. */
static scan_config_t paper_config(sim_t *sim)
{
    const scene_sensor_t *sn = scene_sensor(sim_scene(sim));
    scan_config_t c = scan_config_default();
    c.poi_col = sn->cols / 2;
    c.poi_row = sn->rows / 2;
    c.spot_radius_um = sim_spot_radius0(sim);
    return c;
}

/* The paper's raster on a fresh paperlike bench at tolerance tol, from the true centre. Fills the
 * row and, when expected is not NULL, the expected electrons of every point's sub-frame. */
static int one_scan(double tol, simperf_t *p, simperf_row_t *row, double *expected, err_t *err)
{
    sim_config_t sc = sim_config_default();
    sc.leave_out_tol = tol;
    sim_t *sim;
    int rc = sim_open(&sc, &sim, err);
    if (rc) return rc;
    scan_config_t c = paper_config(sim);
    c.do_centre = c.do_focus = c.do_exposure = 0;
    c.start = sim_pixel_centre(sim, c.poi_col, c.poi_row);
    scan_setup_t su;
    rc = scan_prepare(sim_camera(sim), sim_stage(sim), &c, NULL, &su, err);
    sim_reset_stats(sim);
    double t0 = clock_mono_s();
    if (rc == 0) rc = scan_raster_run(sim_camera(sim), sim_stage(sim), &c, &su, 0, NULL, NULL, err);
    row->scan_s = clock_mono_s() - t0;
    sim_stats_t st;
    sim_get_stats(sim, &st);
    *row = (simperf_row_t){tol,       row->scan_s, st.integrate_s, st.noise_s, st.full,
                           st.coarse, st.uniform,  st.left_out,    0,          st.max_left_out_e};
    int nx = scan_points_per_axis(&c, su.pitch_um), m = c.subframe_px;
    p->points = (size_t)nx * nx;
    p->frames = st.frames;
    p->pixel_frames = st.pixel_frames;
    p->flux_e = sc.flux_e;
    cam_roi_t roi = {c.poi_col - m / 2, c.poi_row - m / 2, m, m};
    for (size_t i = 0; rc == 0 && expected && i < p->points; i++) { /* memo hits: cheap */
        stage_pos_t pos = scan_raster_position(&c, &su, nx, i);
        rc = sim_expected(sim, pos.x_um, pos.y_um, sim_spot_radius(sim, pos.z_um), &roi,
                          expected + i * (size_t)m * m, NULL, err);
    }
    sim_close(sim);
    return rc;
}

/* The setup from a random start (seeded) on the default bench. */
static int one_setup(simperf_t *p, err_t *err)
{
    sim_config_t sc = sim_config_default();
    sim_t *sim;
    int rc = sim_open(&sc, &sim, err);
    if (rc) return rc;
    scan_config_t c = paper_config(sim);
    c.start = sim_pixel_centre(sim, c.poi_col, c.poi_row);
    c.start.x_um += 0.9;
    c.start.y_um -= 1.2;
    c.start.z_um += 6.0;
    scan_setup_t su;
    double t0 = clock_mono_s();
    rc = scan_prepare(sim_camera(sim), sim_stage(sim), &c, NULL, &su, err);
    p->setup_s = clock_mono_s() - t0;
    p->setup_evaluations = su.focus_evaluations;
    sim_close(sim);
    return rc;
}

int simperf_measure(int quick, simperf_t *p, err_t *err)
{
    static const double full[] = {0, 1e-6, 1e-5, 1e-4, 1e-3}, fast[] = {0, 1e-4};
    const double *tols = quick ? fast : full;
    size_t nt = quick ? 2 : 5;
    memset(p, 0, sizeof *p);
    double def = sim_config_default().leave_out_tol;
    size_t per = 51 * 51 * 81;
    double *ref = malloc(sizeof(double) * per), *cur = malloc(sizeof(double) * per);
    int rc = ref && cur ? 0 : err_set(err, -ENOMEM, "out of memory for the bench");
    for (size_t t = 0; rc == 0 && t < nt; t++) {
        simperf_row_t *row = &p->rows[t];
        rc = one_scan(tols[t], p, row, t == 0 ? ref : cur, err);
        if (rc == 0 && p->points * 81 != per) rc = err_set(err, -EINVAL, "unexpected raster size");
        for (size_t k = 0; rc == 0 && t > 0 && k < per; k++)
            if (fabs(cur[k] - ref[k]) > row->max_error_e) row->max_error_e = fabs(cur[k] - ref[k]);
        p->n_rows = t + 1;
        if (tols[t] == def) p->default_row = (int)t;
    }
    if (rc == 0) rc = one_setup(p, err);
    free(ref);
    free(cur);
    return rc;
}

void simperf_print(FILE *f, const simperf_t *p)
{
    fprintf(f,
            "Simulated bench: the paper's full scan (%zu points x 12 frames of a 9 x 9 "
            "sub-frame = %zu pixel draws, paperlike scene, spot flux %.0f e-), one core\n",
            p->points, p->pixel_frames, p->flux_e);
    fprintf(f, "%9s %9s %9s %9s  %7s %7s %8s %8s  %11s %11s\n", "leave-out", "scan s", "integr s",
            "noise s", "full", "coarse", "uniform", "left out", "max err e-", "bound e-");
    for (size_t t = 0; t < p->n_rows; t++) {
        const simperf_row_t *r = &p->rows[t];
        fprintf(f, "%9.0e %9.3f %9.3f %9.3f  %7zu %7zu %8zu %8zu  %11.2e %11.2e%s\n", r->tol,
                r->scan_s, r->integrate_s, r->noise_s, r->full, r->coarse, r->uniform, r->left_out,
                r->max_error_e, r->max_bound_e, (int)t == p->default_row ? "  (default)" : "");
    }
    const simperf_row_t *d = &p->rows[p->default_row], *z = &p->rows[0];
    fprintf(f,
            "  full scan at the default tolerance: %.3f s (target < 2 s); the leave-out rule "
            "saves %.0f %% of the integration time for a largest error of %.2g e- (bound %.2g)\n",
            d->scan_s, z->integrate_s > 0 ? 100 * (1 - d->integrate_s / z->integrate_s) : 0,
            d->max_error_e, d->max_bound_e);
    fprintf(f, "  setup (exposure, centring, focus) from a random start: %.3f s, %d evaluations\n",
            p->setup_s, p->setup_evaluations);
}

json_t *simperf_json(const simperf_t *p)
{
    json_t *root = json_object(), *rows = json_array();
    json_object_set_new(root, "points", json_integer((json_int_t)p->points));
    json_object_set_new(root, "frames", json_integer((json_int_t)p->frames));
    json_object_set_new(root, "pixel_frames", json_integer((json_int_t)p->pixel_frames));
    json_object_set_new(root, "flux_e", json_real(p->flux_e));
    json_object_set_new(root, "setup_s", json_real(p->setup_s));
    json_object_set_new(root, "setup_evaluations", json_integer(p->setup_evaluations));
    json_object_set_new(root, "scan_s", json_real(p->rows[p->default_row].scan_s));
    for (size_t t = 0; t < p->n_rows; t++) {
        const simperf_row_t *r = &p->rows[t];
        json_array_append_new(
            rows, json_pack("{s:f, s:f, s:f, s:f, s:I, s:I, s:I, s:I, s:f, s:f, s:b}", "tol",
                            r->tol, "scan_s", r->scan_s, "integrate_s", r->integrate_s, "noise_s",
                            r->noise_s, "full", (json_int_t)r->full, "coarse",
                            (json_int_t)r->coarse, "uniform", (json_int_t)r->uniform, "left_out",
                            (json_int_t)r->left_out, "max_error_e", r->max_error_e, "max_bound_e",
                            r->max_bound_e, "default", (int)t == p->default_row));
    }
    json_object_set_new(root, "leave_out", rows);
    return root;
}

int simperf_run(FILE *f, int quick, err_t *err)
{
    simperf_t p;
    int rc = simperf_measure(quick, &p, err);
    if (rc == 0) simperf_print(f, &p);
    return rc;
}
