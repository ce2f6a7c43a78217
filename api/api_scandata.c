/* api_scandata.c: the data of a scan: the response raster of any pixel of the sub-frame (in the
 * scan-file format, so it feeds `ips fit`), the whole raster with every pixel's response (the
 * scan file's subframe, for `ips fit --pixels all`), and the fits made of the scan (one point's
 * frames: api_point.c). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"
#include "server/srv_scanfile.h"
#include "server/srv_setup.h"

/* Reads scan arg 0 into *sc; -1 after replying 404. */
static int load_scan(api_req_t *q, storage_t *st, storage_scan_t *sc)
{
    int64_t id;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "scan", &id)) return -1;
    int ret = storage_scan_get(st, id, sc, &err);
    if (ret) api_error_rc(q, ret, NULL, err.msg);
    return ret ? -1 : 0;
}

/* The metadata both scan-file answers carry beside the scan file's keys (docs/api.md). */
static json_t *scan_file_meta(const storage_scan_t *sc, const char *description, int dcol,
                              int drow, int inside_only)
{
    return json_pack("{s:s, s:I, s:I, s:i, s:i, s:{s:i, s:i}, s:s, s:i}", "description",
                     description, "scan_id", (json_int_t)sc->id, "sensor_id",
                     (json_int_t)sc->sensor_id, "dcol", dcol, "drow", drow, "pixel", "col",
                     sc->poi_col + dcol, "row", sc->poi_row + drow, "scan_state",
                     storage_state_name(sc->state), "inside_only", inside_only);
}

/* Answers a scan file's text, or the error that made it (the metadata's allocation included). */
static void reply_scan_text(api_req_t *q, int ret, char *text, size_t len, const err_t *err)
{
    if (ret)
        api_error_rc(q, ret, NULL, err->msg);
    else
        api_reply_text(q, 200, "application/json", text, len);
}

void api_h_scan_pixel(api_req_t *q)
{
    storage_t *st = api_db(q);
    storage_scan_t sc;
    long long all;
    err_t err = {{0}};
    if (!st || api_query_int(q, "all", 0, 0, 1, &all) || load_scan(q, st, &sc)) return;
    int dcol = (int)q->arg[1], drow = (int)q->arg[2], h = sc.sub_px / 2;
    if (q->arg[1] < -h || q->arg[1] > h || q->arg[2] < -h || q->arg[2] > h) {
        api_error(q, 404, "not_found", q->arg[1] < -h || q->arg[1] > h ? "dcol" : "drow",
                  "pixel (%lld, %lld) is outside scan %lld's %dx%d sub-frame (offsets %d..%d)",
                  (long long)q->arg[1], (long long)q->arg[2], (long long)sc.id, sc.sub_px,
                  sc.sub_px, -h, h);
        storage_scan_free(&sc);
        return;
    }
    json_t *extra = scan_file_meta(&sc, "response of one pixel over a scan's raster (ipsd)", dcol,
                                   drow, all ? 0 : 1);
    char *text = NULL;
    size_t len = 0;
    int ret = extra ? srv_pixel_scan_text(st, &sc, dcol, drow, (int)all, extra, &text, &len, &err)
                    : err_set(&err, -ENOMEM, "out of memory");
    json_decref(extra);
    reply_scan_text(q, ret, text, len, &err);
    storage_scan_free(&sc);
}

void api_h_scan_scanfile(api_req_t *q)
{
    storage_t *st = api_db(q);
    storage_scan_t sc;
    err_t err = {{0}};
    if (!st || load_scan(q, st, &sc)) return;
    /* every point's sub_px² means, a number of at most 24 characters and a comma each, and the
     * POI's response (~200 bytes a point): refused before anything is read when over the cap */
    double m2 = (double)sc.sub_px * sc.sub_px, bound = 4096 + sc.points_total * (m2 * 25 + 200);
    size_t cap = srv_config(q->srv)->max_reply_bytes;
    if (bound > (double)cap) {
        api_error(q, 413, "reply_too_large", NULL,
                  "scan %lld: %d points of %d x %d pixels would make a scan file of up to %.0f "
                  "bytes, more than ipsd's --max-reply-bytes (%zu): read one pixel's response "
                  "with /api/scans/%lld/pixels/{dcol}/{drow}, or a point's frames with "
                  "/api/scans/%lld/points/{index}",
                  (long long)sc.id, sc.points_total, sc.sub_px, sc.sub_px, bound, cap,
                  (long long)sc.id, (long long)sc.id);
        storage_scan_free(&sc);
        return;
    }
    json_t *extra = scan_file_meta(&sc,
                                   "a scan's raster with the whole sub-frame at each point (ipsd): "
                                   "the POI's response, every pixel's in subframe",
                                   0, 0, 0);
    char *text = NULL;
    size_t len = 0;
    int ret = extra ? srv_scan_file_text(st, &sc, extra, &text, &len, &err)
                    : err_set(&err, -ENOMEM, "out of memory");
    json_decref(extra);
    reply_scan_text(q, ret, text, len, &err);
    storage_scan_free(&sc);
}

void api_h_scan_fits_list(api_req_t *q)
{
    storage_t *st = api_db(q);
    storage_scan_t sc;
    storage_fit_list_t l;
    long long limit, offset;
    err_t err = {{0}};
    if (!st || api_query_page(q, &limit, &offset) || load_scan(q, st, &sc)) return;
    int ret = storage_fit_list(st, sc.id, (int)limit, (int)offset, &l, &err);
    storage_scan_free(&sc);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    json_t *items = json_array();
    for (size_t i = 0; items && i < l.n; i++)
        json_array_append_new(items, api_enc_fit(&l.items[i], 0));
    api_reply_json(q, 200, api_enc_page(items, l.total, limit, offset));
    storage_fit_list_free(&l);
}
