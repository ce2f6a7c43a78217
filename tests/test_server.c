/* test_server.c: pieces of the server core (server/) without HTTP: the event hub (order, waiting
 * and waking, dropped events, heartbeats, shutdown), the scan setup's JSON round trip, the pixel
 * extraction from stored points against the raster's geometry and the camera's raw frames, the
 * fit job against the published reference fits, the job parameters, and the command line.
 * (The raster size rule, 51 x 51 points for the paper, is tested with it in test_scan.c.) */
#define _GNU_SOURCE /* mkdtemp */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>


#include "base/clock.h"
#include "instrument/scan.h"
#include "check.h"
#include "instrument/scanfile.h"
#include "instrument/sim.h"
#include "server/srv.h"
#include "server/srv_config.h"
#include "server/srv_token.h"
#include "server/srv_events.h"
#include "server/srv_fit.h"
#include "server/srv_params.h"
#include "server/srv_setup.h"
#include "storage/storage.h"

static char tmpdir[512];

/* ---- event hub ---- */

struct counter {
    int sleeps, wakes;
};
static void on_sleep(void *c)
{
    ((struct counter *)c)->sleeps++;
}
static void on_wake(void *c)
{
    ((struct counter *)c)->wakes++;
}

/* A counter of wakes that another thread (the hub's ticker) calls, and a wait for it. */
struct woken {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int wakes;
};
static void on_wake_locked(void *c)
{
    struct woken *w = c;
    pthread_mutex_lock(&w->mu);
    w->wakes++;
    pthread_cond_broadcast(&w->cv);
    pthread_mutex_unlock(&w->mu);
}
/* The wakes once there are at least n, or fewer after a generous deadline (a busy machine). */
static int wait_woken(struct woken *w, int n, int ms)
{
    struct timespec until = clock_deadline(CLOCK_REALTIME, ms);
    pthread_mutex_lock(&w->mu);
    int rc = 0;
    while (w->wakes < n && rc == 0)
        rc = pthread_cond_timedwait(&w->cv, &w->mu, &until);
    int wakes = w->wakes;
    pthread_mutex_unlock(&w->mu);
    return wakes;
}

static srv_event_t event(int64_t job, int done)
{
    srv_event_t e = {.job_id = job, .points_done = done, .eta_s = NAN};
    snprintf(e.phase, sizeof e.phase, "raster");
    return e;
}

