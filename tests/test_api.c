/* test_api.c: the API's route table and its OpenAPI document: the document is valid JSON, OpenAPI
 * 3.1, and describes exactly the routes the router has (every route documented, nothing documented
 * that is not routed, each with responses); the router matches integer path arguments and tells a
 * wrong method (405) from an unknown path (404); the calibration reply cache answers only for the
 * pixel and generation it holds and keeps within its byte bound. */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "api_calib_cache.h"
#include "api_int.h"
#include "check.h"

static void lower(const char *in, char *out, size_t n)
{
    size_t i = 0;
    for (; in[i] && i + 1 < n; i++)
        out[i] = (char)tolower((unsigned char)in[i]);
    out[i] = 0;
}

static void test_openapi(void)
{
    size_t len, n;
    const char *text = api_openapi_text(&len);
    json_error_t je;
    json_t *doc = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (!doc) fprintf(stderr, "openapi.json line %d: %s\n", je.line, je.text);
    CHECK(doc != NULL);
    CHECK(strlen(text) == len); /* NUL-terminated, no NUL inside */
    CHECK(strcmp(json_string_value(json_object_get(doc, "openapi")), "3.1.0") == 0);
    json_t *paths = json_object_get(doc, "paths");
    const api_route_info_t *routes = api_route_list(&n);
    CHECK(n >= 20);
    for (size_t i = 0; i < n; i++) {
        char m[16];
        lower(routes[i].method, m, sizeof m);
        json_t *op = json_object_get(json_object_get(paths, routes[i].pattern), m);
        if (!op) fprintf(stderr, "not documented: %s %s\n", routes[i].method, routes[i].pattern);
        CHECK(op && json_object_size(json_object_get(op, "responses")) > 0);
        CHECK(op && json_is_string(json_object_get(op, "summary")));
    }
    /* and the other way round: every documented operation is routed */
    const char *path, *method;
    json_t *item, *op;
    size_t documented = 0;
    json_object_foreach(paths, path, item)
    {
        json_object_foreach(item, method, op)
        {
            int found = 0;
            documented++;
            for (size_t i = 0; i < n && !found; i++) {
                char m[16];
                lower(routes[i].method, m, sizeof m);
                found = strcmp(routes[i].pattern, path) == 0 && strcmp(m, method) == 0;
            }
            if (!found) fprintf(stderr, "documented, not routed: %s %s\n", method, path);
            CHECK(found);
        }
    }
    CHECK(documented == n);
    /* every $ref points to a schema that exists */
    char *dump = json_dumps(doc, 0);
    json_t *schemas = json_object_get(json_object_get(doc, "components"), "schemas");
    for (char *p = dump; p && (p = strstr(p, "#/components/schemas/")); p++) {
        char name[64] = {0};
        sscanf(p + 21, "%63[A-Za-z]", name);
        if (!json_object_get(schemas, name)) fprintf(stderr, "dangling $ref %s\n", name);
        CHECK(json_object_get(schemas, name) != NULL);
    }
    free(dump);
    json_decref(doc);
}

static void test_router(void)
{
    int64_t arg[API_MAX_ARGS];
    int known = -1;
    const api_route_t *r =
        api_route_find("GET", "/api/sensors/12/pixels/3/40/calibration", arg, &known);
    CHECK(r && r->fn == api_h_pixel_calib && arg[0] == 12 && arg[1] == 3 && arg[2] == 40);
    r = api_route_find("GET", "/api/scans/7/pixels/-1/2", arg, &known);
    CHECK(r && r->fn == api_h_scan_pixel && arg[0] == 7 && arg[1] == -1 && arg[2] == 2);
    r = api_route_find("HEAD", "/api/health", arg, &known);
    CHECK(r && r->fn == api_h_health);
    r = api_route_find("POST", "/api/scans", arg, &known);
    CHECK(r && r->fn == api_h_scans_create && r->json_body);
    r = api_route_find("DELETE", "/api/scans/3", arg, &known);
    CHECK(!r && known == 1); /* 405 */
    const char *bad[] = {"/api/scans/3x",
                         "/api/scans/",
                         "/api/scans/3/",
                         "/api/scans/--3",
                         "/api/scans/1234567890123456",
                         "/api/scan",
                         "/api/scans/3/fits/x"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        r = api_route_find("GET", bad[i], arg, &known);
        CHECK(!r && known == 0); /* 404 */
    }
    char allow[64];
    CHECK(strcmp(api_route_allow("/api/scans", allow, sizeof allow), "GET, POST") == 0);
}

static void test_calib_cache(void)
{
    size_t len = 0, entries, bytes;
    uint64_t hits, misses;
    api_calib_cache_t *c = api_calib_cache_new(8, 100);
    CHECK(c != NULL);
    CHECK(api_calib_cache_get(c, 1, 2, 3, 0, &len) == NULL); /* empty */
    api_calib_cache_put(c, 1, 2, 3, 5, "{\"a\":1}", 7);
    char *t = api_calib_cache_get(c, 1, 2, 3, 5, &len);
    CHECK(t && len == 7 && strcmp(t, "{\"a\":1}") == 0);
    api_calib_cache_release(t);
    CHECK(api_calib_cache_get(c, 1, 2, 3, 6, &len) == NULL); /* a calibration was stored since */
    CHECK(api_calib_cache_get(c, 1, 3, 2, 5, &len) == NULL); /* another pixel */
    api_calib_cache_put(c, 1, 2, 3, 4, "old", 3); /* an older reader's text does not replace it */
    t = api_calib_cache_get(c, 1, 2, 3, 5, &len);
    CHECK(t && strcmp(t, "{\"a\":1}") == 0);
    /* a text held by a reply outlives its entry's replacement and the cache */
    api_calib_cache_put(c, 1, 2, 3, 6, "{\"a\":2}", 7);
    char *t2 = api_calib_cache_get(c, 1, 2, 3, 6, &len);
    CHECK(t2 && strcmp(t2, "{\"a\":2}") == 0 && strcmp(t, "{\"a\":1}") == 0);
    api_calib_cache_release(t2);
    char big[101];
    memset(big, 'x', 100);
    big[100] = 0;
    api_calib_cache_put(c, 7, 7, 7, 5, big, 100); /* 107 bytes in all: over the bound, skipped */
    CHECK(api_calib_cache_get(c, 7, 7, 7, 5, &len) == NULL);
    api_calib_cache_stats(c, &hits, &misses, &entries, &bytes);
    CHECK(hits == 3 && misses == 4 && entries == 1 && bytes == 7);
    api_calib_cache_free(c);
    CHECK(strcmp(t, "{\"a\":1}") == 0); /* still held here (ASan: no use after free) */
    api_calib_cache_release(t);
}

int main(void)
{
    test_openapi();
    test_router();
    test_calib_cache();
    CHECK_DONE();
}
