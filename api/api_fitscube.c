/* api_fitscube.c: POST /api/fits with a FITS scan cube instead of a scan file: the member
 * "scan_fits" {"data": base64 of the FITS file, "dcol", "drow", "all_points"} becomes the
 * "scan" member, the scan file `ips import-fits` writes for that pixel (export/fitsscan.h reads
 * the cube, instrument/scan_cube.h cuts the pixel out; docs/contracts.md "FITS scan cube"), and
 * the upload then goes on as one of that scan file. JSON carries no bytes, hence base64. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <nettle/base64.h>

#include "api_int.h"
#include "export/fitsscan.h"
#include "instrument/scan_cube.h"

/* RFC 4648 base64 (standard alphabet, '=' padding, whitespace ignored) into a new buffer, by
 * nettle's decoder (the library the bearer tokens' SHA-256 already comes from). Returns 0,
 * -EINVAL (a character outside the alphabet, bad padding, a lone trailing sextet) or -ENOMEM. */
static int base64_decode(const char *in, size_t len, unsigned char **out, size_t *out_len)
{
    unsigned char *buf = malloc(BASE64_DECODE_LENGTH(len) + 1);
    if (!buf) return -ENOMEM;
    struct base64_decode_ctx ctx;
    base64_decode_init(&ctx);
    size_t n = BASE64_DECODE_LENGTH(len) + 1;
    if (!base64_decode_update(&ctx, &n, buf, len, in) || !base64_decode_final(&ctx)) {
        free(buf);
        return -EINVAL;
    }
    *out = buf;
    *out_len = n;
    return 0;
}

/* The scan file of a cut as the JSON object an uploaded "scan" is. */
static json_t *scan_json(const fit_scan_t *s)
{
    json_t *o = json_pack("{s:f, s:f, s:f, s:f, s:f, s:i, s:f}", "pitch_um", s->pitch_um,
                          "spot_radius_um", s->spot_radius_um, "bias_dn", s->bias_dn,
                          "gain_e_per_dn", s->gain_e_per_dn, "read_noise_e", s->read_noise_e,
                          "frames", s->frames, "full_scale_dn", s->full_scale_dn);
    const char *names[3] = {"x_um", "y_um", "signal_dn"};
    const double *arrays[3] = {s->x_um, s->y_um, s->signal_dn};
    for (int a = 0; o && a < 3; a++) {
        json_t *arr = json_array();
        for (size_t k = 0; arr && k < s->n; k++)
            /* non-finite means (NaN or BLANK in the cube) are null, as scan files write them */
            if (json_array_append_new(arr, isfinite(arrays[a][k]) ? json_real(arrays[a][k])
                                                                  : json_null())) {
                json_decref(arr);
                arr = NULL;
            }
        if (!arr || json_object_set_new(o, names[a], arr)) {
            json_decref(o);
            o = NULL;
        }
    }
    return o;
}

int api_fits_cube_scan(api_req_t *q, json_t *o)
{
    static const char *const keys[] = {"data", "dcol", "drow", "all_points", NULL};
    json_t *fs;
    if (api_get_obj(q, o, "scan_fits", "scan_fits", &fs)) return -1;
    if (!fs) return 0;
    if (json_object_get(o, "scan")) {
        api_error(q, 422, "invalid", "scan_fits", "give scan or scan_fits, not both");
        return -1;
    }
    const char *data = NULL;
    long long dcol = 0, drow = 0;
    int all = 0;
    if (api_no_unknown(q, fs, "scan_fits.", keys) ||
        api_get_str(q, fs, "data", "scan_fits.data", 1, SIZE_MAX, &data) ||
        api_get_int(q, fs, "dcol", "scan_fits.dcol", 0, -100000, 100000, &dcol) ||
        api_get_int(q, fs, "drow", "scan_fits.drow", 0, -100000, 100000, &drow) ||
        api_get_bool(q, fs, "all_points", "scan_fits.all_points", &all))
        return -1;
    unsigned char *bytes = NULL;
    size_t len = 0;
    int rc = base64_decode(data, strlen(data), &bytes, &len);
    if (rc) {
        if (rc == -ENOMEM) api_error(q, 500, "internal", NULL, "out of memory");
        else api_error(q, 422, "invalid", "scan_fits.data", "scan_fits.data is not base64");
        return -1;
    }
    fitsscan_t cube;
    err_t err = {{0}};
    /* --max-fit-points bounds the memory of what a fit takes: with all_points every position of
     * the cube is the scan's, so NAXIS3 is checked from the header before anything is cut (a
     * 4 MB body can claim a million one-byte points: ~300 MB of JSON values before) */
    int cap = srv_config(q->srv)->max_fit_points;
    rc = fitsscan_read_capped(bytes, len, all ? (size_t)cap : SIZE_MAX, &cube, &err);
    free(bytes);
    if (rc) {
        if (rc == -E2BIG)
            api_error(q, 413, "payload_too_large", "scan_fits.data",
                      "scan_fits: %s, ipsd's limit of points a fit takes (--max-fit-points)",
                      err.msg);
        else if (rc == -ENOMEM) api_error(q, 500, "internal", NULL, "%s", err.msg);
        else api_error(q, 422, "invalid", "scan_fits.data", "scan_fits: %s", err.msg);
        return -1;
    }
    scan_cube_t c = {.ncol = cube.ncol,
                     .nrow = cube.nrow,
                     .n = cube.n,
                     .poi_col = cube.poi_col,
                     .poi_row = cube.poi_row,
                     .mean_dn = cube.mean_dn,
                     .x_um = cube.x_um,
                     .y_um = cube.y_um,
                     .pitch_um = cube.pitch_um,
                     .spot_radius_um = cube.spot_radius_um,
                     .bias_dn = cube.bias_dn,
                     .gain_e_per_dn = cube.gain_e_per_dn,
                     .read_noise_e = cube.read_noise_e,
                     .full_scale_dn = cube.full_scale_dn,
                     .frames = cube.frames};
    scanfile_t sf;
    rc = scan_cube_pixel(&c, (int)dcol, (int)drow, all, &sf, &err);
    fitsscan_free(&cube);
    if (rc == 0 && sf.scan.n > (size_t)cap) {
        api_error(q, 413, "payload_too_large", "scan_fits.data",
                  "scan_fits: %zu positions lie inside pixel (%+lld, %+lld), more than ipsd's "
                  "limit of %d points a fit takes (--max-fit-points)",
                  sf.scan.n, dcol, drow, cap);
        scanfile_free(&sf);
        return -1;
    }
    if (rc == 0 && sf.scan.n == 0)
        rc = err_set(&err, -EINVAL,
                     "no spot position lies strictly inside pixel (%+lld, %+lld) (all_points keeps "
                     "those outside)", dcol, drow);
    if (rc) {
        scanfile_free(&sf);
        if (rc == -ENOMEM) api_error(q, 500, "internal", NULL, "%s", err.msg);
        else api_error(q, 422, "invalid", "scan_fits.dcol", "scan_fits: %s", err.msg);
        return -1;
    }
    json_t *scan = scan_json(&sf.scan);
    scanfile_free(&sf);
    if (!scan || json_object_set_new(o, "scan", scan)) {
        api_error(q, 500, "internal", NULL, "out of memory");
        return -1;
    }
    json_object_del(o, "scan_fits");
    return 0;
}
