/* api_misc.c: GET /api/health (cheap: no database access) and GET /api/openapi.json (the embedded
 * OpenAPI 3.1 document, api/openapi.json). */
#include <stdlib.h>
#include <string.h>

#include "api_int.h"

#ifndef IPSD_VERSION
#define IPSD_VERSION "unknown"
#endif

extern const char *const api_openapi_json; /* generated from api/openapi.json at build time */
extern const size_t api_openapi_json_len;

const char *api_openapi_text(size_t *len)
{
    *len = api_openapi_json_len;
    return api_openapi_json;
}

void api_h_health(api_req_t *q)
{
    const srv_config_t *cfg = srv_config(q->srv);
    api_reply_json(q, 200,
                   json_pack("{s:s, s:s, s:s}", "status", srv_stopping(q->srv) ? "stopping" : "ok",
                             "version", IPSD_VERSION, "bench", cfg->bench));
}

void api_h_openapi(api_req_t *q)
{
    char *copy = malloc(api_openapi_json_len);
    if (!copy) {
        api_error(q, 500, "internal", NULL, "out of memory");
        return;
    }
    memcpy(copy, api_openapi_json, api_openapi_json_len);
    api_reply_text(q, 200, "application/json", copy, api_openapi_json_len);
}
