/* fit_pixels.c: every covered pixel of a scan file's sub-frame, fitted (see fit_pixels.h). One
 * pixel after another, in the server's order (srv_fitall.c): the fits are ~10 ms each, a 5 x 5
 * raster's 25 pixels well under a second, so no threads. */
#include "fit_pixels.h"

#include <errno.h>

#include "base/clock.h"
#include "instrument/scanfile_sub.h"
#include "json/fitjson.h"

/* One pixel's entry; fit (may be NULL) is taken. NULL when out of memory. */
static json_t *pixel_json(int dcol, int drow, const char *status, const scan_cover_t *c,
                          const char *reason, json_t *fit)
{
    return json_pack("{s:i, s:i, s:s, s:I, s:o, s:o}", "dcol", dcol, "drow", drow, "status",
                     status, "n_inside", (json_int_t)c->n_inside, "reason",
                     reason ? json_string(reason) : json_null(), "fit", fit ? fit : json_null());
}

int fit_pixels_run(const scanfile_t *sf, fit_pixels_fn fit, void *user, json_t **out,
                   err_t *err)
{
    double t0 = clock_mono_ms();
    int m = sf->sub_px, h = m / 2, covered = 0, fitted = 0, failed = 0;
    json_t *pixels = json_array();
    *out = NULL;
    if (!pixels) return err_set(err, -ENOMEM, "out of memory");
    for (int drow = -h; drow <= h; drow++)
        for (int dcol = -h; dcol <= h; dcol++) {
            scan_cover_t c;
            scanfile_pixel_cover(sf, dcol, drow, &c);
            json_t *e;
            if (!c.covered) {
                e = pixel_json(dcol, drow, "not_covered", &c, c.reason, NULL);
            } else {
                covered++;
                scanfile_t px;
                json_t *doc = NULL;
                err_t pe;
                int rc = scanfile_pixel(sf, dcol, drow, &px, &pe);
                if (rc == 0) rc = fit(&px.scan, user, &doc, &pe);
                scanfile_free(&px);
                if (rc == -ENOMEM) {
                    json_decref(pixels);
                    return err_set(err, rc, "%s", pe.msg);
                }
                if (rc == 0) fitted++;
                else failed++;
                e = pixel_json(dcol, drow, rc ? "failed" : "fitted", &c, rc ? pe.msg : NULL, doc);
            }
            if (json_array_append_new(pixels, e)) {
                json_decref(pixels);
                return err_set(err, -ENOMEM, "out of memory");
            }
        }
    double ms = clock_mono_ms() - t0;
    *out = json_pack("{s:i, s:o, s:I, s:i, s:i, s:i, s:i, s:o, s:{s:o}}", "sub_px", m, "step_um",
                     fitjson_num(sf->sub_step_um), "n_raster", (json_int_t)sf->scan.n, "covered",
                     covered, "not_covered", m * m - covered, "fitted", fitted, "failed", failed,
                     "pixels", pixels, "timing_ms", "fit", fitjson_num(ms));
    return *out ? 0 : err_set(err, -ENOMEM, "out of memory");
}
