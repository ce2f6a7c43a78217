/* api_export.c: calibrations as FITS files (export/fitsmap.h; docs/api.md, "FITS"): one
 * calibration by id, a sensor pixel's current one, and every current calibration of a sensor as
 * one multi-extension file. Named .fits in the path (the file format), unlike /api/fits (fit
 * jobs: api_fits.c). */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "export/fitsmap.h"

#include "api_int.h"

/* The header view of a stored calibration of a sensor (borrowed pointers into c). */
static fitsmap_t map_of(const storage_calib_t *c, const storage_sensor_t *sn)
{
    return (fitsmap_t){.r = c->r,
                       .S = c->S,
                       .S_err = c->S_err,
                       .S_res = c->S_res,
                       .pitch_um = sn->pitch_um,
                       .pixel_col = c->pixel_col,
                       .pixel_row = c->pixel_row,
                       .wavelength_um = c->wavelength_um,
                       .na = c->na,
                       .spot_radius_um = c->spot_radius_um,
                       .I0 = c->I0,
                       .chi2_red = c->chi2_red,
                       .status = c->status,
                       .noise_model = c->noise_model,
                       .software_version = c->software_version,
                       .calib_id = c->id,
                       .sensor_id = c->sensor_id,
                       .scan_id = c->scan_id,
                       .fit_id = c->fit_id,
                       .created_ms = c->created_ms,
                       .current = c->superseded_by == 0,
                       .by = c->by,
                       .reason = c->reason,
                       .map = storage_map_name(c->map)};
}

/* Writes maps and replies with the file (application/fits, RFC 4047), named filename. */
static void reply_fits(api_req_t *q, const storage_sensor_t *sn, const fitsmap_t *maps, size_t n,
                       const char *filename)
{
    char creator[64];
    snprintf(creator, sizeof creator, "ipsd %s", IPSD_VERSION);
    fitsmap_file_t file = {.creator = creator,
                           .sensor_id = sn->id,
                           .sensor_model = sn->model,
                           .sensor_serial = sn->serial,
                           .pitch_um = sn->pitch_um,
                           .date_ms = clock_wall_ms()};
    void *buf;
    size_t len;
    err_t err = {{0}};
    int ret = fitsmap_write(&file, maps, n, &buf, &len, &err);
    if (ret) {
        api_error(q, 500, "internal", NULL, "%s", err.msg);
        return;
    }
    api_reply_text(q, 200, "application/fits", buf, len);
    if (q->resp && q->status == 200) {
        char cd[128];
        snprintf(cd, sizeof cd, "attachment; filename=\"%s\"", filename);
        MHD_add_response_header(q->resp, "Content-Disposition", cd);
    }
}

/* One calibration with its sensor, as a one-map file. */
static void reply_one(api_req_t *q, storage_t *st, const storage_calib_t *c)
{
    storage_sensor_t sn;
    err_t err = {{0}};
    int ret = storage_sensor_get(st, c->sensor_id, &sn, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    fitsmap_t m = map_of(c, &sn);
    char name[96];
    snprintf(name, sizeof name, "ipsd-calibration-%lld.fits", (long long)c->id);
    reply_fits(q, &sn, &m, 1, name);
    storage_sensor_free(&sn);
}

void api_h_calib_fits(api_req_t *q)
{
    storage_t *st;
    storage_calib_t c;
    int64_t id;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "calibration", &id) || !(st = api_db(q))) return;
    int ret = storage_calib_get(st, id, &c, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    reply_one(q, st, &c);
    storage_calib_free(&c);
}

void api_h_pixel_calib_fits(api_req_t *q)
{
    storage_t *st;
    storage_calib_t c;
    int64_t sensor, col = q->arg[1], row = q->arg[2];
    err_t err = {{0}};
    if (api_arg_id(q, 0, "sensor", &sensor) || !(st = api_db(q))) return;
    int ret = col < 0 || row < 0 || col > INT32_MAX || row > INT32_MAX
                  ? -ENOENT
                  : storage_calib_current(st, sensor, (int)col, (int)row, &c, &err);
    if (ret == -ENOENT) {
        api_error(q, 404, "not_found", NULL,
                  "pixel (%lld, %lld) of sensor %lld has no calibration (or does not exist)",
                  (long long)col, (long long)row, (long long)sensor);
        return;
    }
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    reply_one(q, st, &c);
    storage_calib_free(&c);
}

/* Pixel order of the sensor-wide file: by row, then column (the search lists newest first). */
static int by_pixel(const void *a, const void *b)
{
    const storage_calib_t *x = a, *y = b;
    if (x->pixel_row != y->pixel_row) return x->pixel_row < y->pixel_row ? -1 : 1;
    return (x->pixel_col > y->pixel_col) - (x->pixel_col < y->pixel_col);
}

void api_h_sensor_calibs_fits(api_req_t *q)
{
    storage_t *st;
    storage_sensor_t sn;
    storage_calib_list_t l;
    int64_t sensor;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "sensor", &sensor) || !(st = api_db(q))) return;
    int ret = storage_sensor_get(st, sensor, &sn, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    storage_calib_filter_t f = storage_calib_filter_default();
    f.sensor_id = sensor;
    f.current_only = 1;
    ret = storage_calib_search(st, &f, 0, 0, &l, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        storage_sensor_free(&sn);
        return;
    }
    if (l.n == 0) {
        api_error(q, 404, "not_found", NULL, "sensor %lld has no calibration", (long long)sensor);
    } else {
        fitsmap_t *maps = malloc(sizeof *maps * l.n);
        if (!maps) {
            api_error(q, 500, "internal", NULL, "out of memory");
        } else {
            qsort(l.items, l.n, sizeof *l.items, by_pixel);
            for (size_t k = 0; k < l.n; k++)
                maps[k] = map_of(&l.items[k], &sn);
            char name[96];
            snprintf(name, sizeof name, "ipsd-sensor-%lld-calibrations.fits", (long long)sensor);
            reply_fits(q, &sn, maps, l.n, name);
            free(maps);
        }
    }
    storage_calib_list_free(&l);
    storage_sensor_free(&sn);
}
