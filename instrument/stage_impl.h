/* stage_impl.h (internal to instrument/): how a stage backend plugs into stage.h: a table of
 * operations over the backend's state; stage.c wraps and dispatches. A controller family adds
 * its ops, an opening function from the parsed stage string (stage_url.h; it may use the shared
 * TCP / serial link of stage_link.h) and a line in stage.c's table of families. */
#ifndef IPSD_INSTRUMENT_STAGE_IMPL_H
#define IPSD_INSTRUMENT_STAGE_IMPL_H

#include "instrument/stage.h"

struct stage_ops {
    const char *backend;
    void (*close)(void *impl);
    int (*move)(void *impl, const stage_pos_t *target, err_t *err);
    int (*position)(void *impl, stage_pos_t *pos, err_t *err);
    int (*home)(void *impl, err_t *err);
    int (*limits)(void *impl, stage_limits_t *limits, err_t *err);
    const char *(*identity)(void *impl); /* what the controller says it is (NULL: "") */
};

struct stage {
    const struct stage_ops *ops;
    void *impl;
};

/* The simulated backend's operations (stage_sim.c); stage.c recognises them for the sim-only
 * calls. */
extern const struct stage_ops stage_sim_ops;
int stage_sim_true(void *impl, stage_pos_t *pos);
double stage_sim_time(void *impl);
void stage_sim_add_time(void *impl, double seconds);
int stage_sim_new(const stage_sim_config_t *cfg, void **impl, err_t *err);

/* The controller families, opened from a parsed stage string (connect, reference, read the
 * limits): PI GCS 2.0 (stage_gcs.c; identity: the *IDN? reply) and Zaber ASCII (stage_zaber.c;
 * identity: the devices' device IDs and firmware versions). */
struct stage_url;
extern const struct stage_ops stage_gcs_ops;
int stage_gcs_new(const struct stage_url *u, void **impl, err_t *err);
extern const struct stage_ops stage_zaber_ops;
int stage_zaber_new(const struct stage_url *u, void **impl, err_t *err);

/* The follower (stage_follow.c): a lead stage that a shadow stage follows. */
extern const struct stage_ops stage_follow_ops;
int stage_follow_new(stage_t *lead, stage_t *shadow, void **impl, err_t *err);

#endif
