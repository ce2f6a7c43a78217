/* srv_adaptive.h: the points of an adaptive scan job (internal to server/): the scan worker's
 * alternative to the raster when a scan's strategy is adaptive (srv_params.h srv_strategy_t).
 * Runs on the scan worker's thread, which owns the instrument; the planning (fit/adapt_plan.h,
 * 60-140 ms a step) runs there too. */
#ifndef IPSD_SERVER_SRV_ADAPTIVE_H
#define IPSD_SERVER_SRV_ADAPTIVE_H

#include <stddef.h>

#include "base/err.h"
#include "fit/adapt_plan.h"
#include "instrument/scan.h"
#include "instrument/sim.h"
#include "server/srv_params.h"
#include "storage/storage.h"

/* How an adaptive scan ended. */
typedef struct srv_adaptive_outcome {
    fit_adapt_stop_t stop; /* target, budget or no_gain */
    size_t points;         /* points the scan holds */
    double expected_err;   /* the expected rms error of the map of those points */
    int plans;             /* planning steps of this run (replays of a resume included) */
    double plan_ms;        /* their time */
} srv_adaptive_outcome_t;

/* Called before each batch this run takes: the points so far and the map's expected error. */
typedef void (*srv_adaptive_planned_fn)(size_t points, double expected_err, void *user);

/* Takes the points of scan sc (its setup su stored already) with strategy s: the starting
 * start_grid^2 raster over the POI (fit_adapt_start), then plan (fit_adapt_plan on the points
 * stored so far, read back from the database) and measure the batch, until the planner stops.
 * Each point is captured with scan_subframe_points and handed to hooks->point (the caller
 * stores it as a raster point, index = the order taken). A resumed scan replays the plans from
 * the prefixes of its stored points (the planner is deterministic), so a batch interrupted half
 * way is finished with the positions it had, and the scan ends with the positions an
 * uninterrupted run takes when the points read the same values: on the simulated bench (sim, NULL
 * for a real camera) each point's noise is drawn from its own seed, from the scan's seed and the
 * point's index (sim_reseed), so a resumed scan reads what an uninterrupted one read. planned (may
 * be NULL) with user sees each batch's plan. Returns 0 with *out, -ECANCELED (stopped), or the
 * planner's, camera's, stage's or storage's error. */
int srv_adaptive_capture(storage_t *st, const storage_scan_t *sc, cam_t *cam, stage_t *stage,
                         sim_t *sim, unsigned long seed, const scan_config_t *cfg,
                         const scan_setup_t *su, const srv_strategy_t *s, const scan_hooks_t *hooks,
                         srv_adaptive_planned_fn planned, void *user, srv_adaptive_outcome_t *out,
                         err_t *err);

#endif
