/* srv_ptc.c: photon-transfer jobs (srv_ptc.h; EMVA 1288). The scan worker, the one
 * thread that owns the instrument, runs them between scans in queue order: the simulated bench
 * opened as the sensor (its constants from the database) with the flat-field lamp of
 * sim_set_flat and no spot, the series of flats and darks of instrument/ptc_run.h over the N x N
 * pixels at the array's corner, the analysis of fit/ptc.h, and the report (the `ips ptc` document
 * of json/ptcjson.h plus what was measured) stored in the ptc table together with the job's end
 * (storage_ptc_store_done): a crash leaves the job running with nothing stored (it runs again at
 * the next start) or done with its measurement, never two.
 *
 * A level is a few frames: the job beats its heart and publishes its progress (level k of N)
 * after each, and stops there when cancelled or when ipsd stops (then it goes back to the queue
 * and runs again from the start: a measurement is short and its levels are not stored). Test
 * hooks (srv_failpoint.h): ptc.level after each level, ptc.before_store, ptc.after_store, and
 * camera.frame in the simulated camera. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "base/clock.h"
#include "fit/ptc.h"
#include "instrument/ptc_run.h"
#include "instrument/sim.h"
#include "json/fitjson.h"
#include "json/ptcjson.h"
#include "server/srv_ptc.h"
#include "srv_failpoint.h"
#include "srv_int.h"

#define HEARTBEAT_S 1.0 /* a running measurement writes its heartbeat this often */

/* ---- parameters ---------------------------------------------------------------------------- */

srv_ptc_params_t srv_ptc_params_default(int64_t sensor_id)
{
    return (srv_ptc_params_t){.sensor_id = sensor_id,
                              .levels = SRV_PTC_LEVELS_DEFAULT,
                              .roi_px = SRV_PTC_ROI_DEFAULT,
                              .flat_e = 0,
                              .seed = 1};
}

char *srv_ptc_params_dump(const srv_ptc_params_t *p)
{
    json_t *o =
        json_pack("{s:I, s:i, s:i, s:f, s:I}", "sensor_id", (json_int_t)p->sensor_id, "levels",
                  p->levels, "roi_px", p->roi_px, "flat_e", p->flat_e, "seed", (json_int_t)p->seed);
    char *text = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
    json_decref(o);
    return text;
}

int srv_ptc_params_parse(const char *text, srv_ptc_params_t *p, err_t *err)
{
    json_t *o = json_loads(text, 0, NULL), *v;
    if (!json_is_object(o)) {
        json_decref(o);
        return err_set(err, -EINVAL, "ptc job params: not a JSON object");
    }
    *p = srv_ptc_params_default(0);
    if ((v = json_object_get(o, "sensor_id")) && json_is_integer(v))
        p->sensor_id = json_integer_value(v);
    if ((v = json_object_get(o, "levels")) && json_is_integer(v))
        p->levels = (int)json_integer_value(v);
    if ((v = json_object_get(o, "roi_px")) && json_is_integer(v))
        p->roi_px = (int)json_integer_value(v);
    if ((v = json_object_get(o, "flat_e")) && json_is_number(v)) p->flat_e = json_number_value(v);
    if ((v = json_object_get(o, "seed")) && json_is_integer(v))
        p->seed = (unsigned long)json_integer_value(v);
    json_decref(o);
    if (p->sensor_id <= 0) return err_set(err, -EINVAL, "ptc job params: no sensor_id");
    return 0;
}

/* ---- queueing and the measured constants ---------------------------------------------------- */

int srv_ptc_submit(srv_t *srv, storage_t *st, const srv_ptc_params_t *p, int64_t *job_id,
                   err_t *err)
{
    if (srv_stopping(srv)) return err_set(err, -ESHUTDOWN, "ipsd is shutting down");
    if (strcmp(srv->cfg.bench, "sim") != 0)
        return err_set(err, -ENOTSUP,
                       "photon transfer needs a lamp ipsd can switch: only the simulated bench "
                       "(--bench sim) has one, this ipsd runs --bench %s",
                       srv->cfg.bench);
    storage_sensor_t sn;
    int ret = storage_sensor_get(st, p->sensor_id, &sn, err);
    if (ret) return ret;
    srv_ptc_params_t q = *p;
    /* the N x N corner of the array: at most the array */
    if (q.roi_px > sn.n_cols) q.roi_px = sn.n_cols;
    if (q.roi_px > sn.n_rows) q.roi_px = sn.n_rows;
    storage_sensor_free(&sn);
    if (q.roi_px < 2)
        return err_set(err, -EINVAL, "roi_px: the sensor's array is smaller than 2 x 2 pixels");
    char *params = srv_ptc_params_dump(&q);
    if (!params) return err_set(err, -ENOMEM, "out of memory");
    ret = storage_job_enqueue(st, STORAGE_JOB_PTC, params, 0, job_id, err);
    free(params);
    if (ret) return ret;
    storage_job_t j;
    if (storage_job_get(st, *job_id, &j, NULL) == 0) {
        srv_publish_job(srv, &j, NULL, q.levels, NAN);
        storage_job_free(&j);
    }
    srv_notify_work(srv);
    return 0;
}