static void test_events(void)
{
    srv_events_t *h = NULL;
    srv_sub_t *a = NULL, *b = NULL;
    struct counter ca = {0}, cb = {0};
    srv_event_t e = event(1, 1), got;
    CHECK(srv_events_open(4, 0, &h, NULL) == 0);
    srv_events_publish(h, &e); /* before anyone listens: not seen */
    CHECK(srv_events_subscribe(h, on_sleep, on_wake, &ca, &a) == 0);
    CHECK(srv_events_subscribe(h, on_sleep, on_wake, &cb, &b) == 0);
    CHECK(srv_events_readers(h) == 2);
    CHECK(srv_events_next(h, a, &got) == SRV_EV_NONE && ca.sleeps == 1 && ca.wakes == 0);
    for (int i = 2; i <= 4; i++) {
        e = event(1, i);
        srv_events_publish(h, &e);
    }
    CHECK(ca.wakes == 1 && cb.wakes == 0); /* woken once, only the one that waited */
    for (int i = 2; i <= 4; i++) {
        CHECK(srv_events_next(h, a, &got) == SRV_EV_EVENT && got.points_done == i);
        CHECK(got.seq == (uint64_t)i && strcmp(got.phase, "raster") == 0);
    }
    CHECK(srv_events_next(h, a, &got) == SRV_EV_NONE && ca.sleeps == 2);
    /* b does not read while 5 more come: the ring of 4 drops the oldest */
    for (int i = 5; i <= 9; i++) {
        e = event(2, i);
        srv_events_publish(h, &e);
    }
    CHECK(srv_events_next(h, b, &got) == SRV_EV_LOST);
    CHECK(srv_events_next(h, b, &got) == SRV_EV_EVENT && got.points_done == 6);
    CHECK(ca.wakes == 2);
    srv_events_shutdown(h);
    CHECK(srv_events_next(h, b, &got) == SRV_EV_CLOSED);
    srv_events_unsubscribe(h, a);
    srv_events_unsubscribe(h, b);
    CHECK(srv_events_readers(h) == 0);
    srv_events_close(h);

    /* heartbeats: a waiting reader is woken by the ticker thread (waited for, not slept on) and
     * told; woken once per sleep: while two more periods pass (a probe reader sees them) it is
     * not woken again */
    struct woken cc = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0};
    struct woken cp = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0};
    srv_sub_t *c = NULL, *probe = NULL;
    CHECK(srv_events_open(8, 40, &h, NULL) == 0);
    CHECK(srv_events_subscribe(h, NULL, on_wake_locked, &cc, &c) == 0);
    CHECK(srv_events_subscribe(h, NULL, on_wake_locked, &cp, &probe) == 0);
    CHECK(srv_events_next(h, c, &got) == SRV_EV_NONE);
    CHECK(wait_woken(&cc, 1, 30000) == 1);
    for (int k = 1; k <= 2; k++) {
        while (srv_events_next(h, probe, &got) == SRV_EV_HEARTBEAT)
            ; /* until it waits: the wake then means a period ended after this point */
        CHECK(wait_woken(&cp, k, 30000) == k);
    }
    pthread_mutex_lock(&cc.mu);
    CHECK(cc.wakes == 1);
    pthread_mutex_unlock(&cc.mu);
    CHECK(srv_events_next(h, c, &got) == SRV_EV_HEARTBEAT);
    srv_events_shutdown(h);
    CHECK(srv_events_next(h, c, &got) == SRV_EV_CLOSED);
    srv_events_unsubscribe(h, c);
    srv_events_unsubscribe(h, probe);
    srv_events_close(h);
}

/* ---- setup, stored points and the pixel extraction ---- */

static void test_setup_json(void)
{
    scan_setup_t su = {.centre = {1.0 / 3, -2e-7, 12345.678901234567},
                       .exposure_us = 10331.38,
                       .gain = 1,
                       .pitch_um = 6,
                       .bias_dn = 100,
                       .gain_e_per_dn = 3.153,
                       .read_noise_e = 5.67,
                       .full_scale_dn = 16383,
                       .spot_radius_um = 1.342,
                       .imbalance_x = NAN,
                       .imbalance_y = 0.1,
                       .neighbour_fraction = 0.04,
                       .peak_dn = 6483.5,
                       .centre_iterations = 4,
                       .focus_evaluations = 65},
                 back;
    char *text = srv_setup_dump(&su);
    CHECK(text && srv_setup_parse(text, &back, NULL) == 0);
    CHECK(back.centre.x_um == su.centre.x_um && back.centre.y_um == su.centre.y_um);
    CHECK(back.centre.z_um == su.centre.z_um && back.exposure_us == su.exposure_us);
    CHECK(isnan(back.imbalance_x) && back.imbalance_y == 0.1 && back.focus_evaluations == 65);
    CHECK(back.gain_e_per_dn == 3.153 && back.spot_radius_um == 1.342);
    free(text);
    err_t err = {{0}};
    CHECK(srv_setup_parse("{\"exposure_us\": 1}", &back, &err) == -EINVAL);
    CHECK(strstr(err.msg, "centre_um") != NULL);
}

