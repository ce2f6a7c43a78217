/* srv_scanner.c: the scan worker, the one thread that owns the instrument. It takes scan jobs in
 * order, runs the scan procedure (instrument/scan.h: exposure, centring, focus, then the raster)
 * on the configured bench and stores every raster point as it comes, one transaction per point
 * (storage_frame_put), so a crash loses at most the point in flight. The setup is stored before
 * the raster: a resumed scan continues at the point after its last stored one with the same
 * positions. When the raster is complete the scan is done and the fit of its POI is queued.
 * Cancel (the worker's stop flag, or the database refusing the next point) stops between points;
 * a graceful shutdown gives the job back to the queue. Photon-transfer measurements need the
 * instrument too: this worker takes them in queue order with the scans (srv_ptc.c runs them).
 * An adaptive scan (its strategy, srv_params.h) takes its points batch by batch where the map is
 * least sure instead of the raster (srv_adaptive.c), stored as raster points in the order taken;
 * when it stops, its points_total becomes the points taken and its setup records why it stopped.
 *
 * Storage faults (disk full, read-only, I/O errors): the point that cannot be stored
 * fails the scan and its job with the database's error, the instrument is released, and the
 * worker takes the next job. When even recording the failure cannot be written, the failure is
 * kept in memory (srv_scan_unrecorded, shown by GET /api/health) and the worker retries writing
 * it with a growing pause until it succeeds or ipsd stops; the job is then never left running. */
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "instrument/scan.h"
#include "server/srv_setup.h"
#include "srv_adaptive.h"
#include "srv_bench.h"
#include "srv_failpoint.h"
#include "srv_int.h"

#define HEARTBEAT_S 1.0 /* a running scan job writes its heartbeat and progress this often */
#define RECORD_RETRY_MIN_MS 100  /* first pause before writing an unrecorded failure again */
#define RECORD_RETRY_MAX_MS 5000 /* the pause doubles up to this */

/* One scan job being run. */
struct scan_run {
    srv_t *srv;
    srv_worker_t *w;
    storage_t *st;
    storage_job_t *job;
    storage_scan_t scan;
    storage_sensor_t sensor;
    srv_bench_t bench;
    srv_scan_params_t params;
    scan_config_t cfg;
    scan_setup_t setup;
    int first;            /* first raster point captured by this run */
    double t0, last_beat; /* when this run's raster started, last heartbeat (srv_now_s) */
    double expected_err;  /* an adaptive scan: the map's expected error at the last plan */
    int store_rc;         /* why store_point stopped the raster, 0 if it did not */
    err_t store_err;      /* and its error (the raster's own "stopped by the handler" is not) */
    err_t err;
};

/* Publishes the job's progress (the row is not re-read: the run knows it). */
static void publish(struct scan_run *r, const char *phase, int done, double eta_s)
{
    storage_job_t j = *r->job;
    j.state = STORAGE_RUNNING;
    j.points_done = done;
    j.progress = r->scan.points_total ? (double)done / r->scan.points_total : 0;
    j.error = NULL;
    if (r->params.strategy.adaptive) /* no ETA: the scan's length is the planner's to say */
        srv_publish_job_adaptive(r->srv, &j, phase, r->scan.points_total, r->expected_err);
    else
        srv_publish_job(r->srv, &j, phase, r->scan.points_total, eta_s);
}

static void on_progress(const char *phase, size_t done, size_t total, void *user)
{
    (void)done;
    (void)total;
    struct scan_run *r = user;
    if (strcmp(phase, "raster") != 0 && strcmp(phase, "adaptive") != 0)
        publish(r, phase, r->first, NAN);
}

/* hooks->point: stores one captured point, beats the heart, publishes the progress. A non-zero
 * return stops the raster; store_rc says why. */
