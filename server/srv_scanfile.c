/* srv_scanfile.c: a stored scan as a scan file with its sub-frame (see srv_scanfile.h). Every
 * point's mean frame in one read (storage_frame_means: one snapshot, the same stored numbers a
 * fit reads pixel by pixel); positions by scan_pixel_coords from the stored stage positions and
 * setup, as srv_pixel_scan's. */
#include "server/srv_scanfile.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan.h"
#include "instrument/scanfile.h"
#include "server/srv_setup.h"

/* The scan file of sc with its sub-frame into *out (scanfile_free). */
static int scan_file(storage_t *st, const storage_scan_t *sc, scanfile_t *out, err_t *err)
{
    char *text = NULL;
    storage_means_t mf = {0};
    scan_setup_t su;
    int ret;
    memset(out, 0, sizeof *out);
    if ((ret = storage_scan_get_setup(st, sc->id, &text, err))) return ret;
    if (!text)
        return err_set(err, -ENODATA, "scan %lld has not been set up yet (no points)",
                       (long long)sc->id);
    if ((ret = srv_setup_parse(text, &su, err)) ||
        (ret = storage_frame_means(st, sc->id, &mf, err)) ||
        (ret = scan_file_new(&su, sc->frames, mf.n, out, err)))
        goto out;
    int m = mf.sub_px, h = m / 2;
    for (size_t k = 0; k < mf.n; k++) {
        scan_pixel_coords(&su, 0, 0, mf.stage_x_um[k], mf.stage_y_um[k], &out->x_um[k],
                          &out->y_um[k]);
        out->signal_dn[k] = mf.mean_dn[k * m * m + (size_t)h * m + h];
    }
    out->sub_px = m;
    out->sub_step_um = sc->step_um;
    out->sub_dn = mf.mean_dn; /* taken */
    mf.mean_dn = NULL;
out:
    if (ret) scanfile_free(out);
    storage_means_free(&mf);
    free(text);
    return ret;
}

int srv_scan_file_text(storage_t *st, const storage_scan_t *sc, json_t *extra, char **text,
                       size_t *len, err_t *err)
{
    scanfile_t sf;
    *text = NULL;
    *len = 0;
    int ret = scan_file(st, sc, &sf, err);
    if (ret) return ret;
    json_t *meta = extra ? json_deep_copy(extra) : json_object();
    FILE *f = meta ? open_memstream(text, len) : NULL;
    if (!f || json_object_set_new(meta, "subframe",
                                  scanfile_subframe_json(sf.sub_px, sf.sub_step_um, sf.sub_dn,
                                                         sf.scan.n)))
        ret = err_set(err, -ENOMEM, "out of memory");
    else
        ret = scanfile_dump(f, &sf.scan, meta, err);
    if (f && fclose(f) && ret == 0) ret = err_set(err, -ENOMEM, "out of memory");
    json_decref(meta);
    scanfile_free(&sf);
    if (ret) {
        free(*text);
        *text = NULL;
    }
    return ret;
}
