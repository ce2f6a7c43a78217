/* sim.c: the simulated bench (see sim.h): its configuration, opening and closing, the stage and
 * where the spot really is, the expected image of a spot (photometry over the memoised pixel
 * integrals of sim_memo.c), and the work counters. The spot's optics are in sim_optics.c, the
 * leave-out rule in sim_leaveout.c, the camera that draws frames from the expected image in
 * cam_sim.c (sim_int.h says who does what). */
#include "instrument/sim.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_rng.h>

#include "base/clock.h"
#include "cam_roi.h"
#include "fit/airy.h"
#include "fit/design.h"
#include "fit/gslerr.h"
#include "instrument/scan_limits.h"
#include "sim_int.h"

sim_config_t sim_config_default(void)
{
    return (sim_config_t){
        .scene = "paperlike",
        .sensor = scene_sensor_default(),
        .wavelength_um = SCAN_DEFAULT_WAVELENGTH_NM * 1e-3, /* the scan's defaults (scan_limits.h) */
        .na = SCAN_DEFAULT_NA,
        .radius_um = 0,
        .z_focus_um = 0,
        .depth_um = 0,
        .flux_e = 21500,
        .flat_e = 0,
        .ref_exposure_us = 10000,
        .readout_s = 0.02,
        .noiseless = 0,
        .leave_out_tol = 1e-4,
        .design_tol = 1e-7,
        .temperature_c = 25,
        .seed = SCAN_DEFAULT_SEED,
        .stage = stage_sim_config_default(),
    };
}

static int check_config(const sim_config_t *c, err_t *err)
{
    if (!(c->radius_um >= 0) || !isfinite(c->radius_um))
        return err_set(err, -EINVAL,
                       "spot radius must be >= 0 (got %g um; 0: from wavelength "
                       "and NA)",
                       c->radius_um);
    if (!(c->wavelength_um > 0) || !isfinite(c->wavelength_um))
        return err_set(err, -EINVAL, "wavelength must be positive (got %g um)", c->wavelength_um);
    if (!(c->na > 0 && c->na < 1))
        return err_set(err, -EINVAL, "numerical aperture must be in (0, 1) (got %g)", c->na);
    if (!(c->depth_um >= 0) || !isfinite(c->depth_um) || !isfinite(c->z_focus_um))
        return err_set(err, -EINVAL, "focus position must be finite and depth >= 0");
    if (!isfinite(c->mount_x_um) || !isfinite(c->mount_y_um))
        return err_set(err, -EINVAL, "mount offset must be finite");
    if (!(c->flux_e >= 0) || !isfinite(c->flux_e))
        return err_set(err, -EINVAL, "spot flux must be >= 0 (got %g e-)", c->flux_e);
    if (!(c->flat_e >= 0) || !isfinite(c->flat_e))
        return err_set(err, -EINVAL, "flat field must be >= 0 (got %g e-)", c->flat_e);
    if (!(c->ref_exposure_us > 0) || !isfinite(c->ref_exposure_us))
        return err_set(err, -EINVAL, "reference exposure must be positive (got %g us)",
                       c->ref_exposure_us);
    if (!(c->readout_s >= 0) || !isfinite(c->readout_s))
        return err_set(err, -EINVAL, "read-out time must be >= 0 (got %g s)", c->readout_s);
    if (!(c->leave_out_tol >= 0 && c->leave_out_tol < 1))
        return err_set(err, -EINVAL, "leave-out tolerance must be in [0, 1) (got %g)",
                       c->leave_out_tol);
    if (!(c->design_tol >= 1e-15 && c->design_tol <= 1e-2))
        return err_set(err, -EINVAL, "integration accuracy must be in [1e-15, 1e-2] (got %g)",
                       c->design_tol);
    return 0;
}

