/* cam_sim.c: the simulated camera, the "sim" camera backend: what the camera of the simulated
 * bench says about itself, its exposure and gain, and its frames, drawn from the bench's expected
 * image (sim.h "A frame": Poisson charge, full well, read noise, gain, bias, rounding, clipping),
 * with the bench's clock advanced by each frame. The bench (sim.c) knows nothing of cameras.
 * Its fault switch (sim_config_t.frame_fault) makes it fail, or stop answering: a hang is a real
 * wait (on the wall clock) that the camera's frame timeout ends, as a real camera's would be. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <gsl/gsl_randist.h>

#include "base/clock.h"
#include "cam_impl.h"
#include "cam_roi.h"
#include "sim_int.h"

#define EXPOSURE_MIN_US 1
#define EXPOSURE_MAX_US 60e6
#define GAIN_MIN 1
#define GAIN_MAX 16

/* The description of a simulated camera of sensor sn looking at scene id. */
static void describe(const scene_sensor_t *sn, const char *id, cam_info_t *info)
{
    memset(info, 0, sizeof *info);
    snprintf(info->backend, sizeof info->backend, "sim");
    snprintf(info->id, sizeof info->id, "%.127s", id);
    snprintf(info->model, sizeof info->model, "ipsd simulated bench");
    info->width = sn->cols;
    info->height = sn->rows;
    info->pitch_um = sn->pitch_um;
    info->gain_e_per_dn = sn->gain_e_per_dn;
    info->read_noise_e = sn->read_noise_e;
    info->bias_dn = sn->bias_dn;
    info->full_scale_dn = sn->full_scale_dn;
    info->exposure_min_us = EXPOSURE_MIN_US;
    info->exposure_max_us = EXPOSURE_MAX_US;
    info->gain_min = GAIN_MIN;
    info->gain_max = GAIN_MAX;
}

int sim_info(sim_t *s, cam_info_t *info)
{
    describe(&s->cfg.sensor, s->scene_spec, info);
    return 0;
}

int sim_set_exposure(sim_t *s, double exposure_us, err_t *err)
{
    if (!(exposure_us >= EXPOSURE_MIN_US && exposure_us <= EXPOSURE_MAX_US))
        return err_set(err, -ERANGE,
                       "exposure %g us is outside the simulated camera's range "
                       "[1, 6e7] us",
                       exposure_us);
    s->exposure_us = exposure_us;
    return 0;
}

int sim_set_gain(sim_t *s, double gain, err_t *err)
{
    if (!(gain >= GAIN_MIN && gain <= GAIN_MAX))
        return err_set(err, -ERANGE,
                       "analogue gain %g is outside the simulated camera's range "
                       "[1, 16]",
                       gain);
    s->gain = gain;
    return 0;
}

int sim_set_flat(sim_t *s, double flat_e, err_t *err)
{
    if (!(flat_e >= 0) || !isfinite(flat_e))
        return err_set(err, -EINVAL, "flat field must be >= 0 (got %g e-)", flat_e);
    s->cfg.flat_e = flat_e;
    return 0;
}

/* One pixel's DN from its expected charge (sim.h: Poisson, full well, read noise, gain, bias,
 * rounding, clipping). */
static uint16_t draw_dn(sim_t *s, double lambda_e)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    double e = lambda_e;
    if (!s->cfg.noiseless) {
        /* far above the full well the pixel clips whatever the draw: skip the costly draw */
        e = lambda_e > 100 * sn->full_well_e ? lambda_e
            : lambda_e > 0                   ? (double)gsl_ran_poisson(s->rng, lambda_e)
                                             : 0;
    }
    if (e > sn->full_well_e) e = sn->full_well_e;
    if (!s->cfg.noiseless && sn->read_noise_e > 0)
        e += gsl_ran_gaussian_ziggurat(s->rng, sn->read_noise_e);
    double dn = nearbyint(sn->bias_dn + e * s->gain / sn->gain_e_per_dn);
    return (uint16_t)(dn < 0 ? 0 : dn > sn->full_scale_dn ? sn->full_scale_dn : dn);
}

/* The fault switch's answer for the next frame: 0, or the capture's error after a hang (waits
 * the frame timeout) or a failure. */
static int fault(sim_t *s, err_t *err)
{
    if (!s->cfg.frame_fault) return 0;
    unsigned long long n = s->stats.frames;
    int what = s->cfg.frame_fault(s->cfg.frame_fault_ctx, n);
    if (what == SIM_FRAME_FAIL)
        return err_set(err, -EIO, "simulated camera: capture of frame %llu failed (fault switch)",
                       n + 1);
    if (what != SIM_FRAME_HANG) return 0;
    double limit = s->timeout_s > 0 ? s->timeout_s : s->exposure_us * 1e-6 + 5;
    struct timespec until;
    clock_gettime(CLOCK_MONOTONIC, &until);
    double end = until.tv_sec + until.tv_nsec * 1e-9 + limit;
    until.tv_sec = (time_t)end;
    until.tv_nsec = (long)((end - (double)until.tv_sec) * 1e9);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &until, NULL) == EINTR) {}
    return err_set(err, -ETIMEDOUT,
                   "simulated camera: no frame within %g s (stopped answering at frame %llu)",
                   limit, n + 1);
}

