/* stage.h: the motion stage interface: absolute moves in x, y, z (micrometres), position read
 * back, homing and travel limits. Backends: the simulated stage ("sim", the default) and PI
 * controllers speaking GCS 2.0 over TCP or a serial line ("gcs", stage_gcs.c) and Zaber devices
 * speaking the Zaber ASCII protocol ("zaber", stage_zaber.c); a driver for
 * another controller plugs in through stage_impl.h like the camera backends do.
 *
 * The stage string (ipsd --stage, stage_open_url) names a backend and its connection:
 *   sim
 *   gcs:tcp://HOST:PORT[?OPTIONS]          (PI's controllers listen on port 50000)
 *   gcs:serial:/dev/DEVICE[?OPTIONS]       (raw 8N1; a pseudo-terminal works too)
 *   zaber:tcp://HOST:PORT?step_um=S[&...]  (Zaber's Ethernet devices; serial-to-TCP servers)
 *   zaber:serial:/dev/DEVICE?step_um=S[&...]
 * OPTIONS, joined by &, common to both families: axes=A,B[,C] (the axes of x, y and z: GCS axis
 * identifiers, or Zaber axis numbers 1..9; 1,2,3; with two axes z is fixed at 0), baud=N
 * (serial: 115200), timeout=S (a reply within S seconds: 5), move_timeout=S (a move or
 * referencing done within S: 60), poll_ms=N (pause between on-target or idle polls: 10),
 * reference=0|1 (reference unreferenced axes at opening, GCS FRF or Zaber home: 1; 0 refuses to
 * open them instead).
 * GCS only: unit=mm|um (the controller's position unit, mm).
 * Zaber only: step_um=S (required: micrometres per microstep, the unit of Zaber positions, from
 * the stage's data sheet), device=N (the device number of every axis: 1), devices=D,D[,D] (one
 * device number per axis, for daisy-chained single-axis devices: devices=1,2&axes=1,1).
 *
 * Errors of a GCS stage: -ERANGE outside the travel (TMN? .. TMX?, checked before moving, or
 * the controller's error 7), -EPERM a move the controller refuses now (error 5: servo off or
 * axis unreferenced), -EIO another controller error or a lost connection, -ETIMEDOUT no reply
 * within timeout= or not on target within move_timeout=. Controller errors carry the GCS code
 * and its text in err. After a lost connection the next call reconnects.
 * Errors of a Zaber stage: -ERANGE outside the travel (limit.min .. limit.max, checked before
 * moving, or the device's rejection BADDATA of a move), -EPERM an axis without a reference
 * position (warning WR / WH) or parked, -EIO another rejection (its reason in err), a fault flag
 * (F*), an unexpected limit switch (WL), an interrupted move (NI), or a lost connection,
 * -ETIMEDOUT as for GCS. After a lost connection the next call reconnects.
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
 * ignored; "gcs", "zaber": id is the stage string without its "gcs:" or "zaber:"). *out is the
 * caller's (stage_close).
 * Returns 0, -EINVAL (unknown backend) or -ENOMEM. */
int stage_open(const char *backend, const char *id, stage_t **out, err_t *err);

/* Opens the stage a stage string names (above). Returns 0, -EINVAL (bad string, named in err),
 * a connection error (-ECONNREFUSED, -ENOENT, -ETIMEDOUT, -EIO) or a controller error. */
int stage_open_url(const char *url, stage_t **out, err_t *err);

/* Checks a stage string without opening anything; *is_sim (may be NULL) says whether it names
 * the simulated stage. Returns 0 or -EINVAL with err saying what is wrong. */
int stage_url_check(const char *url, int *is_sim, err_t *err);

/* A stage that moves lead and, after each of its moves, moves shadow to the position lead
 * reports; its position is lead's, its travel the intersection of both. It takes lead (closed
 * with it, also on failure) and borrows shadow. Used to drive the simulated bench's optics (its
 * stage is the shadow) from a real stage. */
int stage_open_follow(stage_t *lead, stage_t *shadow, stage_t **out, err_t *err);

/* The backend's name ("sim", "gcs", "zaber", "follow") and what the controller says it is (a GCS
 * stage's *IDN? reply; a Zaber stage's device IDs and firmware versions; a follower's lead's;
 * "" for the simulated stage). Borrowed, valid until stage_close. */
const char *stage_backend(const stage_t *stage);
const char *stage_identity(const stage_t *stage);

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