/* Stores every point of raster r as scan id of st (with its setup). */
static int64_t store_raster(storage_t *st, const scan_raster_t *r)
{
    storage_sensor_t sn = {.model = "SIM",
                           .serial = "1",
                           .n_cols = 256,
                           .n_rows = 256,
                           .pitch_um = 6,
                           .gain_e_per_dn = 3.153,
                           .read_noise_e = 5.67,
                           .bias_dn = 100,
                           .full_scale_dn = 16383};
    int64_t sensor = 0, scan = 0;
    CHECK(storage_sensor_create(st, &sn, &sensor, NULL) == 0);
    storage_scan_t sc = {.sensor_id = sensor,
                         .poi_col = r->cfg.poi_col,
                         .poi_row = r->cfg.poi_row,
                         .wavelength_um = 0.55,
                         .na = 0.25,
                         .spot_radius_um = r->cfg.spot_radius_um,
                         .area_px = r->cfg.area_px,
                         .step_um = r->cfg.step_um,
                         .sub_px = r->m,
                         .frames = r->cfg.frames,
                         .exposure_us = r->setup.exposure_us,
                         .points_total = (int)r->count};
    CHECK(storage_scan_create(st, &sc, &scan, NULL) == 0);
    CHECK(storage_scan_set_state(st, scan, STORAGE_RUNNING, NULL, NULL) == 0);
    char *text = srv_setup_dump(&r->setup);
    CHECK(storage_scan_set_setup(st, scan, text, NULL) == 0);
    free(text);
    size_t mm = (size_t)r->m * r->m;
    for (size_t i = 0; i < r->count; i++) {
        storage_frame_t f = {.scan_id = scan,
                             .point_index = (int)i,
                             .stage_x_um = r->pos[i].x_um,
                             .stage_y_um = r->pos[i].y_um,
                             .stage_z_um = r->pos[i].z_um,
                             .exposure_us = r->setup.exposure_us,
                             .frames = r->cfg.frames,
                             .sub_px = r->m,
                             .raw = r->raw + i * mm * r->cfg.frames,
                             .mean = r->mean_dn + i * mm};
        CHECK(storage_frame_put(st, &f, NULL) == 0);
    }
    return scan;
}

static void test_pixel_scan(void)
{
    sim_config_t sc = sim_config_default();
    sc.seed = 3;
    sim_t *sim = NULL;
    err_t err = {{0}};
    CHECK(sim_open(&sc, &sim, &err) == 0);
    scan_config_t c = scan_config_default();
    c.poi_col = c.poi_row = 100;
    c.spot_radius_um = sim_spot_radius0(sim);
    c.start = sim_pixel_centre(sim, 100, 100);
    c.start.x_um += 0.4; /* the setup has to find the centre: it is not a round number */
    c.area_px = 3;
    c.step_um = 1.0;
    c.subframe_px = 3;
    c.frames = 2;
    c.keep_frames = 1;
    scan_raster_t r;
    CHECK(scan_run(sim_camera(sim), sim_stage(sim), &c, NULL, &r, &err) == 0);
    char path[600];
    snprintf(path, sizeof path, "%s/pixel.db", tmpdir);
    storage_t *st = NULL;
    CHECK(storage_open(path, &st, &err) == 0);
    storage_scan_t row;
    CHECK(storage_scan_get(st, store_raster(st, &r), &row, NULL) == 0);
    /* What each pixel's scan file must hold, worked out from the raster's geometry and the
     * camera's own frames, not by the extraction code: the raster is 19 x 19 points in 1 um steps
     * centred on the found centre, so pixel (dcol, drow) sees the 5 x 5 points at 1..5 um from
     * its corner (row-major, y downward), and each point's signal is the mean of the point's two
     * raw frames at that sub-frame pixel. */
    const double p = 6.0, R = 1.22 * 0.55 / (2 * 0.25); /* the bench's pitch; eq. 1 by hand */
    int pix[][2] = {{0, 0}, {1, -1}, {-1, 0}}, nx = 19, h = 9, m = 3;
    CHECK(r.nx == nx && r.count == (size_t)nx * nx);
    for (size_t q = 0; q < 3; q++) {
        int dc = pix[q][0], dr = pix[q][1];
        scanfile_t got, all;
        CHECK(srv_pixel_scan(st, &row, dc, dr, 0, &got, &err) == 0);
        CHECK(got.scan.n == 25); /* 5 x 5 inside at 1 um steps */
        for (size_t k = 0; k < got.scan.n && got.scan.n == 25; k++) {
            int a = (int)(k % 5), b = (int)(k / 5); /* column and row of the point in the pixel */
            int ix = h + a + 1 - 3 + 6 * dc, iy = h + b + 1 - 3 + 6 * dr; /* raster indexes */
            size_t i = (size_t)iy * nx + (size_t)ix, at = (size_t)(1 + dr) * m + (size_t)(1 + dc);
            const uint16_t *f0 = r.raw + i * 2 * (size_t)(m * m), *f1 = f0 + m * m;
            CHECK(fabs(got.x_um[k] - (a + 1)) < 1e-9 && fabs(got.y_um[k] - (b + 1)) < 1e-9);
            CHECK(got.signal_dn[k] == (f0[at] + f1[at]) / 2.0);
        }
        CHECK(got.scan.pitch_um == p && got.scan.bias_dn == 100 && got.scan.frames == 2);
        CHECK(got.scan.gain_e_per_dn == 3.153 && got.scan.read_noise_e == 5.67);
        CHECK(got.scan.full_scale_dn == 16383 && fabs(got.scan.spot_radius_um - R) < 1e-12);
        CHECK(srv_pixel_scan(st, &row, dc, dr, 1, &all, &err) == 0);
        CHECK(all.scan.n == r.count); /* all = 1: every point, also outside the pixel */
        scanfile_free(&got);
        scanfile_free(&all);
    }
    scanfile_t none;
    CHECK(srv_pixel_scan(st, &row, 2, 0, 0, &none, &err) == -EINVAL);
    storage_scan_free(&row);
    scan_raster_free(&r);
    storage_close(st);
    unlink(path);
    sim_close(sim);
}

