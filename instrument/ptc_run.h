/* ptc_run.h: the photon-transfer measurement (EMVA 1288) on a camera: at each of a series of
 * exposures, a pair of flats with the lamp on and a pair of darks with it off, reduced to the
 * pair statistics of fit/ptc.h (means and temporal variances over a region of interest). The lamp
 * is the caller's (a callback); on the simulated bench it is the flat field of sim_set_flat
 * (ptc_sim_light). The analysis is fit_ptc_analyse on the levels this returns. */
#ifndef IPSD_INSTRUMENT_PTC_RUN_H
#define IPSD_INSTRUMENT_PTC_RUN_H

#include "base/err.h"
#include "fit/ptc.h"
#include "instrument/cam.h"
#include "instrument/sim.h"

#define PTC_LEVELS_MIN 3
#define PTC_LEVELS_MAX 1000

typedef struct ptc_run_config {
    cam_roi_t roi;          /* the pixels measured (0 x 0: the whole array) */
    int levels;             /* exposures in the series (3..1000) */
    double exposure_max_us; /* the series: exposure_max_us * (i + 1) / levels, i = 0..levels-1 */
} ptc_run_config_t;

/* Switches the lamp on (1) or off (0); returns 0 or a negative errno with err. */
typedef int (*ptc_light_fn)(void *ctx, int on, err_t *err);

/* Called after each level (done of total); a non-zero answer stops the run with -ECANCELED.
 * May be NULL. */
typedef int (*ptc_progress_fn)(void *ctx, int done, int total);

/* Measures cfg->levels levels into lv (caller's, cfg->levels long). Returns 0, -EINVAL (bad
 * configuration, named in err), -ECANCELED, or the camera's or lamp's error. The camera's
 * exposure is left at the last level's and the lamp off. */
int ptc_run(cam_t *cam, ptc_light_fn light, void *light_ctx, const ptc_run_config_t *cfg,
            ptc_progress_fn progress, void *progress_ctx, fit_ptc_level_t *lv, err_t *err);

/* The lamp of the simulated bench (ctx: a ptc_sim_lamp_t): on sets the flat field to the e- per
 * pixel of ptc_sim_lamp_t.flat_e, off sets it to 0. */
typedef struct ptc_sim_lamp {
    sim_t *sim;
    double flat_e; /* e- per pixel per frame at the bench's reference exposure when on */
} ptc_sim_lamp_t;

int ptc_sim_light(void *lamp, int on, err_t *err);

#endif
