/* srv_cover.c: the coverage of a stored scan's sub-frame pixels (see srv_cover.h). The stage
 * positions are the same for every pixel, so the raster is read once. */
#include "server/srv_cover.h"

#include <errno.h>
#include <stdlib.h>

#include "server/srv_setup.h"

int srv_scan_cover(storage_t *st, const storage_scan_t *sc, scan_cover_t **out, err_t *err)
{
    char *text = NULL;
    storage_raster_t r = {0};
    scan_setup_t su;
    int h = sc->sub_px / 2, m = sc->sub_px, ret;
    *out = NULL;
    if ((ret = storage_scan_get_setup(st, sc->id, &text, err))) return ret;
    if (!text)
        return err_set(err, -ENODATA, "scan %lld has not been set up yet (no points)",
                       (long long)sc->id);
    if ((ret = srv_setup_parse(text, &su, err)) ||
        (ret = storage_frame_raster(st, sc->id, 0, 0, &r, err)))
        goto out;
    scan_cover_t *c = calloc((size_t)m * (size_t)m, sizeof *c);
    if (!c) {
        ret = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    for (int drow = -h; drow <= h; drow++)
        for (int dcol = -h; dcol <= h; dcol++)
            scan_pixel_cover(&su, dcol, drow, sc->step_um, r.stage_x_um, r.stage_y_um, r.n,
                             &c[(drow + h) * m + (dcol + h)]);
    *out = c;
out:
    storage_raster_free(&r);
    free(text);
    return ret;
}
