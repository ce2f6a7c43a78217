/* scan_raster.c: the raster of the paper's scan procedure (scan.h): the lattice of positions
 * around the centre the setup found, capturing k frames of the m x m sub-frame at each point, and
 * the raster's memory form (scan_raster_t) that points are stored into or read back into. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan_limits.h"
#include "scan_int.h"

stage_pos_t scan_raster_position(const scan_config_t *cfg, const scan_setup_t *su, int nx,
                                 size_t index)
{
    int ix = (int)(index % (size_t)nx), iy = (int)(index / (size_t)nx);
    double h = (nx - 1) / 2.0;
    return (stage_pos_t){su->centre.x_um + (ix - h) * cfg->step_um,
                         su->centre.y_um + (iy - h) * cfg->step_um, su->centre.z_um};
}

int scan_raster_init(scan_raster_t *r, const scan_config_t *cfg, const scan_setup_t *su, err_t *err)
{
    memset(r, 0, sizeof *r);
    int rc = scan_config_check(cfg, NULL, err);
    if (rc) return rc;
    int nx;
    rc = scan_check_raster(su->pitch_um, cfg->area_px, cfg->step_um, "step_um", &nx, err);
    if (rc) return rc;
    size_t count = (size_t)nx * nx, mm = (size_t)cfg->subframe_px * cfg->subframe_px;
    r->cfg = *cfg;
    r->setup = *su;
    r->nx = nx;
    r->count = count;
    r->m = cfg->subframe_px;
    r->pos = calloc(count, sizeof *r->pos);
    r->mean_dn = calloc(count * mm, sizeof(double));
    r->var_dn = calloc(count * mm, sizeof(double));
    r->have = calloc(count, 1);
    if (cfg->keep_frames) r->raw = calloc(count * mm * (size_t)cfg->frames, sizeof(uint16_t));
    if (!r->pos || !r->mean_dn || !r->var_dn || !r->have || (cfg->keep_frames && !r->raw)) {
        scan_raster_free(r);
        return err_set(err, -ENOMEM, "out of memory for a raster of %zu points", count);
    }
    return 0;
}

void scan_raster_free(scan_raster_t *r)
{
    if (!r) return;
    free(r->pos);
    free(r->mean_dn);
    free(r->var_dn);
    free(r->raw);
    free(r->have);
    memset(r, 0, sizeof *r);
}

int scan_raster_put(scan_raster_t *r, const scan_point_t *pt, err_t *err)
{
    if (pt->index >= r->count || pt->width != r->m || pt->height != r->m)
        return err_set(err, -EINVAL,
                       "point %zu (%dx%d) does not fit the raster (%zu points, "
                       "%dx%d)",
                       pt->index, pt->width, pt->height, r->count, r->m, r->m);
    size_t mm = (size_t)r->m * r->m;
    r->pos[pt->index] = pt->reported;
    memcpy(r->mean_dn + pt->index * mm, pt->mean_dn, sizeof(double) * mm);
    if (pt->var_dn) memcpy(r->var_dn + pt->index * mm, pt->var_dn, sizeof(double) * mm);
    if (r->raw && pt->raw && pt->frames == r->cfg.frames)
        memcpy(r->raw + pt->index * mm * (size_t)pt->frames, pt->raw,
               sizeof(uint16_t) * mm * (size_t)pt->frames);
    if (!r->have[pt->index]) r->captured++;
    r->have[pt->index] = 1;
    return 0;
}

int scan_raster_run(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_setup_t *su,
                    size_t first, const scan_hooks_t *hooks, scan_raster_t *raster, err_t *err)
{
    cam_info_t info;
    int rc = cam_get_info(cam, &info, err);
    if (rc == 0) rc = scan_config_check(cfg, &info, err);
    if (rc) return rc;
    int nx, m = cfg->subframe_px, k = cfg->frames;
    if ((rc = scan_check_raster(su->pitch_um, cfg->area_px, cfg->step_um, "step_um", &nx, err)))
        return rc;
    size_t count = (size_t)nx * nx, mm = (size_t)m * m;
    if (first > count) return err_set(err, -EINVAL, "first point %zu beyond %zu", first, count);
    if ((rc = cam_set_gain(cam, su->gain, err)) ||
        (rc = cam_set_exposure(cam, su->exposure_us, err)))
        return rc;
    cam_roi_t roi = {cfg->poi_col - m / 2, cfg->poi_row - m / 2, m, m};
    struct scan_capture c = {.mean = malloc(sizeof(double) * 2 * mm)};
    c.var = c.mean ? c.mean + mm : NULL;
    if (cfg->keep_frames) c.raw = malloc(sizeof(uint16_t) * mm * (size_t)k);
    c.ts_ns = malloc(sizeof(int64_t) * (size_t)k);
    c.ids = malloc(sizeof(uint64_t) * (size_t)k);
    if (!c.mean || (cfg->keep_frames && !c.raw) || !c.ts_ns || !c.ids) {
        rc = err_set(err, -ENOMEM, "out of memory for a %dx%d sub-frame", m, m);
        goto out;
    }
    for (size_t i = first; i < count; i++) {
        if (scan_stopped(hooks)) {
            rc = err_set(err, -ECANCELED, "scan stopped before raster point %zu of %zu", i, count);
            goto out;
        }
        stage_pos_t pos = scan_raster_position(cfg, su, nx, i);
        if ((rc = scan_capture_at(cam, stage, &pos, &roi, k, cfg->use_expected, &c, err)) != 0)
            goto out;
        scan_point_t pt = scan_point_of_capture(&c, i, count, (int)(i % (size_t)nx),
                                                 (int)(i / (size_t)nx), &pos, k, m);
        if (raster && (rc = scan_raster_put(raster, &pt, err)) != 0) goto out;
        if (hooks && hooks->point && hooks->point(&pt, hooks->user) != 0) {
            rc = err_set(err, -ECANCELED, "scan stopped by the point handler at point %zu", i);
            goto out;
        }
        scan_progress(hooks, "raster", i + 1, count);
    }
out:
    free(c.mean);
    free(c.raw);
    free(c.ts_ns);
    free(c.ids);
    return rc;
}

int scan_run(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_hooks_t *hooks,
             scan_raster_t *raster, err_t *err)
{
    scan_setup_t su;
    memset(raster, 0, sizeof *raster);
    int rc = scan_prepare(cam, stage, cfg, hooks, &su, err);
    if (rc == 0) rc = scan_raster_init(raster, cfg, &su, err);
    if (rc == 0) rc = scan_raster_run(cam, stage, cfg, &su, 0, hooks, raster, err);
    return rc;
}
