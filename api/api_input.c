/* api_input.c: reading request input with errors that name the field: query parameters, the JSON
 * body, typed members with ranges (wrong type 400, out of range 422), unknown members, path ids,
 * and the CSV choice. Each of these functions replies itself and returns -1 on bad input, so a handler just
 * returns. */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "api_int.h"
#include "base/parse.h"

const char *api_query(api_req_t *q, const char *key)
{
    return MHD_lookup_connection_value(q->conn, MHD_GET_ARGUMENT_KIND, key);
}

int api_query_int(api_req_t *q, const char *key, long long def, long long lo, long long hi,
                  long long *v)
{
    const char *s = api_query(q, key);
    *v = def;
    if (!s) return 0;
    long long x;
    if (parse_ll(s, &x)) {
        api_error(q, 400, "bad_type", key, "query parameter %s must be an integer (got '%s')", key,
                  s);
        return -1;
    }
    if (x < lo || x > hi) {
        api_error(q, 422, "out_of_range", key, "query parameter %s must be %lld..%lld (got %lld)",
                  key, lo, hi, x);
        return -1;
    }
    *v = x;
    return 0;
}

int api_query_page(api_req_t *q, long long *limit, long long *offset)
{
    return api_query_int(q, "limit", 50, 1, 1000, limit) ||
                   api_query_int(q, "offset", 0, 0, INT32_MAX, offset)
               ? -1
               : 0;
}

int api_query_state(api_req_t *q, int *state)
{
    const char *s = api_query(q, "state");
    storage_state_t v;
    *state = STORAGE_ANY;
    if (!s) return 0;
    if (storage_state_parse(s, &v)) {
        api_error(q, 422, "out_of_range", "state",
                  "state must be queued, running, done, failed "
                  "or cancelled (got '%s')",
                  s);
        return -1;
    }
    *state = (int)v;
    return 0;
}

json_t *api_body_object(api_req_t *q)
{
    json_error_t je;
    if (!q->body || q->body_len == 0) {
        api_error(q, 400, "bad_json", NULL, "the request needs a JSON object body");
        return NULL;
    }
    json_t *o = json_loadb(q->body, q->body_len, JSON_REJECT_DUPLICATES, &je);
    if (!o) {
        api_error(q, 400, "bad_json", NULL, "malformed JSON at line %d, column %d: %s", je.line,
                  je.column, je.text);
        return NULL;
    }
    if (!json_is_object(o)) {
        json_decref(o);
        api_error(q, 400, "bad_json", NULL, "the body must be a JSON object");
        return NULL;
    }
    return o;
}

/* The member, or NULL; replies 422 when required and absent. *bad = 1 then. */
static json_t *member(api_req_t *q, json_t *o, const char *key, const char *path, int required,
                      int *bad)
{
    json_t *x = json_object_get(o, key);
    *bad = 0;
    if (!x && required) {
        api_error(q, 422, "missing", path, "%s is required", path);
        *bad = 1;
    }
    return x;
}

int api_get_int(api_req_t *q, json_t *o, const char *key, const char *path, int required,
                long long lo, long long hi, long long *v)
{
    int bad;
    json_t *x = member(q, o, key, path, required, &bad);
    if (!x) return -bad;
    if (!json_is_integer(x)) {
        api_error(q, 400, "bad_type", path, "%s must be an integer", path);
        return -1;
    }
    long long y = json_integer_value(x);
    if (y < lo || y > hi) {
        api_error(q, 422, "out_of_range", path, "%s must be %lld..%lld (got %lld)", path, lo, hi,
                  y);
        return -1;
    }
    *v = y;
    return 0;
}

int api_get_num(api_req_t *q, json_t *o, const char *key, const char *path, int required, double lo,
                double hi, int open_lo, double *v)
{
    int bad;
    json_t *x = member(q, o, key, path, required, &bad);
    if (!x) return -bad;
    if (!json_is_number(x)) {
        api_error(q, 400, "bad_type", path, "%s must be a number", path);
        return -1;
    }
    double y = json_number_value(x);
    if (y != 0 && fabs(y) < DBL_MIN) { /* subnormal: no physical constant, and 1/y overflows */
        api_error(q, 422, "out_of_range", path, "%s must be 0 or at least %g in size (got %g)",
                  path, DBL_MIN, y);
        return -1;
    }
    if (!isfinite(y) || (open_lo ? !(y > lo) : !(y >= lo)) || !(y <= hi)) {
        api_error(q, 422, "out_of_range", path, "%s must be %s %g and <= %g (got %g)", path,
                  open_lo ? ">" : ">=", lo, hi, y);
        return -1;
    }
    *v = y;
    return 0;
}

int api_get_str(api_req_t *q, json_t *o, const char *key, const char *path, int required,
                size_t max_len, const char **v)
{
    int bad;
    json_t *x = member(q, o, key, path, required, &bad);
    if (!x) return -bad;
    if (!json_is_string(x)) {
        api_error(q, 400, "bad_type", path, "%s must be a string", path);
        return -1;
    }
    size_t n = json_string_length(x);
    if (n == 0 || n > max_len) {
        api_error(q, 422, "out_of_range", path, "%s must be 1..%zu characters (got %zu)", path,
                  max_len, n);
        return -1;
    }
    *v = json_string_value(x);
    return 0;
}

int api_get_bool(api_req_t *q, json_t *o, const char *key, const char *path, int *v)
{
    json_t *x = json_object_get(o, key);
    if (!x) return 0;
    if (!json_is_boolean(x)) {
        api_error(q, 400, "bad_type", path, "%s must be true or false", path);
        return -1;
    }
    *v = json_is_true(x);
    return 0;
}

int api_get_obj(api_req_t *q, json_t *o, const char *key, const char *path, json_t **v)
{
    json_t *x = json_object_get(o, key);
    *v = NULL;
    if (!x) return 0;
    if (!json_is_object(x)) {
        api_error(q, 400, "bad_type", path, "%s must be an object", path);
        return -1;
    }
    *v = x;
    return 0;
}

int api_no_unknown(api_req_t *q, json_t *o, const char *prefix, const char *const *keys)
{
    const char *key;
    json_t *value;
    json_object_foreach(o, key, value)
    {
        int known = 0;
        for (const char *const *k = keys; *k && !known; k++)
            known = strcmp(*k, key) == 0;
        if (known) continue;
        char path[128];
        snprintf(path, sizeof path, "%s%s", prefix, key);
        api_error(q, 422, "unknown_field", path, "%s is not a field of this request", path);
        return -1;
    }
    return 0;
}

int api_wants_csv(api_req_t *q)
{
    const char *f = api_query(q, "format");
    if (f) {
        if (strcmp(f, "csv") == 0) return 1;
        if (strcmp(f, "json") == 0) return 0;
        api_error(q, 400, "bad_value", "format", "format must be json or csv (got '%s')", f);
        return -1;
    }
    const char *accept =
        MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_ACCEPT);
    return accept && strncasecmp(accept, "text/csv", 8) == 0;
}

int api_arg_id(api_req_t *q, int i, const char *what, int64_t *id)
{
    *id = q->arg[i];
    if (*id >= 1) return 0;
    api_error(q, 404, "not_found", NULL, "%s %lld does not exist", what, (long long)*id);
    return -1;
}