int sim_open(const sim_config_t *cfg, sim_t **out, err_t *err)
{
    fit_gsl_policy(); /* GSL reports failures by return code, never by abort() */
    *out = NULL;
    int rc = check_config(cfg, err);
    if (rc) return rc;
    sim_t *s = calloc(1, sizeof *s);
    if (!s) return err_set(err, -ENOMEM, "out of memory for the simulated bench");
    s->cfg = *cfg;
    snprintf(s->scene_spec, sizeof s->scene_spec, "%s", cfg->scene ? cfg->scene : "paperlike");
    s->cfg.scene = s->scene_spec;
    rc = scene_open(s->scene_spec, &cfg->sensor, &s->scene, err);
    if (rc) goto fail;
    rc = stage_open_sim(&cfg->stage, &s->stage, err);
    if (rc) goto fail;
    s->map = scene_map(s->scene, &s->m);
    s->st = *scene_stats(s->scene);
    if ((rc = sim_levels_build(s)) != 0) {
        rc = err_set(err, rc, "out of memory for the map's levels");
        goto fail;
    }
    sim_optics_init(s);
    s->opts = fit_design_opts_for_tol(cfg->design_tol);
    s->exposure_us = cfg->ref_exposure_us;
    s->gain = 1;
    s->rng = gsl_rng_alloc(gsl_rng_mt19937);
    if (!s->rng || sim_memo_init(s) != 0) {
        rc = err_set(err, -ENOMEM, "out of memory for the simulated bench");
        goto fail;
    }
    gsl_rng_set(s->rng, cfg->seed);
    *out = s;
    return 0;
fail:
    sim_close(s);
    return rc;
}

void sim_close(sim_t *s)
{
    if (!s) return;
    if (s->cam) s->cam_release(s->cam);
    stage_close(s->stage);
    scene_close(s->scene);
    gsl_rng_free(s->rng);
    sim_memo_free(s);
    sim_levels_free(s);
    free(s);
}

void sim_reseed(sim_t *s, unsigned long seed)
{
    gsl_rng_set(s->rng, seed);
}

stage_t *sim_stage(sim_t *s)
{
    return s->stage;
}

const scene_t *sim_scene(const sim_t *s)
{
    return s->scene;
}

void sim_spot(sim_t *s, double *x, double *y, double *z)
{
    stage_pos_t p;
    stage_sim_true_position(s->stage, &p);
    *x = p.x_um + s->cfg.mount_x_um;
    *y = p.y_um + s->cfg.mount_y_um;
    *z = p.z_um;
}

stage_pos_t sim_pixel_centre(const sim_t *s, int col, int row)
{
    double p = s->cfg.sensor.pitch_um;
    return (stage_pos_t){(col + 0.5) * p - s->cfg.mount_x_um, (row + 0.5) * p - s->cfg.mount_y_um,
                         s->cfg.z_focus_um};
}

int sim_expected(sim_t *s, double xs, double ys, double R_um, const cam_roi_t *roi, double *e_out,
                 double *left_out_e, err_t *err)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    cam_roi_t r;
    int rc = cam_roi_check(roi, sn->cols, sn->rows, &r, err);
    if (rc) return rc;
    if (!(R_um > 0) || !isfinite(R_um) || !isfinite(xs) || !isfinite(ys) || fabs(xs) > 1e8 ||
        fabs(ys) > 1e8)
        return err_set(err, -EINVAL, "spot at (%g, %g) um with radius %g um is not usable", xs, ys,
                       R_um);
    size_t npx = (size_t)r.width * r.height;
    double *bnd = malloc(sizeof(double) * npx);
    if (!bnd) return err_set(err, -ENOMEM, "out of memory for %zu pixels", npx);
    double t0 = clock_mono_s();
    rc = sim_memo_integrate(s, xs, ys, R_um, &r, e_out, bnd, err);
    s->stats.integrate_s += clock_mono_s() - t0;
    if (rc == 0) {
        /* electrons = flux (t / t_ref) * integral / whole-plane integral (sim.h photometry) */
        double scale = s->cfg.flux_e * (s->exposure_us / s->cfg.ref_exposure_us) /
                       fit_airy_total(fit_airy_a(R_um));
        double worst = 0;
        for (size_t k = 0; k < npx; k++) {
            e_out[k] *= scale;
            if (bnd[k] * scale > worst) worst = bnd[k] * scale;
        }
        if (left_out_e) *left_out_e = worst;
    }
    free(bnd);
    return rc;
}

void sim_get_stats(const sim_t *s, sim_stats_t *stats)
{
    *stats = s->stats;
}

void sim_reset_stats(sim_t *s)
{
    memset(&s->stats, 0, sizeof s->stats);
}
