/* scan_points.c: the pixel of interest read at spot positions chosen one batch at a time (an
 * adaptive scan, fit/adapt_plan.h): appended to a scan file, as the direct grid of
 * scan_extract.c (no raster of the neighbours, k frames of the POI alone at each position), or
 * as the raster captures its points (k frames of the m x m sub-frame, each point handed to
 * hooks->point: the server stores them as raster points). Positions are given relative to the
 * POI's corner, the stage sent to
 *     stage = centre - p/2 + (x, y),
 * and the reported position written back the same way (scan.h, "Coordinates"). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scanfile.h"
#include "scan_int.h"

/* Grows out's arrays to hold n more points (the scan's pointers follow). */
static int grow(scanfile_t *out, size_t n, err_t *err)
{
    size_t total = out->scan.n + n;
    double *x = realloc(out->x_um, sizeof(double) * total);
    if (x) out->x_um = x;
    double *y = x ? realloc(out->y_um, sizeof(double) * total) : NULL;
    if (y) out->y_um = y;
    double *s = y ? realloc(out->signal_dn, sizeof(double) * total) : NULL;
    if (s) out->signal_dn = s;
    out->scan.x_um = out->x_um, out->scan.y_um = out->y_um, out->scan.signal_dn = out->signal_dn;
    return s ? 0 : err_set(err, -ENOMEM, "out of memory for a scan of %zu points", total);
}

int scan_pixel_points(cam_t *cam, stage_t *stage, const scan_config_t *cfg,
                      const scan_setup_t *su, size_t n, const double *x, const double *y,
                      const scan_hooks_t *hooks, scanfile_t *out, err_t *err)
{
    double p = su->pitch_um;
    int rc = n ? grow(out, n, err) : 0;
    if (rc == 0) rc = cam_set_gain(cam, su->gain, err);
    if (rc == 0) rc = cam_set_exposure(cam, su->exposure_us, err);
    if (rc) return rc;
    cam_roi_t roi = {cfg->poi_col, cfg->poi_row, 1, 1};
    double mean, var;
    struct scan_capture c = {.mean = &mean, .var = &var};
    for (size_t i = 0; i < n; i++) {
        if (scan_stopped(hooks)) return err_set(err, -ECANCELED, "scan stopped at point %zu", out->scan.n);
        stage_pos_t pos = {su->centre.x_um - p / 2 + x[i], su->centre.y_um - p / 2 + y[i],
                           su->centre.z_um};
        if ((rc = scan_capture_at(cam, stage, &pos, &roi, cfg->frames, cfg->use_expected, &c, err)))
            return rc;
        size_t k = out->scan.n++;
        out->x_um[k] = c.reported.x_um - (su->centre.x_um - p / 2);
        out->y_um[k] = c.reported.y_um - (su->centre.y_um - p / 2);
        out->signal_dn[k] = mean;
        scan_progress(hooks, "raster", i + 1, n);
    }
    return 0;
}

int scan_pixel_box(stage_t *stage, const scan_setup_t *su, double box_um[4], err_t *err)
{
    stage_limits_t lim;
    int rc = stage_get_limits(stage, &lim, err);
    if (rc) return rc;
    double cx = su->centre.x_um - su->pitch_um / 2, cy = su->centre.y_um - su->pitch_um / 2;
    box_um[0] = lim.min.x_um - cx, box_um[1] = lim.max.x_um - cx;
    box_um[2] = lim.min.y_um - cy, box_um[3] = lim.max.y_um - cy;
    return 0;
}

int scan_subframe_points(cam_t *cam, stage_t *stage, const scan_config_t *cfg,
                         const scan_setup_t *su, size_t first, size_t count, size_t n,
                         const double *x, const double *y, const scan_hooks_t *hooks, err_t *err)
{
    cam_info_t info;
    int rc = cam_get_info(cam, &info, err);
    if (rc == 0) rc = scan_config_check(cfg, &info, err);
    if (rc == 0) rc = cam_set_gain(cam, su->gain, err);
    if (rc == 0) rc = cam_set_exposure(cam, su->exposure_us, err);
    if (rc) return rc;
    int m = cfg->subframe_px, k = cfg->frames;
    size_t mm = (size_t)m * m;
    double p = su->pitch_um;
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
    for (size_t i = 0; i < n; i++) {
        size_t index = first + i;
        if (scan_stopped(hooks)) {
            rc = err_set(err, -ECANCELED, "scan stopped before point %zu", index);
            goto out;
        }
        stage_pos_t pos = {su->centre.x_um - p / 2 + x[i], su->centre.y_um - p / 2 + y[i],
                           su->centre.z_um};
        if ((rc = scan_capture_at(cam, stage, &pos, &roi, k, cfg->use_expected, &c, err)) != 0)
            goto out;
        scan_point_t pt = scan_point_of_capture(&c, index, count, -1, -1, &pos, k, m);
        if (hooks && hooks->point && hooks->point(&pt, hooks->user) != 0) {
            rc = err_set(err, -ECANCELED, "scan stopped by the point handler at point %zu", index);
            goto out;
        }
        scan_progress(hooks, "adaptive", index + 1, count);
    }
out:
    free(c.mean);
    free(c.raw);
    free(c.ts_ns);
    free(c.ids);
    return rc;
}