static int store_point(const scan_point_t *pt, void *user)
{
    struct scan_run *r = user;
    if (!pt->raw) {
        r->store_rc = err_set(&r->store_err, -EINVAL, "the scan procedure did not keep raw frames");
        return 1;
    }
    storage_frame_t f = {.scan_id = r->scan.id,
                         .point_index = (int)pt->index,
                         .stage_x_um = pt->reported.x_um,
                         .stage_y_um = pt->reported.y_um,
                         .stage_z_um = pt->reported.z_um,
                         .exposure_us = pt->exposure_us,
                         .frames = pt->frames,
                         .sub_px = pt->width,
                         .raw = (uint16_t *)pt->raw,
                         .mean = (double *)pt->mean_dn,
                         .timestamps_ns = (int64_t *)pt->frame_timestamps_ns};
    /* the camera's frame ids, unless it gives none (the simulated bench, libcamera) */
    for (int k = 0; pt->camera_frame_ids && k < pt->frames; k++)
        if (pt->camera_frame_ids[k]) f.camera_frame_ids = (uint64_t *)pt->camera_frame_ids;
    int rc = storage_frame_put(r->st, &f, &r->store_err);
    if (rc && rc != -EEXIST) {
        r->store_rc = rc;
        return 1;
    }
    int done = (int)pt->index + 1, total = r->scan.points_total;
    double now = clock_mono_s();
    if (now - r->last_beat >= HEARTBEAT_S || done == total) {
        r->last_beat = now;
        rc = storage_job_heartbeat(r->st, r->job->id, (double)done / total, done,
                                   &r->store_err);
        if (rc) {
            r->store_rc = rc;
            return 1;
        }
    }
    int run_done = done - r->first;
    double eta = run_done > 0 ? (now - r->t0) / run_done * (total - done) : NAN;
    publish(r, r->params.strategy.adaptive ? "adaptive" : "raster", done, eta);
    if ((r->store_rc = srv_failpoint(r->w, "scan.point", &r->store_err))) return 1; /* test hook */
    return 0;
}

/* The scan procedure's configuration for this scan on this bench. */
static void make_config(struct scan_run *r)
{
    scan_config_t *c = &r->cfg;
    *c = scan_config_default();
    c->poi_col = r->scan.poi_col;
    c->poi_row = r->scan.poi_row;
    c->start = r->bench.start;
    c->area_px = r->scan.area_px;
    c->step_um = r->scan.step_um;
    c->subframe_px = r->scan.sub_px;
    c->frames = r->scan.frames;
    c->exposure_us = r->scan.exposure_us;
    c->keep_frames = 1; /* the database keeps the raw frames */
    c->pitch_um = r->sensor.pitch_um;
    c->bias_dn = r->sensor.bias_dn;
    c->gain_e_per_dn = r->sensor.gain_e_per_dn;
    c->read_noise_e = r->sensor.read_noise_e;
    c->full_scale_dn = r->sensor.full_scale_dn;
    /* the default 16000 DN of a 14-bit ADC, scaled to this sensor's full scale */
    c->saturation_dn = r->sensor.full_scale_dn * (16000.0 / 16383.0);
    c->spot_radius_um = r->scan.spot_radius_um;
    if (r->params.setup_none) /* the POI's centre and the exposure as given */
        c->do_exposure = c->do_centre = c->do_focus = 0;
}

/* A resumed scan runs on the camera that took its stored points: another one (or another
 * backend) is refused naming both. A setup stored without a camera (an older ipsd) passes. */
static int same_camera(struct scan_run *r, const char *stored)
{
    cam_info_t was, now;
    if (srv_setup_camera(stored, &was) || cam_get_info(r->bench.cam, &now, &r->err)) return 0;
    if (strcmp(was.backend, now.backend) == 0 && strcmp(was.serial, now.serial) == 0 &&
        (strcmp(was.backend, "sim") == 0 || strcmp(was.id, now.id) == 0))
        return 0;
    return err_set(&r->err, -EINVAL,
                   "scan %lld was taken with the %s camera %s (serial %s); the bench now has the "
                   "%s camera %s (serial %s): resume it with that camera",
                   (long long)r->scan.id, was.backend, was.id[0] ? was.id : "-",
                   was.serial[0] ? was.serial : "-", now.backend, now.id[0] ? now.id : "-",
                   now.serial[0] ? now.serial : "-");
}