int srv_ptc_constants(storage_t *st, int64_t sensor_id, double *gain_e_per_dn, double *read_noise_e,
                      int64_t *ptc_id, err_t *err)
{
    storage_ptc_list_t l;
    *ptc_id = 0;
    int ret = storage_ptc_history(st, sensor_id, 1, &l, err);
    if (ret) return ret;
    if (l.n) {
        *gain_e_per_dn = l.items[0].gain_e_per_dn;
        *read_noise_e = l.items[0].read_noise_e;
        *ptc_id = l.items[0].id;
    }
    storage_ptc_list_free(&l);
    return 0;
}

int srv_fit_noise(storage_t *st, const srv_fit_params_t *p, int64_t sensor_id, fit_scan_t *scan,
                  srv_noise_source_t *src, err_t *err)
{
    memset(src, 0, sizeof *src);
    snprintf(src->name, sizeof src->name, "%s", sensor_id ? "sensor" : "scan file");
    if (sensor_id) {
        double g = scan->gain_e_per_dn, rn = scan->read_noise_e;
        int ret = srv_ptc_constants(st, sensor_id, &g, &rn, &src->ptc_id, err);
        if (ret) return ret;
        if (src->ptc_id) {
            scan->gain_e_per_dn = g;
            scan->read_noise_e = rn;
            snprintf(src->name, sizeof src->name, "ptc #%lld", (long long)src->ptc_id);
        }
    }
    int g_req = isfinite(p->gain_e_per_dn), rn_req = isfinite(p->read_noise_e);
    if (g_req) scan->gain_e_per_dn = p->gain_e_per_dn;
    if (rn_req) scan->read_noise_e = p->read_noise_e;
    if (g_req || rn_req) {
        snprintf(src->name, sizeof src->name, "request");
        if (g_req && rn_req) src->ptc_id = 0; /* nothing of the measurement is used */
    }
    src->gain_e_per_dn = scan->gain_e_per_dn;
    src->read_noise_e = scan->read_noise_e;
    return 0;
}

int srv_fit_noise_record(json_t *doc, const srv_noise_source_t *src)
{
    json_t *c = json_pack("{s:o, s:o, s:o}", "gain_e_per_dn", fitjson_num(src->gain_e_per_dn),
                          "read_noise_e", fitjson_num(src->read_noise_e), "ptc_id",
                          src->ptc_id ? json_integer(src->ptc_id) : json_null());
    if (!c || json_object_set_new(doc, "noise_constants", c) ||
        json_object_set_new(doc, "noise_source", json_string(src->name)))
        return -ENOMEM;
    return 0;
}

/* ---- the job ------------------------------------------------------------------------------- */

/* One measurement being run. */
struct ptc_job {
    srv_worker_t *w;
    storage_job_t *job;
    srv_ptc_params_t p;
    storage_sensor_t sensor;
    double last_beat;
    int stop_rc; /* why the progress callback stopped the series (0: it did not) */
    err_t err;
};

static void publish(struct ptc_job *r, int done)
{
    storage_job_t j = *r->job;
    j.state = STORAGE_RUNNING;
    j.points_done = done;
    j.progress = (double)done / r->p.levels;
    j.error = NULL;
    srv_publish_job(r->w->srv, &j, "ptc", r->p.levels, NAN);
}

/* After each level: heartbeat (a cancel seen there stops the series), progress, test hook, and
 * the worker's stop flag (cancel or shutdown). Non-zero stops the series; stop_rc says why. */
