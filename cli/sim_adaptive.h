/* sim_adaptive.h: `ips simulate --adaptive`: an adaptive scan of the POI on the simulated bench
 * (cmd_simulate.c sets the bench up as for --grid: the spot at the POI's true centre, no setup),
 * planned by fit/adapt_plan.h batch by batch, and its report against the simulator's truth. */
#ifndef IPSD_CLI_SIM_ADAPTIVE_H
#define IPSD_CLI_SIM_ADAPTIVE_H

#include <stddef.h>

#include <jansson.h>

#include "base/err.h"
#include "instrument/scan.h"
#include "instrument/scanfile.h"
#include "instrument/sim.h"

typedef struct cli_adaptive {
    int start_grid;    /* n0: the starting raster n0 x n0 (fit_adapt_start) */
    int batch;         /* positions a batch */
    double target_err; /* stop at this expected rms error */
    size_t max_points; /* or at this many points */
} cli_adaptive_t;

/* The defaults of fit/adapt_plan.h. */
cli_adaptive_t cli_adaptive_default(void);

/* Scans the POI of sim adaptively with cfg (frames, use_expected) from setup su (its centre the
 * POI's centre, as the scan file says): the starting raster, then batch after batch until the
 * planner stops. *sf (zeroed by the caller) gets every point in the order taken (the caller's,
 * scanfile_free, also after an error); *report a new JSON object: the options, each batch (the
 * points it added, the stage's path, the error the planner predicted for it, and the expected
 * error and the rms error against the scene's truth of the kriged map after it), the stop
 * reason and the final errors. Returns 0 or a negative errno with err. */
int cli_adaptive_run(sim_t *sim, const scan_config_t *cfg, const scan_setup_t *su,
                     const cli_adaptive_t *ad, scanfile_t *sf, json_t **report, err_t *err);

#endif
