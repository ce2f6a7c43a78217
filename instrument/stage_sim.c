/* stage_sim.c: the simulated motion stage (see stage.h): commanded position, positioning error,
 * thermal drift and the bench's virtual clock. Random numbers: GSL mt19937 seeded from cfg. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

#include "stage_impl.h"

struct simstage {
    stage_sim_config_t cfg;
    stage_pos_t cmd; /* commanded (and reported) position */
    double error[3]; /* positioning error of the last move */
    double t_s;      /* bench time since the lamp was switched on */
    gsl_rng *rng;
};

stage_sim_config_t stage_sim_config_default(void)
{
    return (stage_sim_config_t){
        .limits = {.min = {-50000, -50000, -5000}, .max = {50000, 50000, 5000}},
        .home = {0, 0, 0},
        .position_sigma_um = 0,
        .drift_um = {0, 0, 0},
        .drift_tau_s = 3600,
        .prewarm_s = 0,
        .speed_um_s = 1000,
        .settle_s = 0.05,
        .seed = 1,
    };
}

static void simstage_close(void *impl)
{
    struct simstage *s = impl;
    if (!s) return;
    gsl_rng_free(s->rng);
    free(s);
}

static int simstage_move(void *impl, const stage_pos_t *t, err_t *err)
{
    (void)err;
    struct simstage *s = impl;
    double d = sqrt((t->x_um - s->cmd.x_um) * (t->x_um - s->cmd.x_um) +
                    (t->y_um - s->cmd.y_um) * (t->y_um - s->cmd.y_um) +
                    (t->z_um - s->cmd.z_um) * (t->z_um - s->cmd.z_um));
    s->cmd = *t;
    for (int a = 0; a < 3; a++)
        s->error[a] = s->cfg.position_sigma_um > 0
                          ? gsl_ran_gaussian_ziggurat(s->rng, s->cfg.position_sigma_um)
                          : 0;
    s->t_s += s->cfg.settle_s + d / s->cfg.speed_um_s;
    return 0;
}

static int simstage_position(void *impl, stage_pos_t *pos, err_t *err)
{
    (void)err;
    *pos = ((struct simstage *)impl)->cmd;
    return 0;
}

static int simstage_home(void *impl, err_t *err)
{
    struct simstage *s = impl;
    return simstage_move(impl, &s->cfg.home, err);
}

static int simstage_limits(void *impl, stage_limits_t *lim, err_t *err)
{
    (void)err;
    *lim = ((struct simstage *)impl)->cfg.limits;
    return 0;
}

const struct stage_ops stage_sim_ops = {
    .backend = "sim",
    .close = simstage_close,
    .move = simstage_move,
    .position = simstage_position,
    .home = simstage_home,
    .limits = simstage_limits,
};

int stage_sim_true(void *impl, stage_pos_t *pos)
{
    struct simstage *s = impl;
    /* warm-up drift: d(t) = A (1 - exp(-t / tau)), t counted from switching the lamp on */
    double f = 1.0 - exp(-s->t_s / s->cfg.drift_tau_s);
    pos->x_um = s->cmd.x_um + s->error[0] + s->cfg.drift_um[0] * f;
    pos->y_um = s->cmd.y_um + s->error[1] + s->cfg.drift_um[1] * f;
    pos->z_um = s->cmd.z_um + s->error[2] + s->cfg.drift_um[2] * f;
    return 0;
}

double stage_sim_time(void *impl)
{
    return ((struct simstage *)impl)->t_s;
}

void stage_sim_add_time(void *impl, double seconds)
{
    ((struct simstage *)impl)->t_s += seconds;
}

int stage_sim_new(const stage_sim_config_t *cfg, void **impl, err_t *err)
{
    *impl = NULL;
    const double *lo = &cfg->limits.min.x_um, *hi = &cfg->limits.max.x_um, *h = &cfg->home.x_um;
    for (int a = 0; a < 3; a++)
        if (!(lo[a] <= hi[a]) || !isfinite(lo[a]) || !isfinite(hi[a]) || h[a] < lo[a] ||
            h[a] > hi[a])
            return err_set(err, -EINVAL, "stage limits must be finite, min <= max, and hold home");
    for (int a = 0; a < 3; a++)
        if (!isfinite(cfg->drift_um[a])) return err_set(err, -EINVAL, "stage drift must be finite");
    if (!(cfg->position_sigma_um >= 0) || !isfinite(cfg->position_sigma_um))
        return err_set(err, -EINVAL, "stage positioning error must be >= 0 (got %g um)",
                       cfg->position_sigma_um);
    if (!(cfg->drift_tau_s > 0) || !(cfg->prewarm_s >= 0) || !(cfg->speed_um_s > 0) ||
        !(cfg->settle_s >= 0) || !isfinite(cfg->prewarm_s) || !isfinite(cfg->settle_s))
        return err_set(err, -EINVAL,
                       "stage drift time constant and speed must be positive, "
                       "pre-warm and settling times >= 0");
    struct simstage *s = calloc(1, sizeof *s);
    if (s) s->rng = gsl_rng_alloc(gsl_rng_mt19937);
    if (!s || !s->rng) {
        free(s);
        return err_set(err, -ENOMEM, "out of memory for the simulated stage");
    }
    gsl_rng_set(s->rng, cfg->seed);
    s->cfg = *cfg;
    s->cmd = cfg->home;
    s->t_s = cfg->prewarm_s;
    *impl = s;
    return 0;
}
