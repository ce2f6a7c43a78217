/* api_promote.c: POST /api/fits/{id}/promote: makes the map a stored fit offers (its recommended
 * map, of the sensor pixel it was fitted for) the current calibration of that pixel, recorded with
 * who asked ("by", a declared name) and why ("reason"). The lab database changes only on purpose:
 * a re-fit is stored as a fit and becomes the calibration through this route or "promote": true
 * in its request (docs/api.md, "Calibrations"). Any earlier fit can be promoted again, which is
 * how a pixel goes back to an older map. */
#include <errno.h>
#include <stdio.h>

#include "api_int.h"

#define DEFAULT_BY "api"

void api_h_fit_promote(api_req_t *q)
{
    static const char *const keys[] = {"by", "reason", NULL};
    const char *by = NULL, *reason = NULL;
    char text[SRV_REASON_MAX + 64];
    storage_t *st;
    storage_calib_t c;
    int64_t fit_id, calib_id = 0;
    err_t err = {{0}};
    json_t *o = api_body_object(q);
    if (!o || api_arg_id(q, 0, "fit", &fit_id) || api_no_unknown(q, o, "", keys) ||
        api_get_str(q, o, "by", "by", 0, SRV_BY_MAX, &by) ||
        api_get_str(q, o, "reason", "reason", 0, SRV_REASON_MAX, &reason) || !(st = api_db(q)))
        goto out;
    if (!reason) {
        snprintf(text, sizeof text, "fit %lld promoted", (long long)fit_id);
        reason = text;
    }
    int ret = storage_calib_promote(st, fit_id, by ? by : DEFAULT_BY, reason, &calib_id, &err);
    if (ret == -EALREADY) {
        api_error(q, 409, "conflict", NULL, "%s", err.msg);
        goto out;
    }
    if (ret == 0) ret = storage_calib_get(st, calib_id, &c, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        goto out;
    }
    api_reply_json(q, 201, api_enc_calib(&c));
    char loc[64];
    snprintf(loc, sizeof loc, "/api/calibrations/%lld", (long long)calib_id);
    if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_LOCATION, loc);
    storage_calib_free(&c);
out:
    json_decref(o);
}
