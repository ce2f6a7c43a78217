/* scanfile_sub.c: a scan file's sub-frame pixels (see scanfile_sub.h). */
#include "instrument/scanfile_sub.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan.h"

/* The setup that makes the file's positions (relative to the POI's corner) stage positions: the
 * POI's centre at (p/2, p/2), so its corner is at 0. */
static scan_setup_t file_setup(const scanfile_t *sf)
{
    scan_setup_t su;
    memset(&su, 0, sizeof su);
    su.pitch_um = sf->scan.pitch_um;
    su.centre.x_um = su.centre.y_um = sf->scan.pitch_um / 2;
    su.gain = 1;
    return su;
}

void scanfile_pixel_cover(const scanfile_t *sf, int dcol, int drow, scan_cover_t *out)
{
    scan_setup_t su = file_setup(sf);
    scan_pixel_cover(&su, dcol, drow, sf->sub_step_um, sf->scan.x_um, sf->scan.y_um, sf->scan.n,
                     out);
}

int scanfile_pixel(const scanfile_t *sf, int dcol, int drow, scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    int m = sf->sub_px, h = m / 2;
    if (!m || !sf->sub_dn) return err_set(err, -EINVAL, "the scan file has no subframe");
    if (abs(dcol) > h || abs(drow) > h)
        return err_set(err, -EINVAL, "pixel (%+d, %+d) is outside the %dx%d sub-frame", dcol, drow,
                       m, m);
    size_t n = sf->scan.n, mm = (size_t)m * m, at = (size_t)(h + drow) * m + (size_t)(h + dcol);
    if (n) {
        out->x_um = malloc(n * sizeof *out->x_um);
        out->y_um = malloc(n * sizeof *out->y_um);
        out->signal_dn = malloc(n * sizeof *out->signal_dn);
        if (!out->x_um || !out->y_um || !out->signal_dn) {
            scanfile_free(out);
            return err_set(err, -ENOMEM, "out of memory for a scan of %zu points", n);
        }
    }
    scan_setup_t su = file_setup(sf);
    for (size_t k = 0; k < n; k++) {
        scan_pixel_coords(&su, dcol, drow, sf->scan.x_um[k], sf->scan.y_um[k], &out->x_um[k],
                          &out->y_um[k]);
        out->signal_dn[k] = sf->sub_dn[k * mm + at];
    }
    out->scan = sf->scan;
    out->scan.x_um = out->x_um;
    out->scan.y_um = out->y_um;
    out->scan.signal_dn = out->signal_dn;
    return 0;
}
