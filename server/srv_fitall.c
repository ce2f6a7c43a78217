/* srv_fitall.c: a fit job of every pixel a finished scan covers ("pixels": "all"). The
 * fit worker that claimed the job fits the covered pixels of the scan's sub-frame
 * (server/srv_cover.h: the rule of instrument/scan_cover.h) one after another, in row-major order
 * from the top left, each exactly as a fit of that one pixel (srv_pixel_scan over every stored
 * point, srv_fit_run with the job's options), and stores each pixel's fit with the map it offers
 * (and, when the job says "promote", that pixel's new calibration) together with the job's count
 * of pixels done (points_done) in one transaction (storage_fit_store_unit); the last pixel's
 * transaction also ends the job as done. So:
 *   - progress is "pixel k of N" (points_done of points_total in the job's events), each event
 *     naming its pixel ("pixel": the one being fitted, or the one whose fit fit_id was just
 *     stored);
 *   - the job is linked to its fits: its fit_id is the newest pixel's, and each pixel's fit
 *     records the job (fits.job_id, in the pixel's transaction: storage_fit_store_unit), so the
 *     job's fit_ids are every pixel's in the order stored; the job's answer lists them with
 *     their pixels and the pixels not covered (api_jobs.c);
 *   - a cancel stops the job between pixels and inside a pixel's fit (the worker's stop flag,
 *     polled by fit/ through fit/stop.h); the pixels stored before stay, the one in flight
 *     stores nothing;
 *   - a crash leaves every pixel stored once or not at all: the job is requeued at the next start
 *     and resumes at pixel points_done, the first one not stored (the transaction refuses a
 *     pixel whose count does not match, so none is ever stored twice);
 *   - a graceful stop gives the job back to the queue, to resume the same way.
 * Pixels the raster does not cover are not fitted: GET /api/scans/{id}/coverage reports them
 * "not_covered" with the reason. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "json/jdump.h"
#include "server/srv_cover.h"
#include "server/srv_fit.h"
#include "server/srv_setup.h"
#include "srv_failpoint.h"
#include "server/srv_ptc.h"
#include "srv_fitall.h"

/* Progress of the running pixel: an event per step, the heartbeat at most once a second. */
struct all_watch {
    srv_worker_t *w;
    storage_job_t *job;
    int k, n; /* pixel k (0-based) of n */
    double last_beat, t0;
    int done_at_start; /* pixels stored before this run (for the ETA) */
    int dcol, drow;    /* the pixel being fitted, from the POI */
    const storage_scan_t *sc;
};

static double eta(const struct all_watch *aw, double fraction)
{
    double done = aw->k - aw->done_at_start + fraction, dt = clock_mono_s() - aw->t0;
    return done > 0 ? dt / done * (aw->n - aw->k - fraction) : NAN;
}

static void on_progress(double fraction, void *user)
{
    struct all_watch *aw = user;
    storage_job_t j = *aw->job;
    if (fraction > 1) fraction = 1;
    j.state = STORAGE_RUNNING;
    j.points_done = aw->k;
    j.progress = fmin((aw->k + fraction) / aw->n, 0.99);
    j.error = NULL;
    double now = clock_mono_s();
    if (now - aw->last_beat >= 1.0) {
        aw->last_beat = now;
        if (storage_job_heartbeat(aw->w->st, j.id, j.progress, aw->k, NULL) == -ECANCELED)
            atomic_store(&aw->w->stop, 1);
    }
    j.fit_id = 0; /* (this pixel's fit is not stored yet) */
    srv_publish_job_pixel(aw->w->srv, &j, "fit", aw->n, eta(aw, fraction), aw->dcol, aw->drow,
                          aw->sc->poi_col + aw->dcol, aw->sc->poi_row + aw->drow);
    if (srv_failpoint(aw->w, "fit.step", NULL)) atomic_store(&aw->w->stop, 1); /* test hook */
}

static int on_poll(void *user)
{
    struct all_watch *aw = user;
    return aw->w->srv->failpoints && srv_failpoint(aw->w, "fit.poll", NULL) != 0;
}

/* The calibration provenance of pixel (dcol, drow): the request's, or by "api" and a reason
 * naming the scan and the pixel. */
static void provenance(const srv_fit_params_t *p, int dcol, int drow, storage_calib_t *c,
                       char *reason, size_t n)
{
    c->by = (char *)(p->by[0] ? p->by : "api");
    if (p->reason[0])
        snprintf(reason, n, "%s", p->reason);
    else
        snprintf(reason, n,
                 "fit of every pixel of scan %lld (pixel (%+d, %+d)) asked to become the "
                 "calibration",
                 (long long)p->scan_id, dcol, drow);
    c->reason = reason;
}

