/* scan_points.c: the pixel of interest read at spot positions chosen one batch at a time (an
 * adaptive scan, fit/adapt_plan.h), appended to a scan file: as the direct grid of
 * scan_extract.c (no raster of the neighbours, k frames of the POI alone at each position), at
 * positions given relative to the POI's corner, the stage sent to
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