static int on_level(void *ctx, int done, int total)
{
    struct ptc_job *r = ctx;
    double now = clock_mono_s();
    if (now - r->last_beat >= HEARTBEAT_S || done == total) {
        r->last_beat = now;
        double progress = (double)done / total < 1 ? (double)done / total : 0.99;
        r->stop_rc = storage_job_heartbeat(r->w->st, r->job->id, progress, done, &r->err);
        if (r->stop_rc) return 1;
    }
    publish(r, done);
    if ((r->stop_rc = srv_failpoint(r->w, "ptc.level", &r->err))) return 1; /* test hook */
    if (atomic_load(&r->w->stop))
        r->stop_rc = err_set(&r->err, -ECANCELED, "photon-transfer measurement stopped");
    return r->stop_rc != 0;
}

/* The simulated bench as the sensor: a uniform flat field, no spot. */
static int open_bench(struct ptc_job *r, sim_t **sim, double *flat_e)
{
    const storage_sensor_t *s = &r->sensor;
    sim_config_t c = sim_config_default();
    c.scene = "uniform";
    c.sensor.cols = s->n_cols;
    c.sensor.rows = s->n_rows;
    c.sensor.pitch_um = s->pitch_um;
    c.sensor.gain_e_per_dn = s->gain_e_per_dn;
    c.sensor.read_noise_e = s->read_noise_e;
    c.sensor.bias_dn = s->bias_dn;
    c.sensor.full_scale_dn = s->full_scale_dn;
    c.flux_e = 0; /* no spot: the lamp's flat field only */
    /* the saturation charge: the ADC clip or the full well, whichever comes first (sim.h) */
    double sat_e = fmin(c.sensor.full_well_e, (s->full_scale_dn - s->bias_dn) * s->gain_e_per_dn);
    c.flat_e = *flat_e = r->p.flat_e > 0 ? r->p.flat_e : sat_e;
    c.seed = r->p.seed;
    c.stage.seed = r->p.seed;
    c.frame_fault = r->w->srv->failpoints ? srv_failpoint_frame : NULL;
    c.frame_fault_ctx = r->w->srv;
    int ret = sim_open(&c, sim, &r->err);
    if (ret == 0) ret = cam_set_timeout(sim_camera(*sim), r->w->srv->cfg.camera_timeout_s, &r->err);
    return ret;
}

/* The stored report: the `ips ptc` document, what was measured, and the sensor's constants as
 * the database had them (on the simulated bench, the truth the measurement is compared with). */
static char *report(struct ptc_job *r, const fit_ptc_result_t *res, const fit_ptc_level_t *lv,
                    double flat_e)
{
    json_t *doc = ptcjson_result(res, lv, (size_t)r->p.levels);
    json_t *bench = json_pack(
        "{s:s, s:o, s:o, s:o, s:o, s:o, s:i, s:i, s:I}", "kind", "sim", "gain_e_per_dn",
        fitjson_num(r->sensor.gain_e_per_dn), "read_noise_e", fitjson_num(r->sensor.read_noise_e),
        "bias_dn", fitjson_num(r->sensor.bias_dn), "full_scale_dn",
        fitjson_num(r->sensor.full_scale_dn), "flat_e", fitjson_num(flat_e), "pixels",
        r->p.roi_px * r->p.roi_px, "levels", r->p.levels, "seed", (json_int_t)r->p.seed);
    /* the gain's standard error: G = 1/K, so dG = dK / K^2 */
    json_t *gerr = fitjson_num(res->K > 0 ? res->K_err / (res->K * res->K) : NAN);
    char *text = NULL;
    if (doc && bench && gerr && json_object_set_new(doc, "bench", bench) == 0 &&
        json_object_set_new(doc, "gain_err_e_per_dn", gerr) == 0)
        text = json_dumps(doc, JSON_COMPACT | JSON_REAL_PRECISION(17));
    else {
        json_decref(bench);
        json_decref(gerr);
    }
    json_decref(doc);
    return text;
}

