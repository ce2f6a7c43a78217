/* ptc_run.c: the photon-transfer series on a camera (ptc_run.h): per exposure, flats A and B
 * with the lamp on, then darks A and B with it off, at the same exposure (EMVA 1288 R3.1
 * section 6.1 asks for a dark pair at each exposure, so that dark current is subtracted). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "instrument/ptc_run.h"

/* one pair of frames at the current settings, reduced to its mean and temporal variance */
static int pair(cam_t *cam, const cam_roi_t *roi, double *mu, double *s2, err_t *err)
{
    cam_frame_t a = {0}, b = {0};
    int rc = cam_capture(cam, roi, &a, err);
    if (rc == 0) rc = cam_capture(cam, roi, &b, err);
    if (rc == 0) {
        size_t n = (size_t)a.roi.width * a.roi.height;
        if (fit_ptc_pair(a.dn, b.dn, n, mu, s2) != 0)
            rc = err_set(err, -EINVAL, "a region of %zu pixels is too small for a variance", n);
    }
    cam_frame_free(&a);
    cam_frame_free(&b);
    return rc;
}

int ptc_run(cam_t *cam, ptc_light_fn light, void *light_ctx, const ptc_run_config_t *cfg,
            ptc_progress_fn progress, void *progress_ctx, fit_ptc_level_t *lv, err_t *err)
{
    if (cfg->levels < PTC_LEVELS_MIN || cfg->levels > PTC_LEVELS_MAX)
        return err_set(err, -EINVAL, "levels must be in [%d, %d] (got %d)", PTC_LEVELS_MIN,
                       PTC_LEVELS_MAX, cfg->levels);
    if (!(cfg->exposure_max_us > 0) || !isfinite(cfg->exposure_max_us))
        return err_set(err, -EINVAL, "largest exposure must be positive (got %g us)",
                       cfg->exposure_max_us);
    cam_info_t info;
    int rc = cam_get_info(cam, &info, err);
    if (rc) return rc;
    cam_roi_t roi = cfg->roi;
    if (roi.width == 0 && roi.height == 0) roi = (cam_roi_t){0, 0, info.width, info.height};
    for (int i = 0; i < cfg->levels && rc == 0; i++) {
        double t = cfg->exposure_max_us * (i + 1) / cfg->levels;
        lv[i].exposure_us = t;
        if ((rc = cam_set_exposure(cam, t, err)) != 0) break;
        if ((rc = light(light_ctx, 1, err)) != 0) break;
        if ((rc = pair(cam, &roi, &lv[i].mu_y, &lv[i].s2_y, err)) != 0) break;
        if ((rc = light(light_ctx, 0, err)) != 0) break;
        if ((rc = pair(cam, &roi, &lv[i].mu_dark, &lv[i].s2_dark, err)) != 0) break;
        if (progress && progress(progress_ctx, i + 1, cfg->levels))
            rc = err_set(err, -ECANCELED, "photon-transfer run stopped after %d levels", i + 1);
    }
    light(light_ctx, 0, NULL); /* off again after a failure too; the first error stands */
    return rc;
}

int ptc_sim_light(void *ctx, int on, err_t *err)
{
    ptc_sim_lamp_t *lamp = ctx;
    return sim_set_flat(lamp->sim, on ? lamp->flat_e : 0, err);
}