/* ---- the fit a fit job runs, against the published fits of tests/data/paperlike_scan.json ---- */

static int steps_seen;
static double last_fraction;
static void on_fit_progress(double fraction, void *user)
{
    (void)user;
    CHECK(fraction > last_fraction && fraction <= 1);
    last_fraction = fraction;
    steps_seen++;
}

/* The published paper-noise fits r = 1..7: chi2, AIC and BIC by r, the r = 7 map and F-test. */
struct published_fits {
    double chi2[8], aic[8], bic[8], S7[49], F, p_value, chi2_h0;
    int params[8];
};

static int published_fits(json_t *root, struct published_fits *p)
{
    size_t i;
    json_t *f;
    int n = 0;
    json_array_foreach(json_object_get(root, "fits"), i, f)
    {
        int r = (int)json_integer_value(json_object_get(f, "r"));
        if (strcmp(json_string_value(json_object_get(f, "noise")), "paper") || r < 1 || r > 7)
            continue;
        p->chi2[r] = json_number_value(json_object_get(f, "chi2"));
        p->aic[r] = json_number_value(json_object_get(f, "aic"));
        p->bic[r] = json_number_value(json_object_get(f, "bic"));
        p->params[r] = (int)json_integer_value(json_object_get(f, "params"));
        n++;
        if (r != 7) continue;
        json_t *S = json_object_get(f, "S_normalised_mean1_rowmajor_y_then_x"),
               *t = json_object_get(f, "ftest_H0_top_left_bottom_edges");
        for (size_t j = 0; j < 49; j++) p->S7[j] = json_number_value(json_array_get(S, j));
        p->F = json_number_value(json_object_get(t, "F"));
        p->p_value = json_number_value(json_object_get(t, "p_value"));
        p->chi2_h0 = json_number_value(json_object_get(t, "chi2_H0"));
    }
    return n == 7 ? 0 : -1;
}

