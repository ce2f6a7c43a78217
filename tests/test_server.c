/* test_server.c: pieces of the server core (server/) without HTTP: the event hub (order, waiting
 * and waking, dropped events, heartbeats, shutdown), the scan setup's JSON round trip, the pixel
 * extraction from stored points against the instrument's own extraction from the raster in memory
 * (scan_extract_pixel, an independent implementation), the job parameters, the raster size rule of
 * the paper (51 x 51 points), and the command line. */
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

#include <gsl/gsl_errno.h>

#include "base/clock.h"
#include "instrument/scan.h"
#include "check.h"
#include "instrument/scanfile.h"
#include "instrument/sim.h"
#include "server/srv.h"
#include "server/srv_config.h"
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
    int pix[][2] = {{0, 0}, {1, -1}, {-1, 0}};
    for (size_t q = 0; q < 3; q++) {
        scanfile_t want, got, all;
        CHECK(scan_extract_pixel(&r, pix[q][0], pix[q][1], &want, &err) == 0);
        CHECK(srv_pixel_scan(st, &row, pix[q][0], pix[q][1], 0, &got, &err) == 0);
        CHECK(got.scan.n == want.scan.n && want.scan.n == 25); /* 5 x 5 inside at 1 um steps */
        for (size_t k = 0; k < want.scan.n && got.scan.n == want.scan.n; k++)
            CHECK(got.x_um[k] == want.x_um[k] && got.y_um[k] == want.y_um[k] &&
                  got.signal_dn[k] == want.signal_dn[k]);
        CHECK(memcmp(&got.scan.pitch_um, &want.scan.pitch_um,
                     sizeof(fit_scan_t) - offsetof(fit_scan_t, pitch_um)) == 0);
        CHECK(srv_pixel_scan(st, &row, pix[q][0], pix[q][1], 1, &all, &err) == 0);
        CHECK(all.scan.n == r.count); /* all = 1: every point, also outside the pixel */
        scanfile_free(&want);
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

/* ---- the fit a fit job runs: the same numbers as fit_sweep_run (what `ips fit` calls) ---- */

static int steps_seen;
static double last_fraction;
static void on_fit_progress(double fraction, void *user)
{
    (void)user;
    CHECK(fraction > last_fraction && fraction <= 1);
    last_fraction = fraction;
    steps_seen++;
}

static void test_fit_run(void)
{
    scanfile_t sf;
    err_t err = {{0}};
    CHECK(scanfile_read("paperlike_scan.json", &sf, NULL, &err) == 0);
    srv_fit_params_t p = srv_fit_params_auto(1);
    srv_fit_out_t out;
    fit_sweep_t sw;
    atomic_int stop = 0;
    srv_fit_hooks_t hooks = {.stop = &stop, .progress = on_fit_progress};
    CHECK(srv_fit_run(&sf.scan, &p, &hooks, &out, &err) == 0);
    CHECK(steps_seen == 8 + 2 && last_fraction == 1); /* r = 1..8, F-test, Wiener */
    CHECK(fit_sweep_run(&sf.scan, 1, 8, &p.opts, &sw, &err) == 0);
    CHECK(out.best_aic == sw.best_aic && out.best_bic == sw.best_bic && out.r == sw.best_bic);
    const fit_result_t *best = &sw.fits[sw.best_bic - 1];
    size_t n = (size_t)out.r * out.r;
    CHECK(out.S && memcmp(out.S, best->S, n * sizeof(double)) == 0);
    CHECK(out.S_err && memcmp(out.S_err, best->S_err, n * sizeof(double)) == 0);
    CHECK(out.I0 == best->I0 && out.chi2_red == best->chi2_red);
    fit_ftest_t t;
    CHECK(fit_ftest_run(&sf.scan, 7, p.ftest_edges, &p.opts, &t, &err) == 0);
    CHECK(out.f_value == t.F && out.p_value == t.p_value);
    json_t *fits = json_object_get(out.result, "fits");
    CHECK(json_array_size(fits) == 8 && json_object_get(out.result, "wiener"));
    CHECK(json_real_value(json_object_get(json_array_get(fits, 7), "chi2")) == sw.fits[7].chi2);
    fit_sweep_free(&sw);
    srv_fit_out_free(&out);
    /* a stop flag set before the run: stopped before the first fit, nothing kept */
    atomic_store(&stop, 1);
    CHECK(srv_fit_run(&sf.scan, &p, &hooks, &out, &err) == -ECANCELED && !out.result);
    srv_fit_out_free(&out);
    p.r_min = 5;
    p.r_max = 4;
    atomic_store(&stop, 0);
    CHECK(srv_fit_run(&sf.scan, &p, NULL, &out, &err) == -EINVAL && strstr(err.msg, "r_min"));
    srv_fit_out_free(&out);
    scanfile_free(&sf);
}

/* ---- parameters, raster size, command line ---- */

static void test_params(void)
{
    CHECK(srv_raster_points(6.0, 5, 0.6) == 51); /* the paper: 5 x 5 pixels in 0.6 um steps */
    CHECK(srv_raster_points(6.0, 3, 1.0) == 19);
    CHECK(srv_raster_points(6.0, 5, 0.7) == 0 && srv_raster_points(6.0, 5, -0.6) == 0);
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
    CHECK(c.workers == 2 && c.max_body == 4u << 20 && !c.token && strcmp(c.bench, "sim") == 0);
    CHECK(parse(&c, &err, 5, "--listen", "[::1]:9000", "--workers", "3") == 0);
    CHECK(strcmp(c.host, "::1") == 0 && c.port == 9000 && c.workers == 3);
    CHECK(parse(&c, &err, 3, "--listen", "127.0.0.1:70000") == -EINVAL && strstr(err.msg, "port"));
    CHECK(parse(&c, &err, 3, "--bench", "usb") == -EINVAL && strstr(err.msg, "bench"));
    CHECK(parse(&c, &err, 3, "--max-body", "10") == -EINVAL && strstr(err.msg, "max-body"));
    CHECK(parse(&c, &err, 2, "--frobnicate") == -EINVAL && strstr(err.msg, "frobnicate"));
    CHECK(parse(&c, &err, 2, "--db") == -EINVAL && strstr(err.msg, "--db"));
    char path[600];
    snprintf(path, sizeof path, "%s/token", tmpdir);
    FILE *f = fopen(path, "w");
    fputs("\n  abc-123 \n", f);
    fclose(f);
    CHECK(parse(&c, &err, 3, "--token", path) == 0 && c.token && strcmp(c.token, "abc-123") == 0);
    srv_config_free(&c);
    f = fopen(path, "w");
    fputs(" \n", f);
    fclose(f);
    CHECK(parse(&c, &err, 3, "--token", path) == -EINVAL && strstr(err.msg, "empty"));
    unlink(path);
}

int main(void)
{
    gsl_set_error_handler_off();
    const char *base = getenv("TMPDIR");
    snprintf(tmpdir, sizeof tmpdir, "%s/ipsd-test-server-XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(tmpdir)) return 1;
    test_events();
    test_setup_json();
    test_pixel_scan();
    test_fit_run();
    test_params();
    test_config();
    char wal[600];
    snprintf(wal, sizeof wal, "%s/pixel.db-wal", tmpdir);
    unlink(wal);
    snprintf(wal, sizeof wal, "%s/pixel.db-shm", tmpdir);
    unlink(wal);
    CHECK(rmdir(tmpdir) == 0);
    CHECK_DONE();
}
