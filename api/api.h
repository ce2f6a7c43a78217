/* api.h: ipsd's HTTP API (libmicrohttpd + jansson): the front end srv_main runs, and what tests
 * inspect (the route table and the OpenAPI document). Routes, request and response schemas:
 * docs/api.md and GET /api/openapi.json. */
#ifndef IPSD_API_API_H
#define IPSD_API_API_H

#include <stddef.h>

#include "server/srv_main.h"

/* The HTTP front end: start (thread pool on the configured address), quiesce, stop. */
extern const srv_frontend_t api_frontend;

/* One route of the API: method, path pattern ({name} matches one integer path segment). */
typedef struct api_route_info {
    const char *method;
    const char *pattern;
} api_route_info_t;

/* The route table (static), *n routes. */
const api_route_info_t *api_route_list(size_t *n);

/* The OpenAPI 3.1 document served at /api/openapi.json (static text, *len bytes). */
const char *api_openapi_text(size_t *len);

#endif