int sim_capture(sim_t *s, const cam_roi_t *roi, cam_frame_t *f, err_t *err)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    cam_roi_t r;
    int rc = cam_roi_check(roi, sn->cols, sn->rows, &r, err);
    if (rc || (rc = fault(s, err))) return rc;
    size_t npx = (size_t)r.width * r.height;
    f->roi = r;
    f->dn = malloc(sizeof(uint16_t) * npx);
    f->expected_dn = malloc(sizeof(double) * npx);
    if (!f->dn || !f->expected_dn)
        return err_set(err, -ENOMEM, "out of memory for a %dx%d frame", r.width, r.height);
    double xs, ys, zs, left_e = 0;
    sim_spot(s, &xs, &ys, &zs);
    rc = sim_expected(s, xs, ys, sim_spot_radius(s, zs), &r, f->expected_dn, &left_e, err);
    if (rc) return rc;
    /* DN = bias + charge * gain / G (sim.h); the flat field adds the same charge to each pixel */
    double t0 = clock_mono_s(), dn_per_e = s->gain / sn->gain_e_per_dn;
    double flat = s->cfg.flat_e * (s->exposure_us / s->cfg.ref_exposure_us);
    for (size_t k = 0; k < npx; k++) {
        double lambda = f->expected_dn[k] + flat;
        f->dn[k] = draw_dn(s, lambda);
        f->expected_dn[k] = sn->bias_dn + lambda * dn_per_e;
    }
    s->stats.noise_s += clock_mono_s() - t0;
    s->stats.frames++;
    s->stats.pixel_frames += npx;
    if (left_e > s->stats.max_left_out_e) s->stats.max_left_out_e = left_e;
    f->left_out_dn = left_e * dn_per_e;
    f->exposure_us = s->exposure_us;
    f->gain = s->gain;
    double t; /* the frame's timestamp is the start of its exposure, as libcamera's */
    stage_sim_clock(s->stage, &t);
    f->timestamp_ns = (int64_t)llround(t * 1e9);
    stage_sim_advance(s->stage, s->exposure_us * 1e-6 + s->cfg.readout_s);
    f->temperature_c = s->cfg.temperature_c;
    return 0;
}

/* ---- the backend ---- */

static void op_close(void *impl)
{
    sim_close(impl);
}

static int op_info(void *impl, cam_info_t *out, err_t *err)
{
    (void)err;
    return sim_info(impl, out);
}

static int op_set_exposure(void *impl, double us, err_t *err)
{
    return sim_set_exposure(impl, us, err);
}

static int op_set_gain(void *impl, double g, err_t *err)
{
    return sim_set_gain(impl, g, err);
}

static int op_capture(void *impl, const cam_roi_t *roi, cam_frame_t *f, err_t *err)
{
    return sim_capture(impl, roi, f, err);
}

static int op_set_timeout(void *impl, double seconds, err_t *err)
{
    (void)err;
    ((sim_t *)impl)->timeout_s = seconds;
    return 0;
}

/* the handle of cam_open("sim") owns its bench; the one of sim_camera() does not */
static const struct cam_ops owned_ops = {op_close,    op_info,    op_set_exposure,
                                         op_set_gain, op_capture, op_set_timeout};
static const struct cam_ops borrowed_ops = {NULL,        op_info,    op_set_exposure,
                                            op_set_gain, op_capture, op_set_timeout};

static int list(cam_info_t **infos, size_t *n, err_t *err)
{
    static const char *const scenes[] = {"paperlike", "uniform"};
    size_t k = sizeof scenes / sizeof scenes[0];
    cam_info_t *all = calloc(k, sizeof *all);
    if (!all) return err_set(err, -ENOMEM, "out of memory for the camera list");
    scene_sensor_t sn = scene_sensor_default();
    for (size_t i = 0; i < k; i++)
        describe(&sn, scenes[i], &all[i]);
    *infos = all;
    *n = k;
    return 0;
}

/* A bench of the paper's defaults on scene spec (NULL or "": paperlike). */
static int open_bench(const char *spec, void **impl, err_t *err)
{
    sim_config_t cfg = sim_config_default();
    if (spec && *spec) cfg.scene = spec;
    sim_t *sim;
    int rc = sim_open(&cfg, &sim, err);
    *impl = rc ? NULL : sim;
    return rc;
}

const struct cam_backend cam_sim_backend = {CAM_BACKEND_HEADER, "sim", list, open_bench,
                                            &owned_ops};

cam_t *sim_camera(sim_t *s)
{
    if (!s->cam) { /* made on first use: the bench does not depend on the camera interface */
        s->cam = cam_wrap(&borrowed_ops, s);
        s->cam_release = cam_close;
    }
    return s->cam;
}

sim_t *sim_of_camera(cam_t *cam)
{
    sim_t *s = cam_impl_of(cam, &owned_ops);
    return s ? s : cam_impl_of(cam, &borrowed_ops);
}