static void test_fit_run(void)
{
    scanfile_t sf;
    err_t err = {{0}};
    json_error_t je;
    json_t *ref = json_load_file("paperlike_scan.json", 0, &je);
    struct published_fits pub;
    memset(&pub, 0, sizeof pub);
    CHECK(ref && published_fits(ref, &pub) == 0);
    CHECK(scanfile_read("paperlike_scan.json", &sf, NULL, &err) == 0);
    /* the automatic fit of a scan (F-test top, left, bottom at r = 7, Wiener) over r = 1..7: the
     * published AIC and BIC fall all the way to 7, so the calibration is the published r = 7 map */
    int best_aic = 1, best_bic = 1;
    for (int r = 2; r <= 7; r++) {
        if (pub.aic[r] < pub.aic[best_aic]) best_aic = r;
        if (pub.bic[r] < pub.bic[best_bic]) best_bic = r;
    }
    CHECK(best_aic == 7 && best_bic == 7);
    srv_fit_params_t p = srv_fit_params_auto(1);
    p.r_max = 7;
    srv_fit_out_t out;
    atomic_int stop = 0;
    srv_fit_hooks_t hooks = {.stop = &stop, .progress = on_fit_progress};
    CHECK(srv_fit_run(&sf.scan, &p, &hooks, &out, &err) == 0);
    CHECK(steps_seen == 7 + 2 && last_fraction == 1); /* r = 1..7, F-test, Wiener */
    CHECK(out.best_aic == best_aic && out.best_bic == best_bic && out.r == best_bic);
    for (int c = 0; out.S && c < 49; c++) CHECK_NEAR(out.S[c], pub.S7[c], 0, 1e-6);
    CHECK(out.S && out.S_err && strcmp(out.status, "ok") == 0);
    CHECK_NEAR(out.chi2_red, pub.chi2[7] / (81 - pub.params[7]), 1e-8, 0);
    CHECK_NEAR(out.f_value, pub.F, 1e-6, 0);
    CHECK_NEAR(out.p_value, pub.p_value, 1e-6, 0);
    /* the stored document is the `ips fit` one, with the published numbers */
    json_t *fits = json_object_get(out.result, "fits"), *ft = json_object_get(out.result, "ftest");
    CHECK(json_array_size(fits) == 7);
    for (int r = 1; r <= 7 && json_array_size(fits) == 7; r++) {
        json_t *f = json_array_get(fits, (size_t)r - 1);
        CHECK(json_integer_value(json_object_get(f, "r")) == r);
        CHECK_NEAR(json_real_value(json_object_get(f, "chi2")), pub.chi2[r], 1e-8, 0);
        CHECK_NEAR(json_real_value(json_object_get(f, "bic")), pub.bic[r], 0, 1e-6);
    }
    CHECK_NEAR(json_real_value(json_object_get(ft, "chi2_H0")), pub.chi2_h0, 1e-8, 0);
    CHECK_NEAR(json_real_value(json_object_get(ft, "chi2_H1")), pub.chi2[7], 1e-8, 0);
    CHECK(json_integer_value(json_object_get(json_object_get(out.result, "wiener"), "nx")) == 9);
    CHECK(json_integer_value(json_object_get(json_object_get(out.result, "best_r"), "bic")) == 7);
    json_t *timing = json_object_get(out.result, "timing_ms");
    CHECK(json_object_get(timing, "sweep") && json_object_get(timing, "ftest") &&
          json_object_get(timing, "wiener") && json_object_get(timing, "total"));
    srv_fit_out_free(&out);
    /* without its last point (5.4, 5.4) the raster is no grid for Wiener, and an r = 9 F-test
     * has 82 parameters for 80 points: both parts say so in the document, the fit is stored */
    fit_scan_t holey = sf.scan;
    holey.n--;
    p.ftest_r = 9;
    CHECK(srv_fit_run(&holey, &p, NULL, &out, &err) == 0);
    json_t *ftest_error = json_object_get(json_object_get(out.result, "ftest"), "error"),
           *wiener_error = json_object_get(json_object_get(out.result, "wiener"), "error");
    CHECK(json_is_string(ftest_error) && strstr(json_string_value(ftest_error), "r = 9"));
    CHECK(json_is_string(wiener_error) && strstr(json_string_value(wiener_error), "grid"));
    CHECK(isnan(out.f_value) && isnan(out.p_value) && out.r > 0);
    srv_fit_out_free(&out);
    /* a stop flag set before the run: stopped before the first fit, nothing kept */
    atomic_store(&stop, 1);
    steps_seen = 0;
    CHECK(srv_fit_run(&sf.scan, &p, &hooks, &out, &err) == -ECANCELED && !out.result);
    CHECK(steps_seen == 0 && out.r == 0 && !out.S);
    srv_fit_out_free(&out);
    p.r_min = 5;
    p.r_max = 4;
    atomic_store(&stop, 0);
    CHECK(srv_fit_run(&sf.scan, &p, NULL, &out, &err) == -EINVAL && strstr(err.msg, "r_min"));
    srv_fit_out_free(&out);
    scanfile_free(&sf);
    json_decref(ref);
}

