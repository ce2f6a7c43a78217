/* stage_follow.c: a stage made of two (stage.h, stage_open_follow): the lead stage moves and
 * reports; after each of its moves the shadow stage is moved to the position the lead reports.
 * This is how the simulated camera works with a real stage: the simulated bench's optics put the
 * spot where its own (shadow) stage is, so it follows the position the real controller reports
 * (POS?), and the bench clock advances by the shadow's move time. */
#include <errno.h>
#include <stdlib.h>

#include "stage_impl.h"

struct follow {
    stage_t *lead;   /* owned */
    stage_t *shadow; /* borrowed */
};

static void follow_close(void *impl)
{
    struct follow *f = impl;
    if (!f) return;
    stage_close(f->lead);
    free(f);
}

/* The shadow to where the lead reports it is. */
static int catch_up(struct follow *f, err_t *err)
{
    stage_pos_t p;
    int ret = stage_get_position(f->lead, &p, err);
    return ret ? ret : stage_move(f->shadow, &p, err);
}

static int follow_move(void *impl, const stage_pos_t *t, err_t *err)
{
    struct follow *f = impl;
    int ret = stage_move(f->lead, t, err);
    return ret ? ret : catch_up(f, err);
}

static int follow_position(void *impl, stage_pos_t *pos, err_t *err)
{
    return stage_get_position(((struct follow *)impl)->lead, pos, err);
}

static const char *follow_identity(void *impl)
{
    return stage_identity(((struct follow *)impl)->lead);
}

static int follow_home(void *impl, err_t *err)
{
    struct follow *f = impl;
    int ret = stage_home(f->lead, err);
    return ret ? ret : catch_up(f, err);
}

/* Where both can go: the intersection of the two travels. */
static int follow_limits(void *impl, stage_limits_t *lim, err_t *err)
{
    struct follow *f = impl;
    stage_limits_t s;
    int ret = stage_get_limits(f->lead, lim, err);
    if (ret || (ret = stage_get_limits(f->shadow, &s, err))) return ret;
    double *lo = &lim->min.x_um, *hi = &lim->max.x_um, *slo = &s.min.x_um, *shi = &s.max.x_um;
    for (int a = 0; a < 3; a++) {
        if (slo[a] > lo[a]) lo[a] = slo[a];
        if (shi[a] < hi[a]) hi[a] = shi[a];
    }
    return 0;
}

const struct stage_ops stage_follow_ops = {
    .backend = "follow",
    .close = follow_close,
    .move = follow_move,
    .position = follow_position,
    .home = follow_home,
    .limits = follow_limits,
    .identity = follow_identity,
};

int stage_follow_new(stage_t *lead, stage_t *shadow, void **impl, err_t *err)
{
    struct follow *f = calloc(1, sizeof *f);
    if (!f) return err_set(err, -ENOMEM, "out of memory for the stage");
    f->lead = lead;
    f->shadow = shadow;
    *impl = f;
    return 0;
}
