/* api_interp.c: the interpolated IPS map of a stored map, for display (the paper's "interpolated
 * IPS map", Fig. IPSV_3D (b)): GET /api/fits/{id}/interp?r=R&n=N (any r of the fit's sweep; by
 * default the recommended map, the one stored as the calibration) and GET
 * /api/calibrations/{id}/interp?n=N. Both are computed by fit_interp_bicubic (fit/interp.h), the
 * code `ips fit --interp` uses, so the dashboard shows what the command-line tool prints and no
 * client repeats the interpolation. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "api_int.h"
#include "fit/interp.h"

#define INTERP_N_DEFAULT 100 /* points per axis when ?n= is absent (the dashboard's grid) */
#define INTERP_N_MAX 500     /* 250000 values, about 5 MB of JSON at 17 digits */
#define INTERP_R_MAX 64      /* the largest stored map (storage_calib_t: r is 1..64) */

/* The method fit_interp_bicubic uses for an r x r map (interp.h: r >= 4 bicubic, r = 2, 3
 * bilinear, r = 1 constant). */
static const char *method_name(int r)
{
    return r >= 4 ? "bicubic" : r >= 2 ? "bilinear" : "constant";
}

/* Replies {id_key: id, "r", "n", "method", "S": [n*n]} for the r x r map S, or an error. */
static void reply_interp(api_req_t *q, const char *id_key, int64_t id, const double *S, int r,
                         int n)
{
    size_t nn = (size_t)n * (size_t)n;
    double *out = malloc(sizeof(double) * nn);
    err_t err = {{0}};
    if (!out) {
        api_error(q, 500, "internal", NULL, "out of memory (n = %d)", n);
        return;
    }
    int ret = fit_interp_bicubic(S, r, n, out, &err);
    if (ret) {
        api_error(q, 500, "internal", NULL, "%s", err.msg);
        free(out);
        return;
    }
    json_t *a = json_array();
    for (size_t k = 0; a && k < nn; k++)
        if (json_array_append_new(a, api_num(out[k]))) {
            json_decref(a);
            a = NULL;
        }
    free(out);
    api_reply_json(q, 200,
                   a ? json_pack("{s:I, s:i, s:i, s:s, s:o}", id_key, (json_int_t)id, "r", r, "n",
                                 n, "method", method_name(r), "S", a)
                     : NULL);
}

/* ?n= (1..INTERP_N_MAX, default INTERP_N_DEFAULT); -1 after replying. */
static int read_n(api_req_t *q, int *n)
{
    long long v;
    if (api_query_int(q, "n", INTERP_N_DEFAULT, 1, INTERP_N_MAX, &v)) return -1;
    *n = (int)v;
    return 0;
}

/* The r*r numbers of map S (a JSON array) into a new array; NULL when S is not r*r finite
 * numbers (a fit without a map has S null). */
static double *map_values(json_t *S, int r)
{
    size_t m = (size_t)r * (size_t)r;
    if (!json_is_array(S) || json_array_size(S) != m) return NULL;
    double *v = malloc(sizeof(double) * m);
    for (size_t k = 0; v && k < m; k++) {
        json_t *x = json_array_get(S, k);
        v[k] = json_is_number(x) ? json_number_value(x) : NAN;
        if (!isfinite(v[k])) {
            free(v);
            v = NULL;
        }
    }
    return v;
}

/* Interpolates the map of sweep entry r of fit f's result document, or replies why not. */
static void fit_interp(api_req_t *q, const storage_fit_t *f, long long r_asked, int n)
{
    json_t *doc = f->result ? json_loads(f->result, JSON_DECODE_ANY, NULL) : NULL;
    json_t *fits = json_object_get(doc, "fits"), *entry, *found = NULL;
    /* default: the recommended map, the one the fit's calibration stores (documents stored before
     * recommended_r existed fall back to the best-BIC r, which their calibration stored) */
    json_t *rec = json_object_get(doc, "recommended_r");
    int r = r_asked                ? (int)r_asked
            : json_is_integer(rec) ? (int)json_integer_value(rec)
            : json_is_null(rec)    ? 0
                                   : f->best_r_bic,
        r_lo = 0, r_hi = 0;
    size_t i;
    json_array_foreach(fits, i, entry)
    {
        int er = (int)json_integer_value(json_object_get(entry, "r"));
        if (er == r) found = entry;
        if (!r_lo || er < r_lo) r_lo = er;
        if (er > r_hi) r_hi = er;
    }
    if (!r) {
        api_error(q, 422, "missing", "r",
                  "fit %lld has no recommended map: give r (its sweep is %d..%d)", (long long)f->id,
                  r_lo, r_hi);
    } else if (!found) {
        api_error(q, 422, "out_of_range", "r", "r must be in fit %lld's sweep %d..%d (got %d)",
                  (long long)f->id, r_lo, r_hi, r);
    } else {
        double *S = map_values(json_object_get(found, "S"), r);
        if (S) {
            reply_interp(q, "fit_id", f->id, S, r, n);
            free(S);
        } else {
            const char *status = json_string_value(json_object_get(found, "status"));
            api_error(q, 409, "no_data", "r", "the r = %d fit of fit %lld has no map (status %s)",
                      r, (long long)f->id, status ? status : "unknown");
        }
    }
    json_decref(doc);
}

void api_h_fit_interp(api_req_t *q)
{
    storage_t *st;
    storage_fit_t f;
    int64_t id;
    long long r;
    int n;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "fit", &id) || read_n(q, &n) ||
        api_query_int(q, "r", 0, 1, INTERP_R_MAX, &r) || !(st = api_db(q)))
        return;
    int ret = storage_fit_get(st, id, &f, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    fit_interp(q, &f, r, n);
    storage_fit_free(&f);
}

void api_h_calib_interp(api_req_t *q)
{
    storage_t *st;
    storage_calib_t c;
    int64_t id;
    int n;
    err_t err = {{0}};
    if (api_arg_id(q, 0, "calibration", &id) || read_n(q, &n) || !(st = api_db(q))) return;
    int ret = storage_calib_get(st, id, &c, &err);
    if (ret) {
        api_error_rc(q, ret, NULL, err.msg);
        return;
    }
    reply_interp(q, "calibration_id", c.id, c.S, c.r, n);
    storage_calib_free(&c);
}