/* ---- parameters, command line ---- */

static void test_params(void)
{
    srv_fit_params_t p = srv_fit_params_auto(42), back;
    char edges[64];
    CHECK(strcmp(srv_edges_text(p.ftest_edges, edges, sizeof edges), "top,left,bottom") == 0);
    p.opts.noise = FIT_NOISE_SHOT_READ;
    p.drow = -1;
    char *text = srv_fit_params_dump(&p);
    CHECK(text && srv_fit_params_parse(text, &back, NULL) == 0);
    CHECK(back.scan_id == 42 && back.r_min == 1 && back.r_max == 8 && back.ftest_r == 7);
    CHECK(back.ftest_edges == (FIT_EDGE_TOP | FIT_EDGE_LEFT | FIT_EDGE_BOTTOM) && back.wiener);
    CHECK(back.opts.noise == FIT_NOISE_SHOT_READ && back.drow == -1 && !back.scan_file);
    free(text);
    srv_fit_params_free(&back);
    CHECK(srv_fit_params_parse("{\"r_max\": 3}", &back, NULL) == -EINVAL); /* no scan at all */
    srv_fit_params_free(&back);
    /* promotion and provenance: the automatic fit's, a re-fit's (not promoted), and a job queued
     * before "promote" existed, whose map became the calibration (it still does) */
    CHECK(p.promote && strcmp(p.by, "ipsd") == 0);
    CHECK(strcmp(p.reason, "automatic fit of scan 42") == 0);
    p = srv_fit_params_default();
    p.scan_id = 5;
    snprintf(p.reason, sizeof p.reason, "why \"not\"");
    CHECK(!p.promote && !p.by[0]);
    text = srv_fit_params_dump(&p);
    CHECK(text && strstr(text, "\"promote\":false") && !strstr(text, "\"by\""));
    CHECK(text && srv_fit_params_parse(text, &back, NULL) == 0 && !back.promote);
    CHECK(strcmp(back.reason, "why \"not\"") == 0 && !back.by[0]);
    free(text);
    srv_fit_params_free(&back);
    CHECK(srv_fit_params_parse("{\"scan_id\": 3}", &back, NULL) == 0 && back.promote == 1);
    srv_fit_params_free(&back);
}

static int parse(srv_config_t *c, err_t *err, int argc, ...)
{
    char *argv[16] = {"ipsd"};
    va_list ap;
    va_start(ap, argc);
    for (int i = 1; i < argc; i++)
        argv[i] = va_arg(ap, char *);
    va_end(ap);
    *c = srv_config_default();
    return srv_config_parse(argc, argv, c, err);
}

