/* api_coverage.c: GET /api/scans/{id}/coverage: every pixel of a scan's sub-frame with whether
 * its raster covers it (server/srv_cover.h, the rule of instrument/scan_cover.h), why not, and
 * the pixel's newest fit of this scan and current calibration: what a fit of every pixel
 * ("pixels": "all", api_fits.c) fits, and the status of the pixels it leaves out. */
#include <errno.h>
#include <stdlib.h>

#include "api_int.h"
#include "server/srv_cover.h"

/* The newest fit of each sub-frame pixel among the scan's fits (newest first), by index. */
static void newest_fits(const storage_fit_list_t *l, int m, const storage_fit_t **by_pixel)
{
    int h = m / 2;
    for (size_t i = l->n; i-- > 0;) {
        const storage_fit_t *f = &l->items[i];
        if (abs(f->dcol) <= h && abs(f->drow) <= h) by_pixel[(f->drow + h) * m + f->dcol + h] = f;
    }
}

void api_h_scan_coverage(api_req_t *q)
{
    storage_t *st = api_db(q);
    storage_scan_t sc;
    storage_fit_list_t fits = {0};
    scan_cover_t *cover = NULL;
    const storage_fit_t **by_pixel = NULL;
    int64_t id;
    err_t err = {{0}};
    if (!st || api_arg_id(q, 0, "scan", &id)) return;
    int ret = storage_scan_get(st, id, &sc, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    int m = sc.sub_px, h = m / 2, n_covered = 0;
    if ((ret = srv_scan_cover(st, &sc, &cover, &err)) == 0 &&
        (ret = storage_fit_list(st, sc.id, 0, 0, &fits, &err)) == 0 &&
        !(by_pixel = calloc((size_t)m * (size_t)m, sizeof *by_pixel)))
        ret = err_set(&err, -ENOMEM, "out of memory");
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        goto out;
    }
    newest_fits(&fits, m, by_pixel);
    json_t *pixels = json_array();
    for (int i = 0; pixels && i < m * m; i++) {
        const scan_cover_t *c = &cover[i];
        const storage_fit_t *f = by_pixel[i];
        int dcol = i % m - h, drow = i / m - h, col = sc.poi_col + dcol, row = sc.poi_row + drow;
        storage_calib_t cal;
        json_t *calib_id = json_null();
        if (storage_calib_current(st, sc.sensor_id, col, row, &cal, NULL) == 0) {
            calib_id = json_integer(cal.id);
            storage_calib_free(&cal);
        }
        n_covered += c->covered;
        json_array_append_new(
            pixels,
            json_pack("{s:i, s:i, s:i, s:i, s:s, s:o, s:I, s:o, s:o, s:o}", "dcol", dcol, "drow",
                      drow, "col", col, "row", row, "status",
                      c->covered ? "covered" : SRV_NOT_COVERED, "reason",
                      c->covered ? json_null() : json_string(c->reason), "n_inside",
                      (json_int_t)c->n_inside, "fit_id", f ? json_integer(f->id) : json_null(),
                      "fit_r", f && f->map_sensor_id ? json_integer(f->map_r) : json_null(),
                      "calibration_id", calib_id));
    }
    api_reply_json(q, 200,
                   json_pack("{s:I, s:I, s:i, s:i, s:f, s:i, s:i, s:o}", "scan_id",
                             (json_int_t)sc.id, "sensor_id", (json_int_t)sc.sensor_id, "sub_px", m,
                             "area_px", sc.area_px, "step_um", sc.step_um, "covered", n_covered,
                             "not_covered", m * m - n_covered, "pixels", pixels));
out:
    free(by_pixel);
    free(cover);
    storage_fit_list_free(&fits);
    storage_scan_free(&sc);
}
