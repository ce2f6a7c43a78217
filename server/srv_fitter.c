/* srv_fitter.c: the fit workers. Each takes the oldest queued fit job, builds the scan the fit
 * needs (the pixel's response over all of a finished scan's stored points, srv_pixel_scan, or the
 * uploaded scan file; the fit selects its region's points, the Wiener baseline takes them all),
 * runs it (srv_fit_run) and stores the fit with the map it offers to that sensor pixel (the
 * recommended map), linked to the job, and the job's end (done) in one transaction
 * (storage_fit_store_done): a crash leaves the job running with nothing stored (it runs again)
 * or done with everything, never a fit the job does not name. The map becomes the pixel's
 * calibration when the job says so (the automatic fit of a scan, a request with "promote": true,
 * an upload with a target pixel).
 * A fit stops between its steps (each r of the sweep, the F-test, the Wiener baseline) and inside
 * their long loops (fit/stop.h: the worker's stop flag, which a cancel and the shutdown set
 * directly) when it is cancelled or ipsd stops; stopped by the shutdown, it goes back to the queue. A fit interrupted
 * by a crash is requeued at the next start and simply runs again: it had stored nothing. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/thread_sched.h"
#include "instrument/scanfile.h"
#include "json/jdump.h"
#include "server/srv_fit.h"
#include "server/srv_ptc.h"
#include "server/srv_setup.h"
#include "srv_failpoint.h"
#include "srv_fitall.h"
#include "srv_int.h"

/* What a fit job works on: the scan, its optics and where the calibration goes. */
struct fit_input {
    scanfile_t sf;
    storage_calib_t calib; /* the target pixel and provenance (no map yet); sensor_id 0: none */
};

/* The scan file of the job: a finished scan's pixel, or the upload. */
static int load_input(storage_t *st, const srv_fit_params_t *p, struct fit_input *in, err_t *err)
{
    storage_calib_t *c = &in->calib;
    c->wavelength_um = c->na = c->spot_radius_um = c->I0 = c->chi2_red = NAN;
    if (p->scan_file) {
        char *text = json_dumps(p->scan_file, JSON_COMPACT | JSON_REAL_PRECISION(17));
        if (!text) return err_set(err, -ENOMEM, "out of memory");
        int ret = scanfile_parse(text, strlen(text), &in->sf, NULL, err);
        free(text);
        c->sensor_id = p->sensor_id;
        c->pixel_col = p->pixel_col;
        c->pixel_row = p->pixel_row;
        c->wavelength_um = p->wavelength_um;
        c->na = p->na;
        c->spot_radius_um = in->sf.scan.spot_radius_um;
        return ret;
    }
    storage_scan_t sc;
    int ret = storage_scan_get(st, p->scan_id, &sc, err);
    if (ret) return ret;
    if (sc.state != STORAGE_DONE)
        ret = err_set(err, -ESTALE, "scan %lld is %s, not done", (long long)sc.id,
                      storage_state_name(sc.state));
    /* every stored point: the fit takes its region (fit/region.h), Wiener the whole raster */
    if (ret == 0) ret = srv_pixel_scan(st, &sc, p->dcol, p->drow, 1, &in->sf, err);
    c->sensor_id = sc.sensor_id;
    c->pixel_col = sc.poi_col + p->dcol;
    c->pixel_row = sc.poi_row + p->drow;
    c->scan_id = sc.id;
    c->wavelength_um = sc.wavelength_um;
    c->na = sc.na;
    c->spot_radius_um = sc.spot_radius_um;
    storage_scan_free(&sc);
    return ret;
}

/* Who made the fit's map the calibration and why, when the request did not say (docs/api.md):
 * by "api", and a reason naming the fit's data. c->reason is malloc'ed (NULL when out of
 * memory: storage's default); c->by borrows p's. */
