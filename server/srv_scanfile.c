/* srv_scanfile.c: a stored scan as a scan file with its sub-frame (see srv_scanfile.h). Each
 * pixel's column of means is read as a fit reads it (storage_frame_raster, one pixel of every
 * point's mean frame), so the file holds the very numbers the server's fits take; positions by
 * scan_pixel_coords from the stored stage positions and setup, as srv_pixel_scan's. A running
 * scan gains points between the reads: the file keeps the points the first read had. */
#include "server/srv_scanfile.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/scan.h"
#include "instrument/scanfile.h"
#include "server/srv_setup.h"

/* Pixel (dcol, drow)'s means into column at of dn (n points of mm); the raster read must have at
 * least the n points of first, the same ones. */
static int read_pixel(storage_t *st, const storage_scan_t *sc, int dcol, int drow,
                      const storage_raster_t *first, double *dn, size_t mm, size_t at, err_t *err)
{
    storage_raster_t r = {0};
    int ret = storage_frame_raster(st, sc->id, dcol, drow, &r, err);
    if (ret) return ret;
    if (r.n < first->n ||
        (first->n && memcmp(r.point_index, first->point_index, first->n * sizeof(int))))
        ret = err_set(err, -EIO, "scan %lld's stored points changed while it was read",
                      (long long)sc->id);
    for (size_t k = 0; ret == 0 && k < first->n; k++)
        dn[k * mm + at] = r.mean_dn[k];
    storage_raster_free(&r);
    return ret;
}

/* The scan file of sc with its sub-frame into *out (scanfile_free). */
static int scan_file(storage_t *st, const storage_scan_t *sc, scanfile_t *out, err_t *err)
{
    char *text = NULL;
    storage_raster_t first = {0};
    scan_setup_t su;
    int m = sc->sub_px, h = m / 2, ret;
    size_t mm = (size_t)m * m;
    memset(out, 0, sizeof *out);
    if ((ret = storage_scan_get_setup(st, sc->id, &text, err))) return ret;
    if (!text)
        return err_set(err, -ENODATA, "scan %lld has not been set up yet (no points)",
                       (long long)sc->id);
    if ((ret = srv_setup_parse(text, &su, err)) ||
        (ret = storage_frame_raster(st, sc->id, -h, -h, &first, err)) ||
        (ret = scan_file_new(&su, sc->frames, first.n, out, err)))
        goto out;
    if (first.n && !(out->sub_dn = malloc(first.n * mm * sizeof *out->sub_dn))) {
        ret = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    for (size_t i = 0; ret == 0 && i < mm; i++)
        ret = read_pixel(st, sc, (int)(i % m) - h, (int)(i / m) - h, &first, out->sub_dn, mm, i,
                         err);
    for (size_t k = 0; ret == 0 && k < first.n; k++) {
        scan_pixel_coords(&su, 0, 0, first.stage_x_um[k], first.stage_y_um[k], &out->x_um[k],
                          &out->y_um[k]);
        out->signal_dn[k] = out->sub_dn[k * mm + (size_t)h * m + h];
    }
    out->sub_px = m;
    out->sub_step_um = sc->step_um;
out:
    if (ret) scanfile_free(out);
    storage_raster_free(&first);
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
