/* api_point.c: GET /api/scans/{id}/points/{index}, one raster point's frames (mean and raw). A
 * point stores up to sub_px² x frames raw values (255² x 1032: 134 MB of frames, a quarter of a
 * gigabyte of JSON), so the reply's size is estimated from the scan before anything is read, a
 * reply over --max-reply-bytes is refused (413 naming raw_limit and how many frames fit), and
 * ?raw_offset=&raw_limit= ask for a page of the raw frames, of which only that page is read. The
 * raw frames' text is written here and not built of jansson values (~40 bytes each). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"
#include "json/jdump.h"

/* Bytes of the reply's text at most: the members but mean and raw (a few hundred bytes), the
 * mean frame (a number of at most 24 characters and a comma each) and count raw frames (at most
 * 5 digits and a comma a value, brackets and a comma a frame). */
static double reply_bound(int sub_px, int count)
{
    double m2 = (double)sub_px * sub_px;
    return 1024 + m2 * 25 + (double)count * (m2 * 6 + 3 + 2 * 21); /* + a timestamp and an id */
}

/* Writes v (0..65535) at p; returns the characters written. */
static size_t put_u16(char *p, unsigned v)
{
    char tmp[5];
    size_t n = 0, k = 0;
    do {
        tmp[n++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    while (n)
        p[k++] = tmp[--n];
    return k;
}

/* The reply's text: head (the small members, an object's text) without its closing brace, then
 * mean's text and the raw frames. NULL when out of memory. */
static char *point_text(const storage_frame_t *f, const char *head, const char *mean, size_t *len)
{
    size_t m2 = (size_t)f->sub_px * (size_t)f->sub_px, hl = strlen(head) - 1, ml = strlen(mean);
    size_t cap = hl + ml + 32 + (size_t)f->raw_count * (m2 * 6 + 3);
    char *t = malloc(cap), *p = t;
    if (!t) return NULL;
    memcpy(p, head, hl);
    p += hl;
    p += sprintf(p, ",\"mean\":");
    memcpy(p, mean, ml);
    p += ml;
    p += sprintf(p, ",\"raw\":[");
    for (int k = 0; k < f->raw_count; k++) {
        const uint16_t *r = f->raw + (size_t)k * m2;
        *p++ = k ? ',' : '[';
        if (k) *p++ = '[';
        for (size_t j = 0; j < m2; j++) {
            if (j) *p++ = ',';
            p += put_u16(p, r[j]);
        }
        *p++ = ']';
    }
    *p++ = ']';
    *p++ = '}';
    *len = (size_t)(p - t);
    return t;
}

void api_h_scan_point(api_req_t *q)
{
    storage_t *st = api_db(q);
    storage_scan_t sc;
    storage_frame_t f;
    long long off, lim;
    int64_t id;
    err_t err = {{0}};
    if (!st || api_arg_id(q, 0, "scan", &id)) return;
    int ret = storage_scan_get(st, id, &sc, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    int64_t i = q->arg[1];
    int k = sc.frames, sub_px = sc.sub_px, total = sc.points_total;
    storage_scan_free(&sc);
    if (i < 0 || i >= total) {
        api_error(q, 404, "not_found", "index", "point %lld is outside scan %lld's 0..%d",
                  (long long)i, (long long)id, total - 1);
        return;
    }
    if (api_query_int(q, "raw_offset", 0, 0, k, &off) ||
        api_query_int(q, "raw_limit", k - off, 0, k, &lim))
        return;
    if (lim > k - off) lim = k - off;
    size_t cap = srv_config(q->srv)->max_reply_bytes;
    if (reply_bound(sub_px, (int)lim) > (double)cap) {
        double m2 = (double)sub_px * sub_px, page = ((double)cap - 1024 - m2 * 25) / (m2 * 6 + 3 + 2 * 21);
        api_error(q, 413, "reply_too_large", "raw_limit",
                  "point %lld of scan %lld: %lld raw frames of %d x %d pixels would make a reply "
                  "of up to %.0f bytes, more than ipsd's --max-reply-bytes (%zu): ask for at most "
                  "%.0f frames a request with ?raw_offset=&raw_limit=",
                  (long long)i, (long long)id, lim, sub_px, sub_px, reply_bound(sub_px, (int)lim),
                  cap, page > 0 ? floor(page) : 0);
        return;
    }
    ret = storage_frame_get_part(st, id, (int)i, (int)off, (int)lim, &f, &err);
    if (ret) {
        api_error_rc(q, ret, ret == -ENOENT ? "index" : NULL, err.msg);
        return;
    }
    size_t m2 = (size_t)f.sub_px * f.sub_px, len = 0;
    json_t *mean = json_array();
    for (size_t j = 0; mean && j < m2; j++)
        json_array_append_new(mean, api_num(f.mean[j]));
    json_t *head = json_pack("{s:I, s:i, s:[f, f, f], s:f, s:o, s:i, s:i, s:i}", "scan_id",
                             (json_int_t)f.scan_id, "point_index", f.point_index, "stage_um",
                             f.stage_x_um, f.stage_y_um, f.stage_z_um, "exposure_us",
                             f.exposure_us, "captured_ms", api_time(f.captured_ms), "frames",
                             f.frames, "sub_px", f.sub_px, "raw_offset", f.raw_first);
    /* schema 10: the timestamps and camera frame ids of the frames in raw; null: not recorded */
    const uint64_t *per_frame[2] = {(const uint64_t *)f.timestamps_ns, f.camera_frame_ids};
    const char *per_name[2] = {"timestamps_ns", "camera_frame_ids"};
    for (int a = 0; head && a < 2; a++) {
        json_t *v = per_frame[a] ? json_array() : json_null();
        for (int k = f.raw_first; v && per_frame[a] && k < f.raw_first + f.raw_count; k++)
            json_array_append_new(v, json_integer(a == 0 ? (json_int_t)(int64_t)per_frame[a][k]
                                                         : (json_int_t)per_frame[a][k]));
        json_object_set_new(head, per_name[a], v);
    }
    char *head_text = head ? jdump_string(head, JDUMP_COMPACT) : NULL;
    char *mean_text = mean ? jdump_string(mean, JDUMP_COMPACT) : NULL;
    json_decref(head);
    json_decref(mean);
    char *text = head_text && mean_text ? point_text(&f, head_text, mean_text, &len) : NULL;
    free(head_text);
    free(mean_text);
    storage_frame_free(&f);
    if (!text) {
        api_error(q, 500, "internal", NULL, "out of memory building the reply");
        return;
    }
    api_reply_text(q, 200, "application/json", text, len);
}
