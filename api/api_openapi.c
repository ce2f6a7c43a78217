/* api_openapi.c: GET /api/openapi.json, the OpenAPI 3.1 document: api/openapi.json (embedded at
 * build time) with the scan request's bounds filled in from the one definition of a scan's
 * defaults and limits (instrument/scan_limits.h). Each field of scan_fields[] that the request
 * has (its api path under components.schemas.ScanCreate) gets its default, minimum or
 * exclusiveMinimum, maximum and description from the table, and odd fields "not": {"multipleOf":
 * 2} and "x-odd": true; so the document, the API's checks and `ips simulate` cannot disagree. The
 * document is built once, on first use, and served as is after. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"
#include "instrument/scan_limits.h"

extern const char *const api_openapi_json; /* generated from api/openapi.json at build time */
extern const size_t api_openapi_json_len;

static pthread_once_t once = PTHREAD_ONCE_INIT;
static const char *doc_text;
static size_t doc_len;

/* A number of field f: an integer for integer fields (so that 5 is not served as 5.0). */
static json_t *number(const scan_field_t *f, double v)
{
    return f->integer ? json_integer((json_int_t)v) : json_real(v);
}

/* The schema of the scan request member at path ("raster.area_px") in doc, or NULL. */
static json_t *request_member(json_t *doc, const char *path)
{
    json_t *s = json_object_get(json_object_get(json_object_get(doc, "components"), "schemas"),
                                "ScanCreate");
    char seg[64];
    for (const char *p = path; s && *p;) {
        size_t n = strcspn(p, ".");
        if (n >= sizeof seg) return NULL;
        memcpy(seg, p, n);
        seg[n] = '\0';
        s = json_object_get(json_object_get(s, "properties"), seg);
        p += n + (p[n] == '.');
    }
    return s;
}

/* Writes the table's bounds into doc; 0, or -1 naming the field the document lacks. */
static int patch(json_t *doc)
{
    for (int i = 0; i < SCAN_NFIELDS; i++) {
        const scan_field_t *f = &scan_fields[i];
        if (!f->api) continue;
        json_t *m = request_member(doc, f->api);
        if (!json_is_object(m)) {
            fprintf(stderr, "ipsd: openapi.json has no ScanCreate member %s\n", f->api);
            return -1;
        }
        json_object_del(m, "minimum");
        json_object_del(m, "exclusiveMinimum");
        json_object_del(m, "default");
        json_object_set_new(m, f->open_min ? "exclusiveMinimum" : "minimum", number(f, f->min));
        json_object_set_new(m, "maximum", number(f, f->max));
        if (isfinite(f->def)) json_object_set_new(m, "default", number(f, f->def));
        if (f->odd) {
            json_object_set_new(m, "not", json_pack("{s:i}", "multipleOf", 2));
            json_object_set_new(m, "x-odd", json_true());
        }
        json_object_set_new(m, "description", json_string(f->description));
    }
    return 0;
}

/* doc as text with 15 significant digits when every number reads back as itself (0.6, not the
 * 0.59999999999999998 of 17 digits), else with 17 (always exact). */
static char *dump(const json_t *doc)
{
    char *text = json_dumps(doc, JSON_INDENT(1) | JSON_REAL_PRECISION(15));
    json_t *back = text ? json_loads(text, 0, NULL) : NULL;
    int same = back && json_equal(doc, back);
    json_decref(back);
    if (same) return text;
    free(text);
    return json_dumps(doc, JSON_INDENT(1) | JSON_REAL_PRECISION(17));
}

static void build(void)
{
    doc_text = api_openapi_json;
    doc_len = api_openapi_json_len;
    json_t *doc = json_loadb(api_openapi_json, api_openapi_json_len, 0, NULL);
    char *text = doc && patch(doc) == 0 ? dump(doc) : NULL;
    if (text) {
        doc_text = text; /* kept for the life of the process */
        doc_len = strlen(text);
    } else {
        fprintf(stderr, "ipsd: serving openapi.json without the scan limits filled in\n");
    }
    json_decref(doc);
}

const char *api_openapi_text(size_t *len)
{
    pthread_once(&once, build);
    *len = doc_len;
    return doc_text;
}

void api_h_openapi(api_req_t *q)
{
    size_t len;
    const char *text = api_openapi_text(&len);
    char *copy = malloc(len);
    if (!copy) {
        api_error(q, 500, "internal", NULL, "out of memory");
        return;
    }
    memcpy(copy, text, len);
    api_reply_text(q, 200, "application/json", copy, len);
}
