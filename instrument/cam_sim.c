/* cam_sim.c: the "sim" camera backend: cam.h's calls mapped onto the simulated bench (sim.h). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cam_impl.h"
#include "instrument/sim.h"

static void close_owned(void *impl)
{
    sim_close(impl);
}

static int info(void *impl, cam_info_t *out, err_t *err)
{
    (void)err;
    return sim_info(impl, out);
}

static int set_exposure(void *impl, double us, err_t *err)
{
    return sim_set_exposure(impl, us, err);
}

static int set_gain(void *impl, double g, err_t *err)
{
    return sim_set_gain(impl, g, err);
}

static int capture(void *impl, const cam_roi_t *roi, cam_frame_t *f, err_t *err)
{
    return sim_capture(impl, roi, f, err);
}

/* the handle of cam_open("sim") owns its bench; the one of sim_camera() does not */
static const struct cam_ops owned_ops = {"sim", close_owned, info, set_exposure, set_gain, capture};
static const struct cam_ops borrowed_ops = {"sim", NULL, info, set_exposure, set_gain, capture};

int cam_sim_list(cam_info_t **infos, size_t *n, err_t *err)
{
    static const char *const scenes[] = {"paperlike", "uniform"};
    size_t k = sizeof scenes / sizeof scenes[0];
    cam_info_t *list = calloc(k, sizeof *list);
    if (!list) return err_set(err, -ENOMEM, "out of memory for the camera list");
    scene_sensor_t sn = scene_sensor_default();
    for (size_t i = 0; i < k; i++) {
        cam_info_t *c = &list[i];
        snprintf(c->backend, sizeof c->backend, "sim");
        snprintf(c->id, sizeof c->id, "%s", scenes[i]);
        snprintf(c->model, sizeof c->model, "ipsd simulated bench");
        c->width = sn.cols;
        c->height = sn.rows;
        c->pitch_um = sn.pitch_um;
        c->gain_e_per_dn = sn.gain_e_per_dn;
        c->read_noise_e = sn.read_noise_e;
        c->bias_dn = sn.bias_dn;
        c->full_scale_dn = sn.full_scale_dn;
        c->exposure_min_us = 1;
        c->exposure_max_us = 60e6;
        c->gain_min = 1;
        c->gain_max = 16;
    }
    *infos = list;
    *n = k;
    return 0;
}

int cam_sim_open(const char *spec, cam_t **out, err_t *err)
{
    sim_config_t cfg = sim_config_default();
    if (spec && *spec) cfg.scene = spec;
    sim_t *sim;
    int rc = sim_open(&cfg, &sim, err);
    if (rc) return rc;
    *out = cam_wrap(&owned_ops, sim);
    if (!*out) {
        sim_close(sim);
        return err_set(err, -ENOMEM, "out of memory for the camera");
    }
    return 0;
}

int cam_sim_borrowed(struct sim *sim, cam_t **out)
{
    *out = cam_wrap(&borrowed_ops, sim);
    return *out ? 0 : -ENOMEM;
}

struct sim *cam_sim_of(cam_t *cam)
{
    return cam && (cam->ops == &owned_ops || cam->ops == &borrowed_ops) ? cam->impl : NULL;
}

sim_t *sim_of_camera(cam_t *cam)
{
    return cam_sim_of(cam);
}
