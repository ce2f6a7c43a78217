/* api_misc.c: GET /api/health (cheap: no database access). GET /api/openapi.json is in
 * api_openapi.c. */
#include <stdlib.h>
#include <string.h>

#include "api_int.h"

#ifndef IPSD_VERSION
#define IPSD_VERSION "unknown"
#endif

void api_h_health(api_req_t *q)
{
    const srv_config_t *cfg = srv_config(q->srv);
    api_reply_json(q, 200,
                   json_pack("{s:s, s:s, s:s}", "status", srv_stopping(q->srv) ? "stopping" : "ok",
                             "version", IPSD_VERSION, "bench", cfg->bench));
}
