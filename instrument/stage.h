/* stage.h: the motion stage interface: absolute moves in x, y, z (micrometres), position read
 * back, homing and travel limits. The default backend is the simulated stage ("sim"); a driver for
 * a real controller plugs in through stage_impl.h like the camera backends do.
 *
 * The simulated stage reports the position it was commanded to (an open-loop stage without
 * encoders) while its true position, which the simulated bench's optics use, differs by
 *   - a positioning error: an independent Gaussian offset per axis drawn at every move
 *     (position_sigma_um), and
 *   - slow thermal drift: drift_um * (1 - exp(-t / drift_tau_s)) per axis, t the bench time since
 *     the lamp was switched on. The paper pre-warms its lamp for 4 h so that only the flat tail
 *     of this curve falls in a scan: prewarm_s starts the clock that late.
 * Both are off by default. The stage keeps the bench's virtual clock: moves take
 * settle_s + distance / speed_um_s, and the simulated camera adds each exposure and read-out. */
#ifndef IPSD_INSTRUMENT_STAGE_H
#define IPSD_INSTRUMENT_STAGE_H

#include "base/err.h"

typedef struct stage stage_t;

typedef struct stage_pos {
    double x_um, y_um, z_um;
} stage_pos_t;

typedef struct stage_limits {
    stage_pos_t min, max; /* travel range, inclusive */
} stage_limits_t;

typedef struct stage_sim_config {
    stage_limits_t limits;    /* default x, y in [-50000, 50000] um, z in [-5000, 5000] um */
    stage_pos_t home;         /* where homing goes (0, 0, 0) */
    double position_sigma_um; /* Gaussian positioning error per axis, per move (0) */
    double drift_um[3];       /* thermal drift amplitude in x, y, z (0) */
    double drift_tau_s;       /* its time constant (3600 s) */
    double prewarm_s;         /* bench time at opening: lamp on this long already (0) */
    double speed_um_s;        /* travel speed, for the clock (1000 um/s) */
    double settle_s;          /* settling time per move (0.05 s) */
    unsigned long seed;       /* random numbers of the positioning error */
} stage_sim_config_t;

stage_sim_config_t stage_sim_config_default(void);

/* Opens stage id of backend ("sim": a simulated stage with the default configuration, id
 * ignored). *out is the caller's (stage_close). Returns 0, -EINVAL (unknown backend) or -ENOMEM. */
int stage_open(const char *backend, const char *id, stage_t **out, err_t *err);

/* Opens a simulated stage with cfg. Returns 0, -EINVAL (bad configuration) or -ENOMEM. */
int stage_open_sim(const stage_sim_config_t *cfg, stage_t **out, err_t *err);

/* Closes the stage; accepts NULL. */
void stage_close(stage_t *stage);

/* Moves to target (absolute). Returns 0, -ERANGE (outside the limits: the stage does not move)
 * or a backend error. */
int stage_move(stage_t *stage, const stage_pos_t *target, err_t *err);

/* The position the stage reports. */
int stage_get_position(stage_t *stage, stage_pos_t *pos, err_t *err);

/* Moves to the home position. */
int stage_home(stage_t *stage, err_t *err);

int stage_get_limits(stage_t *stage, stage_limits_t *limits, err_t *err);

/* Simulated stages only (-ENOTSUP otherwise): where the stage really is now (commanded position
 * plus positioning error plus drift), the bench clock in seconds, and advancing that clock. */
int stage_sim_true_position(stage_t *stage, stage_pos_t *pos);
int stage_sim_clock(stage_t *stage, double *seconds);
int stage_sim_advance(stage_t *stage, double seconds);

#endif
