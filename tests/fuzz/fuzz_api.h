/* fuzz_api.h: the fuzz targets' way into the API without HTTP: one server core per process on a
 * throw-away database (a sensor and a queued scan in it), and requests handed straight to the
 * router and the handlers, their query arguments split and unescaped as libmicrohttpd does. Every
 * reply is checked: a handler must answer, never with a 500, and every JSON body, the error body
 * included, must parse (docs/contracts.md). A broken rule abort()s, which libFuzzer and the replay
 * driver report with the input. */
#ifndef IPSD_TESTS_FUZZ_API_H
#define IPSD_TESTS_FUZZ_API_H

#include <stddef.h>
#include <stdint.h>

/* The ids the throw-away database holds (made through the API by the first request). */
#define FUZZ_SENSOR_ID 1
#define FUZZ_SCAN_ID 1

/* Runs one request: method, url (path, optionally ?query, escaped as on the wire) and body
 * (len bytes, may be NULL). The path goes through api_unescape_keep_nul and the router; a
 * route's handler runs (except the event stream, which would wait). Returns the status. */
unsigned fuzz_request(const char *method, const char *url, const char *body, size_t len);

/* The routing of a request as api_http.c's first callback does it, without running a handler:
 * the unescaped path, the route, or the 404 / 405 error body quoting the path. Returns 200 for
 * a route, else the error's status. */
unsigned fuzz_route(const char *method, const char *url);

/* The libFuzzer entry point every target defines (replay.c calls it without libFuzzer). */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#endif