static void test_config(void)
{
    srv_config_t c;
    err_t err = {{0}};
    CHECK(parse(&c, &err, 1) == 0 && c.port == 8080 && strcmp(c.host, "127.0.0.1") == 0);
    CHECK(c.workers == 2 && c.max_body == 4u << 20 && c.n_tokens == 0 && !c.reads_closed &&
          strcmp(c.bench, "sim") == 0);
    CHECK(!c.cors_origin[0] && !c.access_log[0] && !c.backup_dir[0] && !c.backup_out[0]);
    CHECK(parse(&c, &err, 5, "--listen", "[::1]:9000", "--workers", "3") == 0);
    CHECK(strcmp(c.host, "::1") == 0 && c.port == 9000 && c.workers == 3);
    CHECK(parse(&c, &err, 3, "--listen", "127.0.0.1:70000") == -EINVAL && strstr(err.msg, "port"));
    CHECK(parse(&c, &err, 3, "--bench", "usb") == -EINVAL && strstr(err.msg, "bench"));
    CHECK(parse(&c, &err, 3, "--max-body", "10") == -EINVAL && strstr(err.msg, "max-body"));
    /* the jitter request's bound on its Airy integrals: default 4e7, 1e5..2e9 */
    CHECK(parse(&c, &err, 1) == 0 && c.max_jitter_evals == 40000000);
    CHECK(parse(&c, &err, 3, "--max-jitter-evals", "5000000") == 0 && c.max_jitter_evals == 5000000);
    CHECK(parse(&c, &err, 3, "--max-jitter-evals", "99999") == -EINVAL &&
          strstr(err.msg, "max-jitter-evals"));
    CHECK(parse(&c, &err, 2, "--frobnicate") == -EINVAL && strstr(err.msg, "frobnicate"));
    CHECK(parse(&c, &err, 2, "--db") == -EINVAL && strstr(err.msg, "--db"));
    char path[600];
    snprintf(path, sizeof path, "%s/token", tmpdir);
    FILE *f = fopen(path, "w");
    fputs("\n  abc-123 \n", f);
    fclose(f);
    /* the digest of "abc-123" by another implementation: printf abc-123 | sha256sum */
    static const char abc_sha[] =
        "sha256:5942d94f524882e0f29bf0a1e5a6dcc952eea1c0c21dd3588a3fc7db9716db0c";
    CHECK(parse(&c, &err, 3, "--token", path) == 0 && c.n_tokens == 1 &&
          c.tokens[0].level == SRV_TOKEN_WRITE);
    char line[SRV_TOKEN_HASH_LINE];
    srv_token_hash_line("abc-123", 7, line);
    CHECK(strcmp(line, abc_sha) == 0);
    CHECK(srv_token_level(&c, "abc-123", 7) == SRV_TOKEN_WRITE);
    CHECK(srv_token_level(&c, "abc-12", 6) == SRV_TOKEN_NONE);
    CHECK(srv_token_level(&c, "abc-1234", 8) == SRV_TOKEN_NONE);
    srv_config_free(&c);
    CHECK(c.n_tokens == 0 && srv_token_level(&c, "abc-123", 7) == SRV_TOKEN_NONE);
    /* several lines: a comment, the hash line of abc-123 (upper-case hex), a plain token */
    char rpath[600];
    snprintf(rpath, sizeof rpath, "%s/read-token", tmpdir);
    f = fopen(rpath, "w");
    fputs("# lab readers\nSHA256:x\n", f);
    fclose(f);
    CHECK(parse(&c, &err, 5, "--token", path, "--read-token", rpath) == 0 && c.n_tokens == 2 &&
          c.reads_closed); /* "SHA256:x" is not the prefix (case matters): a plain token */
    f = fopen(rpath, "w");
    fprintf(f, "# lab readers\n\n  sha256:5942D94F524882E0F29BF0A1E5A6DCC952EEA1C0C21DD3588A3FC7DB9716DB0C\n"
               "reader-2\n");
    fclose(f);
    CHECK(parse(&c, &err, 3, "--read-token", rpath) == -EINVAL && strstr(err.msg, "--token"));
    f = fopen(path, "w");
    fputs("writer-1\n", f);
    fclose(f);
    CHECK(parse(&c, &err, 5, "--token", path, "--read-token", rpath) == 0 && c.n_tokens == 3);
    CHECK(srv_token_level(&c, "abc-123", 7) == SRV_TOKEN_READ);
    CHECK(srv_token_level(&c, "reader-2", 8) == SRV_TOKEN_READ);
    CHECK(srv_token_level(&c, "writer-1", 8) == SRV_TOKEN_WRITE);
    CHECK(srv_token_level(&c, "sha256:5942d94f524882e0f29bf0a1e5a6dcc952eea1c0c21dd3588a3fc7db97"
                              "16db0c", 71) == SRV_TOKEN_NONE); /* the hash is not a token */
    f = fopen(rpath, "w");
    fputs("sha256:5942d94f\n", f);
    fclose(f);
    CHECK(parse(&c, &err, 5, "--token", path, "--read-token", rpath) == -EINVAL &&
          strstr(err.msg, "line 1") && strstr(err.msg, "64 hex"));
    f = fopen(rpath, "w");
    fputs("two words\n", f);
    fclose(f);
    CHECK(parse(&c, &err, 5, "--token", path, "--read-token", rpath) == -EINVAL &&
          strstr(err.msg, "whitespace"));
    unlink(rpath);
    CHECK(parse(&c, &err, 3, "--cors-origin", "https://lab.example:8443") == 0 &&
          strcmp(c.cors_origin, "https://lab.example:8443") == 0);
    CHECK(parse(&c, &err, 3, "--cors-origin", "https://lab.example/x") == -EINVAL &&
          strstr(err.msg, "cors-origin"));
    CHECK(parse(&c, &err, 3, "--cors-origin", "a\r\nX: y") == -EINVAL);
    CHECK(parse(&c, &err, 3, "--access-log", "-") == 0 && !c.access_log[0]);
    CHECK(parse(&c, &err, 3, "--access-log", "off") == 0 && strcmp(c.access_log, "off") == 0);
    f = fopen(path, "w");
    fputs(" \n", f);
    fclose(f);
    CHECK(parse(&c, &err, 3, "--token", path) == -EINVAL && strstr(err.msg, "empty"));
    unlink(path);
}

