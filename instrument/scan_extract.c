/* scan_extract.c: scan files from the scan procedure (scan.h): one sub-frame pixel's response
 * extracted from a raster (positions relative to that pixel's corner), its building blocks for
 * rasters kept elsewhere, and the direct grid inside the POI (the paper's 9 x 9 of fig. 9). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan_limits.h"
#include "instrument/scanfile.h"
#include "scan_int.h"

int scan_file_new(const scan_setup_t *su, int frames, size_t n, scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (n) {
        out->x_um = malloc(sizeof(double) * n);
        out->y_um = malloc(sizeof(double) * n);
        out->signal_dn = malloc(sizeof(double) * n);
        if (!out->x_um || !out->y_um || !out->signal_dn) {
            scanfile_free(out);
            return err_set(err, -ENOMEM, "out of memory for a scan of %zu points", n);
        }
    }
    out->scan = (fit_scan_t){.n = n,
                             .x_um = out->x_um,
                             .y_um = out->y_um,
                             .signal_dn = out->signal_dn,
                             .pitch_um = su->pitch_um,
                             .spot_radius_um = su->spot_radius_um,
                             .bias_dn = su->bias_dn,
                             .gain_e_per_dn = su->gain_e_per_dn / su->gain,
                             .read_noise_e = su->read_noise_e,
                             .frames = frames,
                             .full_scale_dn = su->full_scale_dn};
    return 0;
}

int scan_pixel_coords(const scan_setup_t *su, int dcol, int drow, double sx, double sy, double *x,
                      double *y)
{
    /* the pixel spans [o, o + p] in stage coordinates, o = the POI's corner + (dcol, drow) p.
     * Computed as (position relative to the POI's corner) - dcol p, in that order: a scan file
     * keeps positions relative to the POI's corner (GET /api/scans/{id}/scanfile, ips simulate
     * --write-subframe), and `ips fit --pixels all` gets every other pixel's positions from them
     * with this same function (centre p/2, so the corner is 0), bit for bit the server's. */
    double p = su->pitch_um, eps = 1e-6 * p;
    *x = (sx - (su->centre.x_um - p / 2)) - dcol * p;
    *y = (sy - (su->centre.y_um - p / 2)) - drow * p;
    return *x > eps && *x < p - eps && *y > eps && *y < p - eps;
}

int scan_extract_pixel(const scan_raster_t *r, int dcol, int drow, scanfile_t *out, err_t *err)
{
    return scan_extract_pixel_region(r, dcol, drow, 0, out, err);
}

int scan_extract_pixel_region(const scan_raster_t *r, int dcol, int drow, int all,
                              scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    int h = r->m / 2;
    if (abs(dcol) > h || abs(drow) > h)
        return err_set(err, -EINVAL, "pixel (%+d, %+d) is outside the %dx%d sub-frame", dcol, drow,
                       r->m, r->m);
    size_t n = 0, at = (size_t)(h + drow) * r->m + (size_t)(h + dcol), mm = (size_t)r->m * r->m;
    for (int pass = 0; pass < 2; pass++) {
        size_t k = 0;
        for (size_t i = 0; i < r->count; i++) {
            double x, y;
            int inside =
                scan_pixel_coords(&r->setup, dcol, drow, r->pos[i].x_um, r->pos[i].y_um, &x, &y);
            if (!r->have[i] || !(all || inside)) continue;
            if (pass == 1) {
                out->x_um[k] = x;
                out->y_um[k] = y;
                out->signal_dn[k] = r->mean_dn[i * mm + at];
            }
            k++;
        }
        if (pass == 0) {
            n = k;
            int rc = scan_file_new(&r->setup, r->cfg.frames, n, out, err);
            if (rc) return rc;
        }
    }
    return 0;
}

int scan_grid_pixel(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_setup_t *su,
                    int n, const scan_hooks_t *hooks, scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    double p = su->pitch_um;
    int rc = scan_field_check(&scan_fields[SCAN_F_GRID], n, "grid", err);
    if (rc == 0) rc = scan_check_grid(p, n, cfg->step_um, "grid", err);
    if (rc) return rc;
    rc = scan_file_new(su, cfg->frames, (size_t)n * n, out, err);
    if (rc == 0) rc = cam_set_gain(cam, su->gain, err);
    if (rc == 0) rc = cam_set_exposure(cam, su->exposure_us, err);
    if (rc) goto fail;
    cam_roi_t roi = {cfg->poi_col, cfg->poi_row, 1, 1};
    double mean, var;
    struct scan_capture c = {.mean = &mean, .var = &var};
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            if (scan_stopped(hooks)) {
                rc = err_set(err, -ECANCELED, "scan stopped in the grid");
                goto fail;
            }
            double x = p / 2 + (i - (n - 1) / 2.0) * cfg->step_um;
            double y = p / 2 + (j - (n - 1) / 2.0) * cfg->step_um;
            stage_pos_t pos = {su->centre.x_um - p / 2 + x, su->centre.y_um - p / 2 + y,
                               su->centre.z_um};
            rc = scan_capture_at(cam, stage, &pos, &roi, cfg->frames, cfg->use_expected, &c, err);
            if (rc) goto fail;
            size_t k = (size_t)j * n + (size_t)i;
            out->x_um[k] = c.reported.x_um - (su->centre.x_um - p / 2);
            out->y_um[k] = c.reported.y_um - (su->centre.y_um - p / 2);
            out->signal_dn[k] = mean;
            scan_progress(hooks, "raster", k + 1, (size_t)n * n);
        }
    return 0;
fail:
    scanfile_free(out);
    return rc;
}