static void provenance(const srv_fit_params_t *p, storage_calib_t *c)
{
    char text[SRV_REASON_MAX + 64];
    c->by = (char *)(p->by[0] ? p->by : "api");
    if (p->reason[0])
        snprintf(text, sizeof text, "%s", p->reason);
    else if (p->scan_id)
        snprintf(text, sizeof text,
                 "fit of scan %lld pixel (%+d, %+d) asked to become the calibration",
                 (long long)p->scan_id, p->dcol, p->drow);
    else
        snprintf(text, sizeof text, "fit of an uploaded scan file");
    c->reason = strdup(text);
}

/* Stores the fit, with the map it offers when it has one and a sensor pixel to go to, and ends
 * the job as done; the map becomes that pixel's calibration when the job asks (p->promote).
 * -ECANCELED, storing nothing, when the job was cancelled meanwhile. */
static int store(storage_t *st, int64_t job_id, const srv_fit_params_t *p, struct fit_input *in,
                 srv_fit_out_t *out, err_t *err)
{
    char *result = jdump_string(out->result, JDUMP_COMPACT); /* json_dumps's text, faster */
    if (!result) return err_set(err, -ENOMEM, "out of memory");
    storage_fit_t f = {.scan_id = p->scan_id,
                       .dcol = p->dcol,
                       .drow = p->drow,
                       .noise_model = (char *)fit_noise_name(p->opts.noise),
                       .best_r_aic = out->best_aic,
                       .best_r_bic = out->best_bic,
                       .f_value = out->f_value,
                       .p_value = out->p_value,
                       .result = result};
    storage_calib_t *c = &in->calib;
    int with_calib = out->r > 0 && c->sensor_id > 0;
    if (with_calib) {
        c->r = out->r;
        c->S = out->S;
        c->S_err = out->S_err;
        c->map = out->map;
        c->S_res = out->S_res;
        c->map_note = out->map_note[0] ? out->map_note : NULL;
        c->I0 = out->I0;
        c->chi2_red = out->chi2_red;
        c->status = (char *)out->status;
        c->noise_model = f.noise_model;
        provenance(p, c);
    }
    int ret = storage_fit_store_done(st, &f, with_calib ? c : NULL, p->promote, job_id, NULL, NULL,
                                     err);
    free(c->reason);
    c->reason = NULL;
    free(result);
    return ret;
}

/* Progress of a running fit: an event per step, the heartbeat at most once a second. */
struct fit_watch {
    srv_worker_t *w;
    storage_job_t *job;
    double last_beat;
};

static void on_progress(double fraction, void *user)
{
    struct fit_watch *fw = user;
    storage_job_t j = *fw->job;
    j.state = STORAGE_RUNNING;
    j.progress = fraction < 1 ? fraction : 0.99;
    j.error = NULL;
    double now = clock_mono_s();
    if (now - fw->last_beat >= 1.0) {
        fw->last_beat = now;
        /* a cancel seen here stops the fit at its next step */
        if (storage_job_heartbeat(fw->w->st, j.id, j.progress, 0, NULL) == -ECANCELED)
            atomic_store(&fw->w->stop, 1);
    }
    srv_publish_job(fw->w->srv, &j, "fit", 0, NAN);
    if (srv_failpoint(fw->w, "fit.step", NULL)) atomic_store(&fw->w->stop, 1); /* test hook */
}

/* Inside the fit's long loops: the test hook fit.poll (a hold there is a fit held mid-step; it
 * ends, stopping the fit, when the job is cancelled or ipsd stops). */
static int on_poll(void *user)
{
    struct fit_watch *fw = user;
    return fw->w->srv->failpoints && srv_failpoint(fw->w, "fit.poll", NULL) != 0;
}

/* The same at a named place of the fit: fit.poll, then the place's own point fit.poll.SITE
 * (fit.poll.lm: inside the LM), so a test can hold a fit inside one loop whatever the count of
 * the polls before it. */
static int on_poll_at(void *user, const char *site)
{
    struct fit_watch *fw = user;
    if (!fw->w->srv->failpoints) return 0;
    if (on_poll(user)) return 1;
    char name[32];
    snprintf(name, sizeof name, "fit.poll.%s", site);
    return srv_failpoint(fw->w, name, NULL) != 0;
}

/* After a stopped fit: cancelled by the user (nothing to do), else the shutdown (or a cancel
 * meant for a previous job): the job goes back to the queue and runs again. */