/* Event-stream tickets (srv_token.h): "EXPIRY.MAC" with EXPIRY = now + ttl, valid strictly
 * before EXPIRY on the clock given, and nothing altered passes. */
static void test_tickets(void)
{
    char t[SRV_TICKET_MAX], u[2 * SRV_TICKET_MAX];
    err_t err = {{0}};
    CHECK(srv_token_ticket(1000, 60000, t, &err) == 0);
    CHECK(strncmp(t, "61000.", 6) == 0 && strlen(t) == 6 + 64);
    CHECK(strspn(t + 6, "0123456789abcdef") == 64);
    CHECK(srv_token_ticket_check(t, 1000) == 1);
    CHECK(srv_token_ticket_check(t, 60999) == 1);
    CHECK(srv_token_ticket_check(t, 61000) == 0); /* expired */
    CHECK(srv_token_ticket_check(t, 1000000) == 0);
    snprintf(u, sizeof u, "%s", t);
    u[strlen(u) - 1] = u[strlen(u) - 1] == '0' ? '1' : '0'; /* the MAC altered */
    CHECK(srv_token_ticket_check(u, 1000) == 0);
    snprintf(u, sizeof u, "9%s", t); /* the expiry moved later, the MAC kept */
    CHECK(srv_token_ticket_check(u, 1000) == 0);
    snprintf(u, sizeof u, "%.*s", (int)strlen(t) - 1, t); /* truncated */
    CHECK(srv_token_ticket_check(u, 1000) == 0);
    CHECK(srv_token_ticket_check("", 0) == 0 && srv_token_ticket_check(NULL, 0) == 0);
    CHECK(srv_token_ticket_check(".", 0) == 0 && srv_token_ticket_check("61000", 0) == 0);
    char v[SRV_TICKET_MAX];
    CHECK(srv_token_ticket(1000, 60000, v, &err) == 0 && strcmp(v, t) == 0); /* same key */
    CHECK(srv_token_ticket(1001, 60000, v, &err) == 0 && strcmp(v + 6, t + 6) != 0);
}

int main(void)
{
    const char *base = getenv("TMPDIR");
    snprintf(tmpdir, sizeof tmpdir, "%s/ipsd-test-server-XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(tmpdir)) return 1;
    test_events();
    test_setup_json();
    test_pixel_scan();
    test_fit_run();
    test_params();
    test_config();
    test_tickets();
    char wal[600];
    snprintf(wal, sizeof wal, "%s/pixel.db-wal", tmpdir);
    unlink(wal);
    snprintf(wal, sizeof wal, "%s/pixel.db-shm", tmpdir);
    unlink(wal);
    CHECK(rmdir(tmpdir) == 0);
    CHECK_DONE();
}
