/* scan_cube.c: a pixel's scan file from a scan cube (scan_cube.h), with the building blocks of
 * scan_extract.c, so a cube and a raster of ipsd's own are cut the same way. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan.h"
#include "instrument/scan_cube.h"

int scan_cube_pixel(const scan_cube_t *c, int dcol, int drow, int all, scanfile_t *out,
                    err_t *err)
{
    memset(out, 0, sizeof *out);
    int col = c->poi_col + dcol, row = c->poi_row + drow;
    if (col < 0 || col >= c->ncol || row < 0 || row >= c->nrow)
        return err_set(err, -EINVAL,
                       "pixel (%+d, %+d) is outside the %dx%d sub-frame (the POI is its column %d, "
                       "row %d, counted from 1)", dcol, drow, c->ncol, c->nrow, c->poi_col + 1,
                       c->poi_row + 1);
    if (!(c->pitch_um > 0 && isfinite(c->pitch_um)) || !(c->spot_radius_um > 0) ||
        !(c->gain_e_per_dn > 0) || !(c->read_noise_e >= 0) || !isfinite(c->bias_dn) ||
        c->frames < 1)
        return err_set(err, -EINVAL, "the cube's sensor constants are out of range");
    /* The POI's centre at (p/2, p/2) of its own frame: scan_pixel_coords then gives
       x - (0 + dcol p), which is x itself for the POI. Gain 1: the constants are the sensor's. */
    const double p = c->pitch_um;
    scan_setup_t su = {.centre = {p / 2, p / 2, 0},
                       .gain = 1,
                       .pitch_um = p,
                       .bias_dn = c->bias_dn,
                       .gain_e_per_dn = c->gain_e_per_dn,
                       .read_noise_e = c->read_noise_e,
                       .full_scale_dn = c->full_scale_dn,
                       .spot_radius_um = c->spot_radius_um};
    size_t plane = (size_t)c->nrow * (size_t)c->ncol, at = (size_t)row * c->ncol + (size_t)col;
    size_t n = 0;
    for (int pass = 0; pass < 2; pass++) {
        size_t k = 0;
        for (size_t i = 0; i < c->n; i++) {
            double x, y;
            int inside = scan_pixel_coords(&su, dcol, drow, c->x_um[i], c->y_um[i], &x, &y);
            if (!(all || inside)) continue;
            if (pass == 1) {
                out->x_um[k] = x;
                out->y_um[k] = y;
                out->signal_dn[k] = c->mean_dn[i * plane + at];
            }
            k++;
        }
        if (pass == 0) {
            n = k;
            int rc = scan_file_new(&su, c->frames, n, out, err);
            if (rc) return rc;
        }
    }
    return 0;
}