static void stopped(storage_t *st, int64_t id)
{
    if (storage_job_heartbeat(st, id, 0, 0, NULL) == 0) storage_job_release(st, id, NULL);
}

/* Runs one claimed job to its end state. */
static void run_job(srv_worker_t *w, storage_job_t *job)
{
    srv_fit_params_t p;
    struct fit_input in = {0};
    srv_fit_out_t out = {0};
    err_t err = {{0}};
    struct fit_watch fw = {.w = w, .job = job, .last_beat = clock_mono_s()};
    srv_fit_hooks_t hooks = {.stop = &w->stop, .poll = on_poll, .poll_at = on_poll_at,
                             .progress = on_progress, .user = &fw};
    srv_worker_begin(w, job->id);
    srv_publish_job(w->srv, job, "fit", 0, NAN);
    int ret = srv_fit_params_parse(job->params, &p, &err);
    if (ret == 0 && p.all_pixels) { /* every pixel the scan covers: srv_fitall.c */
        ret = srv_fitall_run(w, job, &p, &err);
        goto end;
    }
    srv_noise_source_t noise;
    if (ret == 0) ret = load_input(w->st, &p, &in, &err);
    /* sigma's gain and read noise: the request's, the sensor's photon transfer, the scan's */
    if (ret == 0)
        ret = srv_fit_noise(w->st, &p, p.scan_file ? 0 : in.calib.sensor_id, &in.sf.scan, &noise,
                            &err);
    if (ret == 0) ret = srv_fit_run(&in.sf.scan, &p, &hooks, &out, &err);
    if (ret == 0 && srv_fit_noise_record(out.result, &noise))
        ret = err_set(&err, -ENOMEM, "out of memory");
    if (ret == 0) ret = srv_failpoint(w, "fit.before_store", &err); /* test hook */
    /* the fit and the job's done in one transaction (cancelled meanwhile: nothing stored) */
    if (ret == 0) ret = store(w->st, job->id, &p, &in, &out, &err);
    if (ret == 0) srv_failpoint(w, "fit.after_store", NULL); /* test hook: the job is done */
end:
    if (ret == -ECANCELED) {
        if (!p.all_pixels) stopped(w->st, job->id); /* srv_fitall_run gives its job back itself */
    } else if (ret) {
        fprintf(stderr, "ipsd: fit job %lld failed: %s\n", (long long)job->id, err.msg);
        storage_job_finish(w->st, job->id, STORAGE_FAILED, err.msg, NULL);
    }
    srv_worker_end(w);
    storage_job_t j;
    if (storage_job_get(w->st, job->id, &j, NULL) == 0) {
        srv_publish_job(w->srv, &j, NULL, 0, NAN);
        storage_job_free(&j);
    }
    srv_fit_out_free(&out);
    scanfile_free(&in.sf);
    srv_fit_params_free(&p);
}

/* Fits are background work: on Linux the nice value and the policy are per thread, so a fit
 * worker at nice --fit-nice (10: weight 110 against the HTTP threads' 1024) yields the CPU to the
 * HTTP threads (reads stay fast while fits run) without starving (the scheduler's weights still
 * give it its share). --fit-sched batch adds SCHED_BATCH: no wakeup preemption of the HTTP
 * threads by a fit worker; --fit-sched idle, SCHED_IDLE: a fit runs only on a CPU nothing else
 * wants (docs/server.md weighs its lock-holder risk). Measured: docs/operations.md. */
static void lower_priority(const srv_config_t *cfg)
{
    int ret = thread_sched_set(cfg->fit_nice, 0, cfg->fit_sched);
    if (ret) fprintf(stderr, "ipsd: fit worker: cannot lower its priority: %s\n", strerror(-ret));
}

void *srv_fitter_main(void *arg)
{
    srv_worker_t *w = arg;
    lower_priority(&w->srv->cfg);
    srv_worker_loop(w, STORAGE_JOB_BIT(STORAGE_JOB_FIT), "fit worker", run_job);
    return NULL;
}
