/* stage.c: the motion stage interface's dispatch over its backends (see stage.h): the simulated
 * stage (stage_sim.c), the controller families (PI GCS 2.0: stage_gcs.c; Zaber ASCII:
 * stage_zaber.c) and the follower (stage_follow.c). */
#include "instrument/stage.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fit/gslerr.h"
#include "stage_impl.h"
#include "stage_url.h"

/* A handle over a backend's state; on failure the state is closed. */
static int wrap(const struct stage_ops *ops, void *impl, stage_t **out, err_t *err)
{
    stage_t *s = calloc(1, sizeof *s);
    if (!s) {
        ops->close(impl);
        return err_set(err, -ENOMEM, "out of memory for the stage");
    }
    s->ops = ops;
    s->impl = impl;
    *out = s;
    return 0;
}

int stage_open_sim(const stage_sim_config_t *cfg, stage_t **out, err_t *err)
{
    fit_gsl_policy(); /* GSL reports failures by return code, never by abort() */
    *out = NULL;
    void *impl;
    int rc = stage_sim_new(cfg, &impl, err);
    if (rc) return rc;
    return wrap(&stage_sim_ops, impl, out, err);
}

/* The controller families: the backend of a parsed stage string, its operations and opening. */
static const struct family {
    int url_backend; /* STAGE_URL_... */
    const struct stage_ops *ops;
    int (*open)(const stage_url_t *u, void **impl, err_t *err);
} families[] = {
    {STAGE_URL_GCS, &stage_gcs_ops, stage_gcs_new},
    {STAGE_URL_ZABER, &stage_zaber_ops, stage_zaber_new},
};

int stage_open(const char *backend, const char *id, stage_t **out, err_t *err)
{
    *out = NULL;
    if (!backend || strcmp(backend, "sim") == 0) {
        stage_sim_config_t cfg = stage_sim_config_default();
        return stage_open_sim(&cfg, out, err);
    }
    for (size_t f = 0; f < sizeof families / sizeof families[0]; f++)
        if (strcmp(backend, families[f].ops->backend) == 0) {
            char url[1100];
            if (!id || snprintf(url, sizeof url, "%s:%s", backend, id) >= (int)sizeof url)
                return err_set(err, -EINVAL, "%s stage: need an address", backend);
            return stage_open_url(url, out, err);
        }
    return err_set(err, -EINVAL, "unknown stage backend '%s' (sim, gcs, zaber)", backend);
}

int stage_url_check(const char *url, int *is_sim, err_t *err)
{
    stage_url_t u;
    int ret = stage_url_parse(url, &u, err);
    if (ret == 0 && is_sim) *is_sim = u.backend == STAGE_URL_SIM;
    return ret;
}

int stage_open_url(const char *url, stage_t **out, err_t *err)
{
    *out = NULL;
    stage_url_t u;
    int ret = stage_url_parse(url, &u, err);
    if (ret) return ret;
    if (u.backend == STAGE_URL_SIM) return stage_open("sim", NULL, out, err);
    for (size_t f = 0; f < sizeof families / sizeof families[0]; f++)
        if (u.backend == families[f].url_backend) {
            void *impl;
            if ((ret = families[f].open(&u, &impl, err))) return ret;
            return wrap(families[f].ops, impl, out, err);
        }
    return err_set(err, -EINVAL, "stage string names no backend"); /* not reached */
}

int stage_open_follow(stage_t *lead, stage_t *shadow, stage_t **out, err_t *err)
{
    *out = NULL;
    void *impl;
    int ret = stage_follow_new(lead, shadow, &impl, err);
    if (ret) {
        stage_close(lead);
        return ret;
    }
    return wrap(&stage_follow_ops, impl, out, err);
}

const char *stage_backend(const stage_t *stage)
{
    return stage->ops->backend;
}

const char *stage_identity(const stage_t *stage)
{
    return stage->ops->identity ? stage->ops->identity(stage->impl) : "";
}

void stage_close(stage_t *stage)
{
    if (!stage) return;
    stage->ops->close(stage->impl);
    free(stage);
}

int stage_move(stage_t *stage, const stage_pos_t *target, err_t *err)
{
    if (!isfinite(target->x_um) || !isfinite(target->y_um) || !isfinite(target->z_um))
        return err_set(err, -EINVAL, "stage target is not finite");
    stage_limits_t lim;
    int rc = stage->ops->limits(stage->impl, &lim, err);
    if (rc) return rc;
    const double *t = &target->x_um, *lo = &lim.min.x_um, *hi = &lim.max.x_um;
    static const char axis[] = "xyz";
    for (int a = 0; a < 3; a++)
        if (t[a] < lo[a] || t[a] > hi[a])
            return err_set(err, -ERANGE, "stage target %c = %g um is outside the travel [%g, %g]",
                           axis[a], t[a], lo[a], hi[a]);
    return stage->ops->move(stage->impl, target, err);
}

int stage_get_position(stage_t *stage, stage_pos_t *pos, err_t *err)
{
    return stage->ops->position(stage->impl, pos, err);
}

int stage_home(stage_t *stage, err_t *err)
{
    return stage->ops->home(stage->impl, err);
}

int stage_get_limits(stage_t *stage, stage_limits_t *limits, err_t *err)
{
    return stage->ops->limits(stage->impl, limits, err);
}

int stage_sim_true_position(stage_t *stage, stage_pos_t *pos)
{
    if (stage->ops != &stage_sim_ops) return -ENOTSUP;
    return stage_sim_true(stage->impl, pos);
}

int stage_sim_clock(stage_t *stage, double *seconds)
{
    if (stage->ops != &stage_sim_ops) return -ENOTSUP;
    *seconds = stage_sim_time(stage->impl);
    return 0;
}

int stage_sim_advance(stage_t *stage, double seconds)
{
    if (stage->ops != &stage_sim_ops) return -ENOTSUP;
    if (!(seconds >= 0) || !isfinite(seconds)) return -EINVAL;
    stage_sim_add_time(stage->impl, seconds);
    return 0;
}