/* The stored setup, or a new one from scan_prepare, stored before the raster starts. */
static int setup(struct scan_run *r, const scan_hooks_t *hooks)
{
    char *text = NULL;
    int ret = storage_scan_get_setup(r->st, r->scan.id, &text, &r->err);
    if (ret) return ret;
    if (text) {
        ret = srv_setup_parse(text, &r->setup, &r->err);
        if (ret == 0) ret = same_camera(r, text);
        free(text);
        return ret;
    }
    cam_info_t cam;
    if ((ret = scan_prepare(r->bench.cam, r->bench.stage, &r->cfg, hooks, &r->setup, &r->err)) ||
        (ret = cam_get_info(r->bench.cam, &cam, &r->err)))
        return ret;
    if (!(text = srv_setup_dump_provenance(&r->setup, &cam, r->params.setup_none)))
        return err_set(&r->err, -ENOMEM, "out of memory");
    ret = storage_scan_set_setup(r->st, r->scan.id, text, &r->err);
    free(text);
    return ret;
}

/* The scan's points are all stored: the scan done, the automatic fit of its POI queued and the
 * job finished, in one transaction (storage_scan_finish): no one sees the scan done without its
 * automatic fit, so a user's re-fit can no longer come first and make it be skipped. */
static int finish_done(struct scan_run *r)
{
    int ret = srv_failpoint(r->w, "scan.finish", &r->err); /* test hook: before the end */
    if (ret) return ret;
    srv_fit_params_t p = srv_fit_params_auto(r->scan.id);
    p.map = (storage_map_t)r->srv->cfg.calibration_map; /* --calibration-map */
    p.krige = p.map == STORAGE_MAP_KRIGED;
    if (r->params.strategy.adaptive) p.wiener = 0; /* Wiener needs a regular grid of points */
    char *params = srv_fit_params_dump(&p);
    if (!params) return err_set(&r->err, -ENOMEM, "out of memory");
    int64_t fit_job = 0;
    ret = storage_scan_finish(r->st, r->scan.id, r->job->id, params, &fit_job, &r->err);
    free(params);
    if (ret || !fit_job) return ret;
    storage_job_t j; /* the fit job's queued event, then a fit worker wakes for it */
    if (storage_job_get(r->st, fit_job, &j, NULL) == 0) {
        srv_publish_job(r->srv, &j, NULL, 0, NAN);
        storage_job_free(&j);
    }
    srv_notify_work(r->srv);
    return 0;
}

/* Loads the scan and its sensor, opens the bench, and marks the scan running. */
static int begin(struct scan_run *r)
{
    srv_scan_params_t *p = &r->params;
    int ret;
    if (!r->job->scan_id) return err_set(&r->err, -EINVAL, "scan job without a scan");
    if ((ret = srv_scan_params_parse(r->job->params, p, &r->err)) ||
        (ret = storage_scan_get(r->st, r->job->scan_id, &r->scan, &r->err)) ||
        (ret = storage_sensor_get(r->st, r->scan.sensor_id, &r->sensor, &r->err)))
        return ret;
    if (r->scan.state == STORAGE_DONE) return 0;
    /* the job must still be ours (not cancelled meanwhile) before the scan is marked running */
    if ((ret = storage_job_heartbeat(r->st, r->job->id, r->job->progress, r->job->points_done,
                                     &r->err)) ||
        (ret = srv_bench_open(r->srv->cfg.bench, r->srv->cfg.stage, &r->sensor, &r->scan, p,
                              r->srv->failpoints ? srv_failpoint_frame : NULL, r->srv,
                              r->srv->cfg.camera_timeout_s, &r->bench, &r->err)))
        return ret;
    make_config(r);
    return storage_scan_set_state(r->st, r->scan.id, STORAGE_RUNNING, NULL, &r->err);
}

static void on_planned(size_t points, double expected_err, void *user)
{
    struct scan_run *r = user;
    r->expected_err = expected_err;
    publish(r, "adaptive", (int)points, NAN);
}

/* An adaptive scan that stopped: its points_total becomes the points taken, and its setup records
 * why it stopped ("adaptive": {"stop", "points", "expected_err"}). Both are repeated as they
 * were when a restart finds the scan stopped already. */
