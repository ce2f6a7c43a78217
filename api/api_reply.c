/* api_reply.c: building the reply of a request: JSON and text bodies, the error body of
 * docs/contracts.md ({"error": {"code", "message", "field"}}), the mapping of storage and server
 * error codes to HTTP statuses, and the request's borrowed database handle. */
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"
#include "base/utf8.h"

void api_reply_text(api_req_t *q, unsigned status, const char *ctype, char *buf, size_t len)
{
    if (q->resp) { /* a reply exists already: keep the first */
        free(buf);
        return;
    }
    q->resp = MHD_create_response_from_buffer(len, buf, MHD_RESPMEM_MUST_FREE);
    if (!q->resp) {
        free(buf);
        return;
    }
    q->status = status;
    q->resp_bytes = (long long)len;
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CONTENT_TYPE, ctype);
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
}

void api_reply_shared(api_req_t *q, unsigned status, const char *ctype, char *buf, size_t len,
                      void (*release)(void *))
{
    if (q->resp) { /* a reply exists already: keep the first */
        release(buf);
        return;
    }
    q->resp = MHD_create_response_from_buffer_with_free_callback(len, buf, release);
    if (!q->resp) {
        release(buf);
        return;
    }
    q->status = status;
    q->resp_bytes = (long long)len;
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CONTENT_TYPE, ctype);
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CACHE_CONTROL, "no-store");
}

char *api_json_text(json_t *body, size_t *len)
{
    if (!body) return NULL;
    /* 17 significant digits: maps and positions read back bit-identical */
    char *text = json_dumps(body, JSON_COMPACT | JSON_REAL_PRECISION(17));
    json_decref(body);
    if (text) *len = strlen(text);
    return text;
}

void api_reply_json(api_req_t *q, unsigned status, json_t *body)
{
    size_t len = 0;
    char *text = api_json_text(body, &len);
    if (!text) {
        api_error(q, 500, "internal", NULL, "out of memory building the reply");
        return;
    }
    api_reply_text(q, status, "application/json", text, len);
}

void api_error(api_req_t *q, unsigned status, const char *code, const char *field, const char *fmt,
               ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* messages quote the request (a URL, a query value, a cut-off key): make them valid UTF-8, or
     * jansson refuses them and the body would lose its message and field */
    utf8_sanitize(msg);
    char fld[256];
    if (field) {
        snprintf(fld, sizeof fld, "%s", field);
        utf8_sanitize(fld);
    }
    json_t *e = json_pack("{s:s, s:s}", "code", code, "message", msg);
    if (e && field) json_object_set_new(e, "field", json_string(fld));
    json_t *body = e ? json_pack("{s:o}", "error", e) : NULL;
    char *text = body ? json_dumps(body, JSON_COMPACT) : NULL;
    json_decref(body);
    if (!text)
        text = strdup("{\"error\": {\"code\": \"internal\", \"message\": \"out of memory\"}}");
    if (text) api_reply_text(q, status, "application/json", text, strlen(text));
}

void api_error_rc(api_req_t *q, int rc, const char *field, const char *msg)
{
    switch (rc) {
    case -ENOENT:
        api_error(q, 404, "not_found", field, "%s", msg);
        break;
    case -EINVAL:
        api_error(q, 422, "invalid", field, "%s", msg);
        break;
    case -EEXIST:
        api_error(q, 409, "exists", field, "%s", msg);
        break;
    case -ESTALE:
        api_error(q, 409, "conflict", field, "%s", msg);
        break;
    case -ENODATA:
        api_error(q, 409, "no_data", field, "%s", msg);
        break;
    case -EBUSY:
        api_error(q, 503, "busy", NULL, "database busy, try again: %s", msg);
        break;
    case -ESHUTDOWN:
        api_error(q, 503, "shutting_down", NULL, "%s", msg);
        break;
    case -ENOSPC: /* the database's disk is full: nothing was stored */
        api_error(q, 507, "storage_full", NULL, "%s", msg);
        break;
    case -EROFS:
        api_error(q, 503, "storage_read_only", NULL, "%s", msg);
        break;
    default:
        api_error(q, 500, "internal", NULL, "%s", msg);
        break;
    }
}

storage_t *api_db(api_req_t *q)
{
    if (q->st) return q->st;
    err_t err = {{0}};
    q->st = srv_db_get(q->srv, &err);
    if (!q->st) api_error(q, 503, "unavailable", NULL, "database unavailable: %s", err.msg);
    return q->st;
}
