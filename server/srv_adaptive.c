/* srv_adaptive.c: the points of an adaptive scan job (srv_adaptive.h): the starting raster, then
 * plan and measure batch after batch, every plan made from the points as stored (the database's
 * copy, so that a resumed scan plans from exactly what an uninterrupted one planned from). */
#include "srv_adaptive.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "server/srv_setup.h"

/* The POI's response at every stored point, in the order taken (positions relative to its
 * corner, the setup's constants). */
static int stored(storage_t *st, const storage_scan_t *sc, scanfile_t *sf, err_t *err)
{
    scanfile_free(sf);
    memset(sf, 0, sizeof *sf);
    int rc = srv_pixel_scan(st, sc, 0, 0, 1, sf, err);
    return rc == -ENODATA
               ? err_set(err, -EIO, "adaptive scan %lld: no setup stored", (long long)sc->id)
               : rc;
}

/* Points first.. of the given positions: on the simulated bench one at a time, each after the
 * noise is reseeded from the scan's seed and the point's index. */
static int take(cam_t *cam, stage_t *stage, sim_t *sim, unsigned long seed,
                const scan_config_t *cfg, const scan_setup_t *su, size_t first, size_t count,
                size_t n, const double *x, const double *y, const scan_hooks_t *hooks, err_t *err)
{
    if (!sim) return scan_subframe_points(cam, stage, cfg, su, first, count, n, x, y, hooks, err);
    int rc = 0;
    for (size_t i = 0; rc == 0 && i < n; i++) {
        /* a point's own seed: the scan's and its index mixed by the golden ratio's bits */
        sim_reseed(sim, (seed ^ (0x9e3779b9UL * (first + i + 1))) & 0xffffffffUL);
        rc = scan_subframe_points(cam, stage, cfg, su, first + i, count, 1, x + i, y + i, hooks,
                                  err);
    }
    return rc;
}

int srv_adaptive_capture(storage_t *st, const storage_scan_t *sc, cam_t *cam, stage_t *stage,
                         sim_t *sim, unsigned long seed, const scan_config_t *cfg,
                         const scan_setup_t *su, const srv_strategy_t *s, const scan_hooks_t *hooks,
                         srv_adaptive_planned_fn planned, void *user, srv_adaptive_outcome_t *out,
                         err_t *err)
{
    memset(out, 0, sizeof *out);
    fit_adapt_opts_t o = fit_adapt_opts_default();
    o.batch = s->batch;
    o.target_err = s->target_err;
    o.max_points = (size_t)s->max_points;
    size_t n0 = (size_t)s->start_grid * s->start_grid, count = (size_t)s->max_points;
    scanfile_t sf;
    memset(&sf, 0, sizeof sf);
    double *x = malloc(sizeof(double) * n0), *y = malloc(sizeof(double) * n0);
    int rc =
        x && y ? scan_pixel_box(stage, su, o.box_um, err) : err_set(err, -ENOMEM, "out of memory");
    int ns = rc ? 0 : fit_adapt_start(su->pitch_um, s->start_grid, o.box_um, x, y);
    if (rc == 0 && ns < 1)
        rc = err_set(err, -EINVAL,
                     "strategy.start_grid: no position of the %dx%d raster is "
                     "within the stage's travel",
                     s->start_grid, s->start_grid);
    o.start_points = (size_t)(ns > 0 ? ns : 0);
    if (rc == 0) rc = stored(st, sc, &sf, err);
    /* the starting raster, or what of it is not stored yet */
    if (rc == 0 && sf.scan.n < (size_t)ns)
        rc = take(cam, stage, sim, seed, cfg, su, sf.scan.n, count, (size_t)ns - sf.scan.n,
                  x + sf.scan.n, y + sf.scan.n, hooks, err);
    size_t k = (size_t)ns; /* the points the next plan sees: a batch boundary */
    fit_adapt_cache_t cache = {0}; /* the candidates' design rows, from plan to plan */
    while (rc == 0) {
        if ((rc = stored(st, sc, &sf, err))) break;
        size_t have = sf.scan.n;
        if (have < k) {
            rc = err_set(err, -EIO, "adaptive scan %lld: %zu points stored, %zu expected",
                         (long long)sc->id, have, k);
            break;
        }
        fit_scan_t prefix = sf.scan;
        prefix.n = k;
        fit_adapt_step_t step;
        rc = fit_adapt_plan(&prefix, &o, &cache, &step, err);
        out->plans++;
        out->plan_ms += step.ms;
        if (rc == 0) {
            out->stop = step.stop;
            out->expected_err = step.expected_err;
            out->points = have > k ? have : k;
        }
        if (rc == 0 && step.stop == FIT_ADAPT_GO) {
            size_t end = k + (size_t)step.n;
            if (end > have) { /* a batch to take, or the rest of one interrupted */
                size_t skip = have - k;
                if (planned) planned(have, step.expected_err, user);
                rc = take(cam, stage, sim, seed, cfg, su, have, count, end - have, step.x_um + skip,
                          step.y_um + skip, hooks, err);
            }
            k = end;
        } else if (rc == 0 && planned) {
            planned(out->points, step.expected_err, user);
        }
        int go = step.stop == FIT_ADAPT_GO;
        fit_adapt_step_free(&step);
        if (!go) break;
    }
    fit_adapt_cache_free(&cache);
    scanfile_free(&sf);
    free(x), free(y);
    return rc;
}