static int adaptive_end(struct scan_run *r, const srv_adaptive_outcome_t *o)
{
    char *text = NULL;
    int ret = storage_scan_set_points_total(r->st, r->scan.id, (int)o->points, &r->err);
    if (ret == 0) ret = storage_scan_get_setup(r->st, r->scan.id, &text, &r->err);
    if (ret) return ret;
    json_t *su = text ? json_loads(text, 0, NULL) : NULL;
    free(text);
    text = NULL;
    if (su)
        json_object_set_new(su, "adaptive",
                            json_pack("{s:s, s:I, s:f}", "stop", fit_adapt_stop_name(o->stop),
                                      "points", (json_int_t)o->points, "expected_err",
                                      o->expected_err));
    if (su) text = json_dumps(su, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(su);
    if (!text) return err_set(&r->err, -ENOMEM, "out of memory");
    ret = storage_scan_set_setup(r->st, r->scan.id, text, &r->err);
    free(text);
    r->scan.points_total = (int)o->points;
    fprintf(stderr, "ipsd: adaptive scan %lld stopped (%s) at %zu points, expected error %.4g; "
                    "%d plans in %.0f ms\n",
            (long long)r->scan.id, fit_adapt_stop_name(o->stop), o->points, o->expected_err,
            o->plans, o->plan_ms);
    return ret;
}

/* Setup and raster from the point after the last stored one. */
static int capture(struct scan_run *r)
{
    scan_hooks_t hooks = {
        .point = store_point, .progress = on_progress, .user = r, .stop = &r->w->stop};
    int last = -1, count = 0;
    int ret = storage_frame_last(r->st, r->scan.id, &last, &count, &r->err);
    r->first = last + 1;
    if (ret == 0) ret = setup(r, &hooks);
    if (ret == 0) ret = srv_failpoint(r->w, "scan.setup", &r->err); /* test hook */
    if (ret) return ret;
    r->t0 = r->last_beat = clock_mono_s();
    if (r->params.strategy.adaptive) {
        srv_adaptive_outcome_t o;
        r->expected_err = NAN;
        publish(r, "adaptive", r->first, NAN);
        ret = srv_adaptive_capture(r->st, &r->scan, r->bench.cam, r->bench.stage, r->bench.sim,
                                   r->params.seed, &r->cfg, &r->setup, &r->params.strategy,
                                   &hooks, on_planned, r, &o, &r->err);
        if (r->store_rc) {
            r->err = r->store_err;
            return r->store_rc;
        }
        return ret ? ret : adaptive_end(r, &o);
    }
    if (r->first >= r->scan.points_total) return ret;
    publish(r, "raster", r->first, NAN);
    ret = scan_raster_run(r->bench.cam, r->bench.stage, &r->cfg, &r->setup, (size_t)r->first,
                          &hooks, NULL, &r->err);
    if (r->store_rc) {
        r->err = r->store_err;
        return r->store_rc;
    }
    return ret;
}

/* Writes the failure of the run: the scan and the job failed with r->err. 0, or the storage
 * error that kept it from being written (a job no longer running, e.g. cancelled meanwhile,
 * needs nothing more). */
static int record_failure(struct scan_run *r, int *scan_written, err_t *e)
{
    int ret = 0;
    if (r->scan.id && !*scan_written) {
        ret = storage_scan_set_state(r->st, r->scan.id, STORAGE_FAILED, r->err.msg, e);
        if (ret && ret != -ENOENT) return ret;
        *scan_written = 1;
    }
    ret = storage_job_finish(r->st, r->job->id, STORAGE_FAILED, r->err.msg, e);
    return ret == -ECANCELED || ret == -ESTALE || ret == -ENOENT ? 0 : ret;
}

/* Records the failure (why: its error code), retrying while the storage refuses it: the failure is kept in memory and
 * shown by GET /api/health meanwhile. Gives up only when ipsd stops (the job, still running in
 * the database, is requeued at the next start and resumes). */
static void fail_job(struct scan_run *r, int why)
{
    err_t e = {{0}};
    int scan_written = 0, pause_ms = RECORD_RETRY_MIN_MS, tries = 1;
    int ret = record_failure(r, &scan_written, &e);
    /* a full disk: the write-ahead log's space back to the file system, if the database file
     * can take its pages now */
    if (why == -ENOSPC) storage_checkpoint(r->st, NULL);
    if (ret == 0) return;
    fprintf(stderr, "ipsd: scan job %lld: cannot record its failure (%s); kept in memory, "
                    "retrying\n",
            (long long)r->job->id, e.msg);
    srv_scan_unrecorded_set(r->srv, r->job->id, r->err.msg);
    while (ret && !atomic_load(&r->srv->stopping)) {
        srv_wait_work(r->srv, pause_ms);
        pause_ms = pause_ms * 2 > RECORD_RETRY_MAX_MS ? RECORD_RETRY_MAX_MS : pause_ms * 2;
        storage_checkpoint(r->st, NULL);
        ret = record_failure(r, &scan_written, &e);
        tries++;
    }
    if (ret == 0)
        fprintf(stderr, "ipsd: scan job %lld: failure recorded after %d tries\n",
                (long long)r->job->id, tries);
    else
        fprintf(stderr, "ipsd: scan job %lld: failure not recorded at shutdown (%s); it is "
                        "requeued at the next start\n",
                (long long)r->job->id, e.msg);
    srv_scan_unrecorded_set(r->srv, 0, NULL);
}

/* After the run stopped with ret: done, cancelled by the user, stopped by the shutdown, or
 * failed. The job row is brought to its final (or queued) state and the event published. The
 * instrument is released already. */
static void conclude(struct scan_run *r, int ret)
{
    storage_t *st = r->st;
    int64_t id = r->job->id;
    if (ret == 0) ret = finish_done(r);
    if (ret == -ECANCELED) {
        /* who stopped us: the user (the job is cancelled), else the shutdown (or a cancel meant
         * for the previous job): the job goes back to the queue and resumes where it stopped */
        int beat = storage_job_heartbeat(st, id, r->job->progress, r->job->points_done, NULL);
        if (beat == -ECANCELED)
            storage_scan_set_state(st, r->scan.id, STORAGE_CANCELLED, NULL, NULL);
        else if (beat == 0)
            storage_job_release(st, id, NULL);
    } else if (ret) {
        fprintf(stderr, "ipsd: scan job %lld failed: %s\n", (long long)id, r->err.msg);
        fail_job(r, ret);
    }
    storage_job_t j;
    if (storage_job_get(st, id, &j, NULL) == 0) {
        srv_publish_job(r->srv, &j, NULL, r->scan.points_total, NAN);
        storage_job_free(&j);
    }
}

static void run_job(srv_worker_t *w, storage_job_t *job)
{
    if (job->kind == STORAGE_JOB_PTC) { /* srv_ptc.c */
        srv_ptc_run_job(w, job);
        return;
    }
    struct scan_run r = {.srv = w->srv, .w = w, .st = w->st, .job = job};
    srv_worker_begin(w, job->id);
    int ret = begin(&r);
    if (ret == 0 && r.scan.state != STORAGE_DONE) ret = capture(&r);
    srv_bench_close(&r.bench); /* the instrument is free before the job's end is written */
    memset(&r.bench, 0, sizeof r.bench);
    conclude(&r, ret);
    srv_worker_end(w);
    storage_sensor_free(&r.sensor);
    storage_scan_free(&r.scan);
}

void srv_scan_unrecorded_set(srv_t *srv, int64_t job_id, const char *msg)
{
    pthread_mutex_lock(&srv->mu);
    srv->unrecorded_job = job_id;
    snprintf(srv->unrecorded_msg, sizeof srv->unrecorded_msg, "%s", msg ? msg : "");
    pthread_mutex_unlock(&srv->mu);
}

int64_t srv_scan_unrecorded(srv_t *srv, char *msg, size_t size)
{
    pthread_mutex_lock(&srv->mu);
    int64_t id = srv->unrecorded_job;
    if (msg && size) snprintf(msg, size, "%s", id ? srv->unrecorded_msg : "");
    pthread_mutex_unlock(&srv->mu);
    return id;
}

void *srv_scanner_main(void *arg)
{
    srv_worker_t *w = arg;
    /* the instrument's jobs, in the order queued: scans and photon-transfer measurements */
    srv_worker_loop(w, STORAGE_JOB_BIT(STORAGE_JOB_SCAN) | STORAGE_JOB_BIT(STORAGE_JOB_PTC),
                    "scan worker", run_job);
    return NULL;
}