/* Fits pixel (dcol, drow) and stores it as unit aw->k of the job. */
static int fit_pixel(struct all_watch *aw, const srv_fit_params_t *p, const storage_scan_t *sc,
                     int dcol, int drow, int64_t *fit_id, err_t *err)
{
    srv_worker_t *w = aw->w;
    scanfile_t sf;
    srv_fit_out_t out = {0};
    char *result = NULL, reason[SRV_REASON_MAX + 96];
    srv_fit_hooks_t hooks = {
        .stop = &w->stop, .poll = on_poll, .progress = on_progress, .user = aw};
    /* every stored point: the fit takes its region (fit/region.h), Wiener the whole raster */
    srv_noise_source_t noise;
    int ret = srv_pixel_scan(w->st, sc, dcol, drow, 1, &sf, err);
    if (ret) return ret;
    /* sigma's gain and read noise: the request's, the sensor's photon transfer, the scan's */
    if ((ret = srv_fit_noise(w->st, p, sc->sensor_id, &sf.scan, &noise, err)) ||
        (ret = srv_fit_run(&sf.scan, p, &hooks, &out, err)))
        goto out;
    if (srv_fit_noise_record(out.result, &noise)) {
        ret = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    if (!(result = jdump_string(out.result, JDUMP_COMPACT))) { /* json_dumps's text, faster */
        ret = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    storage_fit_t f = {.scan_id = sc->id,
                       .dcol = dcol,
                       .drow = drow,
                       .noise_model = (char *)fit_noise_name(p->opts.noise),
                       .best_r_aic = out.best_aic,
                       .best_r_bic = out.best_bic,
                       .f_value = out.f_value,
                       .p_value = out.p_value,
                       .result = result};
    storage_calib_t c = {.sensor_id = sc->sensor_id,
                         .pixel_col = sc->poi_col + dcol,
                         .pixel_row = sc->poi_row + drow,
                         .scan_id = sc->id,
                         .wavelength_um = sc->wavelength_um,
                         .na = sc->na,
                         .spot_radius_um = sc->spot_radius_um,
                         .r = out.r,
                         .S = out.S,
                         .S_err = out.S_err,
                         .map = out.map,
                         .S_res = out.S_res,
                         .map_note = out.map_note[0] ? out.map_note : NULL,
                         .I0 = out.I0,
                         .chi2_red = out.chi2_red,
                         .status = (char *)out.status,
                         .noise_model = f.noise_model};
    provenance(p, dcol, drow, &c, reason, sizeof reason);
    ret = storage_fit_store_unit(w->st, &f, out.r > 0 ? &c : NULL, p->promote, aw->job->id, aw->k,
                                 aw->n, fit_id, NULL, err);
out:
    free(result);
    srv_fit_out_free(&out);
    scanfile_free(&sf);
    return ret;
}

int srv_fitall_run(srv_worker_t *w, storage_job_t *job, const srv_fit_params_t *p, err_t *err)
{
    storage_scan_t sc;
    scan_cover_t *cover = NULL;
    int *todo = NULL, n = 0;
    int ret = storage_scan_get(w->st, p->scan_id, &sc, err);
    if (ret) return ret;
    if (sc.state != STORAGE_DONE)
        ret = err_set(err, -ESTALE, "scan %lld is %s, not done", (long long)sc.id,
                      storage_state_name(sc.state));
    if (ret == 0) ret = srv_scan_cover(w->st, &sc, &cover, err);
    int m = sc.sub_px, h = m / 2;
    if (ret == 0 && !(todo = malloc((size_t)m * (size_t)m * sizeof *todo)))
        ret = err_set(err, -ENOMEM, "out of memory");
    for (int i = 0; ret == 0 && i < m * m; i++)
        if (cover[i].covered) todo[n++] = i;
    if (ret == 0 && n == 0)
        ret = err_set(err, -ENODATA, "scan %lld's raster covers no pixel of its sub-frame",
                      (long long)sc.id);
    struct all_watch aw = {.w = w,
                           .job = job,
                           .k = job->points_done,
                           .n = n,
                           .last_beat = clock_mono_s(),
                           .t0 = clock_mono_s(),
                           .done_at_start = job->points_done,
                           .sc = &sc};
    /* every pixel stored already (cannot happen: the last one ends the job) */
    if (ret == 0 && aw.k >= n) ret = storage_job_finish(w->st, job->id, STORAGE_DONE, NULL, err);
    for (; ret == 0 && aw.k < n; aw.k++) {
        if (atomic_load(&w->stop)) {
            ret = err_set(err, -ECANCELED, "stopped");
            break;
        }
        int dcol = todo[aw.k] % m - h, drow = todo[aw.k] / m - h;
        int64_t fit_id = 0;
        aw.dcol = dcol;
        aw.drow = drow;
        if ((ret = fit_pixel(&aw, p, &sc, dcol, drow, &fit_id, err))) break;
        storage_job_t j = *job;
        j.state = aw.k + 1 < n ? STORAGE_RUNNING : STORAGE_DONE;
        j.points_done = aw.k + 1;
        j.progress = (double)(aw.k + 1) / n;
        j.error = NULL;
        j.fit_id = fit_id; /* the pixel's fit, just stored (the job's fit_id now too) */
        /* (after the last pixel's, done, the fitter publishes the job's stored state too) */
        srv_publish_job_pixel(w->srv, &j, "fit", n, eta(&aw, 1), dcol, drow, sc.poi_col + dcol,
                              sc.poi_row + drow);
        srv_failpoint(w, "fit.pixel", NULL); /* test hook: k + 1 pixels stored */
    }
    /* stopped: cancelled (nothing to do), else the shutdown: the job goes back to the queue
     * with its count of pixels done kept, to resume at the next pixel */
    if (ret == -ECANCELED &&
        storage_job_heartbeat(w->st, job->id, n ? (double)aw.k / n : 0, aw.k, NULL) == 0)
        storage_job_release(w->st, job->id, NULL);
    free(todo);
    free(cover);
    storage_scan_free(&sc);
    return ret;
}