/* The series, its analysis and the store; 0 or the error (r->err). */
static int measure(struct ptc_job *r)
{
    int ret;
    if ((ret = srv_ptc_params_parse(r->job->params, &r->p, &r->err)) ||
        (ret = storage_sensor_get(r->w->st, r->p.sensor_id, &r->sensor, &r->err)))
        return ret;
    if (r->p.levels < PTC_LEVELS_MIN || r->p.levels > PTC_LEVELS_MAX || r->p.roi_px < 2 ||
        r->p.roi_px > r->sensor.n_cols || r->p.roi_px > r->sensor.n_rows)
        return err_set(&r->err, -EINVAL, "ptc job params: levels %d or roi_px %d out of range",
                       r->p.levels, r->p.roi_px);
    /* the job must still be ours (not cancelled meanwhile) before the instrument is used */
    if ((ret = storage_job_heartbeat(r->w->st, r->job->id, 0, 0, &r->err))) return ret;
    fit_ptc_level_t *lv = calloc((size_t)r->p.levels, sizeof *lv);
    if (!lv) return err_set(&r->err, -ENOMEM, "out of memory for %d levels", r->p.levels);
    sim_t *sim = NULL;
    double flat_e = 0;
    publish(r, 0);
    ret = open_bench(r, &sim, &flat_e);
    if (ret == 0) {
        ptc_sim_lamp_t lamp = {sim, flat_e};
        sim_config_t def = sim_config_default();
        ptc_run_config_t run = {.roi = {0, 0, r->p.roi_px, r->p.roi_px},
                                .levels = r->p.levels,
                                .exposure_max_us = 1.25 * def.ref_exposure_us};
        r->last_beat = clock_mono_s();
        ret = ptc_run(sim_camera(sim), ptc_sim_light, &lamp, &run, on_level, r, lv, &r->err);
        if (r->stop_rc) ret = r->stop_rc; /* r->err says why */
    }
    sim_close(sim); /* the instrument is free before the result is written */
    fit_ptc_result_t res;
    if (ret == 0 && fit_ptc_analyse(lv, (size_t)r->p.levels, &res) != 0)
        ret = err_set(&r->err, -EINVAL,
                      "the photon-transfer analysis failed: no photon-transfer slope "
                      "(noise-free frames, or too few levels below saturation)");
    if (ret == 0) ret = srv_failpoint(r->w, "ptc.before_store", &r->err); /* test hook */
    char *text = ret == 0 ? report(r, &res, lv, flat_e) : NULL;
    if (ret == 0 && !text) ret = err_set(&r->err, -ENOMEM, "out of memory for the report");
    free(lv);
    if (ret) return ret;
    storage_ptc_t row = {.sensor_id = r->sensor.id,
                         .gain_e_per_dn = res.gain_e_per_dn,
                         .read_noise_e = res.read_noise_e,
                         .dark_dn = res.dark_dn,
                         .saturation_dn = res.saturation_dn,
                         .linearity_error_pct = res.linearity_error_pct,
                         .result = text,
                         .job_id = r->job->id};
    int64_t id = 0;
    /* the measurement and the job's done in one transaction (cancelled meanwhile: nothing) */
    ret = storage_ptc_store_done(r->w->st, &row, &id, &r->err);
    free(text);
    if (ret == 0) {
        fprintf(stderr,
                "ipsd: ptc job %lld: sensor %lld gain %.4f e-/DN, read noise %.3f e- "
                "(measurement %lld)\n",
                (long long)r->job->id, (long long)r->sensor.id, res.gain_e_per_dn, res.read_noise_e,
                (long long)id);
        srv_failpoint(r->w, "ptc.after_store", NULL); /* test hook: the job is done */
    }
    return ret;
}

void srv_ptc_run_job(srv_worker_t *w, storage_job_t *job)
{
    struct ptc_job r = {.w = w, .job = job};
    srv_worker_begin(w, job->id);
    int ret = measure(&r);
    if (ret == -ECANCELED) {
        /* cancelled by the user (nothing to do), else the shutdown (or a cancel meant for a
         * previous job): the job goes back to the queue and runs again from its start */
        if (storage_job_heartbeat(w->st, job->id, 0, 0, NULL) == 0)
            storage_job_release(w->st, job->id, NULL);
    } else if (ret) {
        fprintf(stderr, "ipsd: ptc job %lld failed: %s\n", (long long)job->id, r.err.msg);
        /* a job no longer running (cancelled, requeued) needs nothing more; one whose failure
         * cannot be written stays running and is requeued at the next start */
        storage_job_finish(w->st, job->id, STORAGE_FAILED, r.err.msg, NULL);
    }
    srv_worker_end(w);
    storage_job_t j;
    if (storage_job_get(w->st, job->id, &j, NULL) == 0) {
        srv_publish_job(w->srv, &j, NULL, r.p.levels, NAN);
        storage_job_free(&j);
    }
    storage_sensor_free(&r.sensor);
}
