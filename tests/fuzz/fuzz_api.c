/* fuzz_api.c: see fuzz_api.h. The fuzz executables are linked with
 * -Wl,--wrap=MHD_lookup_connection_value,--wrap=MHD_create_response_from_buffer (tests/fuzz.cmake):
 * the first answers the handlers' query and header look-ups for the fake connection from the
 * fuzzed query string, the second keeps a copy of each reply body for the checks. The server core
 * is opened but never started, and stopped after the database is seeded: the validators and the
 * reads run in full, and a valid write that would queue a job (a scan, a fit) is refused with 503
 * shutting_down, so a long run does not fill the database with jobs. */
#include "fuzz_api.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <jansson.h>
#include <microhttpd.h>

#include "api_int.h"
#include "server/srv.h"

/* ---- the fake connection ---- */

static char fake_conn_tag;
#define FAKE_CONN ((struct MHD_Connection *)&fake_conn_tag)
#define MAX_ARGS 64

static struct {
    char *key[MAX_ARGS], *value[MAX_ARGS];
    int n;
} args;

const char *__real_MHD_lookup_connection_value(struct MHD_Connection *c, enum MHD_ValueKind kind,
                                               const char *key);
struct MHD_Response *__real_MHD_create_response_from_buffer(size_t size, void *buffer,
                                                           enum MHD_ResponseMemoryMode mode);
const char *__wrap_MHD_lookup_connection_value(struct MHD_Connection *c, enum MHD_ValueKind kind,
                                               const char *key);
struct MHD_Response *__wrap_MHD_create_response_from_buffer(size_t size, void *buffer,
                                                           enum MHD_ResponseMemoryMode mode);

/* libmicrohttpd's look-up: the first argument of that name, compared without case. The fake
 * connection has no headers (no Accept, no Authorization). */
const char *__wrap_MHD_lookup_connection_value(struct MHD_Connection *c, enum MHD_ValueKind kind,
                                               const char *key)
{
    if (c != FAKE_CONN) return __real_MHD_lookup_connection_value(c, kind, key);
    if (kind != MHD_GET_ARGUMENT_KIND || !key) return NULL;
    for (int i = 0; i < args.n; i++)
        if (strcasecmp(args.key[i], key) == 0) return args.value[i];
    return NULL;
}

static char *reply_body;
static size_t reply_len;

struct MHD_Response *__wrap_MHD_create_response_from_buffer(size_t size, void *buffer,
                                                           enum MHD_ResponseMemoryMode mode)
{
    free(reply_body);
    reply_body = malloc(size + 1);
    if (!reply_body) abort();
    memcpy(reply_body, buffer, size);
    reply_body[size] = 0;
    reply_len = size;
    return __real_MHD_create_response_from_buffer(size, buffer, mode);
}

/* '+' is a space in a query (MHD_unescape_plus), then the API's unescape. */
static void unescape_arg(char *s)
{
    for (char *p = s; *p; p++)
        if (*p == '+') *p = ' ';
    api_unescape_keep_nul(NULL, NULL, s);
}

static void add_arg(char *key, char *value)
{
    if (args.n == MAX_ARGS) return;
    unescape_arg(key);
    if (value) unescape_arg(value);
    args.key[args.n] = key;
    args.value[args.n] = value; /* NULL: "key" without '=' */
    args.n++;
}

/* libmicrohttpd's MHD_parse_arguments_: '&'-separated, each "key", "key=" or "key=value";
 * splits the query in place. */
static void parse_query(char *s)
{
    args.n = 0;
    while (s && *s) {
        char *amp = strchr(s, '&'), *eq = strchr(s, '=');
        if (amp) *amp++ = 0;
        if (eq && (!amp || eq < amp)) {
            *eq++ = 0;
            add_arg(s, eq);
        } else {
            add_arg(s, NULL);
        }
        s = amp;
    }
}

/* ---- the server ---- */

static srv_t *srv;
static char dir[64], db[128];

static void env_close(void)
{
    char path[160];
    srv_close(srv);
    srv = NULL;
    free(reply_body);
    reply_body = NULL;
    const char *suffix[] = {"", "-wal", "-shm", "-journal", "-ipsd.lock"};
    for (size_t i = 0; i < sizeof suffix / sizeof suffix[0]; i++) {
        snprintf(path, sizeof path, "%s%s", db, suffix[i]);
        unlink(path);
    }
    rmdir(dir);
}

static void must(int ok, const char *what)
{
    if (ok) return;
    fprintf(stderr, "fuzz_api: %s\n", what);
    abort();
}

static void env_open(void)
{
    const char *tmp = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    snprintf(dir, sizeof dir, "%s/ipsd-fuzz-XXXXXX", tmp);
    must(mkdtemp(dir) != NULL, "cannot make a temporary directory");
    snprintf(db, sizeof db, "%s/fuzz.db", dir);
    srv_config_t cfg = srv_config_default();
    snprintf(cfg.db_path, sizeof cfg.db_path, "%s", db);
    /* a jitter request's Airy integrals at most a twentieth of the default (ipsd
     * --max-jitter-evals, about a second in a release build): the sanitized, instrumented fuzz
     * build runs them ~8 times slower, a busy machine slower still, and a run past the fuzzer's
     * 10 s -timeout is reported as a hang (half the default took 13 s with both cores busy). The
     * bound itself is what is fuzzed; its size is not. */
    cfg.max_jitter_evals = 2000000;
    err_t err = {{0}};
    if (srv_open(&cfg, &srv, &err)) {
        fprintf(stderr, "fuzz_api: srv_open: %s\n", err.msg);
        abort();
    }
    atexit(env_close);
    static const char sensor[] = "{\"model\":\"fuzz\",\"serial\":\"F-1\",\"n_cols\":64,"
                                 "\"n_rows\":64,\"pitch_um\":6}";
    static const char scan[] = "{\"sensor_id\":1,\"poi\":{\"col\":10,\"row\":10},"
                               "\"raster\":{\"area_px\":1,\"step_um\":2,\"sub_px\":3,\"frames\":1}}";
    must(fuzz_request("POST", "/api/sensors", sensor, strlen(sensor)) == 201, "seeding the sensor");
    must(fuzz_request("POST", "/api/scans", scan, strlen(scan)) == 202, "seeding the scan");
    srv_stop(srv);
}

/* ---- the checks of a reply ---- */

static void check_reply(const api_req_t *q, const char *method, const char *url)
{
    if (getenv("IPSD_FUZZ_VERBOSE")) /* to see what the seeds reach */
        fprintf(stderr, "%s %s -> %u %.300s\n", method, url, q->status,
                reply_body ? reply_body : "");
    if (!q->resp) {
        fprintf(stderr, "fuzz_api: %s %s: the handler did not reply\n", method, url);
        abort();
    }
    if (q->status >= 500 && q->status != 503) {
        fprintf(stderr, "fuzz_api: %s %s: %u %s\n", method, url, q->status, reply_body);
        abort();
    }
    if (!reply_body || (reply_body[0] != '{' && reply_body[0] != '[')) {
        if (q->status >= 400) {
            fprintf(stderr, "fuzz_api: %s %s: error %u without a JSON body\n", method, url,
                    q->status);
            abort();
        }
        return; /* CSV */
    }
    json_error_t je;
    json_t *o = json_loadb(reply_body, reply_len, JSON_REJECT_DUPLICATES, &je);
    if (!o) {
        fprintf(stderr, "fuzz_api: %s %s: %u reply is not JSON (%s): %s\n", method, url, q->status,
                je.text, reply_body);
        abort();
    }
    if (q->status >= 400) {
        json_t *e = json_object_get(o, "error");
        const char *msg = json_string_value(json_object_get(e, "message"));
        if (!json_is_string(json_object_get(e, "code")) || !msg ||
            strcmp(msg, "out of memory") == 0) {
            fprintf(stderr, "fuzz_api: %s %s: %u has not the error body: %s\n", method, url,
                    q->status, reply_body);
            abort();
        }
    }
    json_decref(o);
}

unsigned fuzz_request(const char *method, const char *url, const char *body, size_t len)
{
    if (!srv) env_open();
    /* the path and the query, unescaped as libmicrohttpd hands them to the handlers */
    char *path = strdup(url);
    must(path != NULL, "out of memory");
    char *query = strchr(path, '?');
    if (query) *query++ = 0;
    api_unescape_keep_nul(NULL, NULL, path);
    parse_query(query);

    api_req_t q = {.srv = srv, .conn = FAKE_CONN};
    int known = 0;
    q.route = api_route_find(method, path, q.arg, &known);
    if (q.route && q.route->fn == api_h_events) q.route = NULL; /* would wait for events */
    if (!q.route) {
        free(path);
        return known ? 405 : 404;
    }
    if (q.route->json_body && body) {
        must((q.body = malloc(len + 1)) != NULL, "out of memory");
        memcpy(q.body, body, len);
        q.body[len] = 0;
        q.body_len = q.body_cap = len;
    }
    free(reply_body);
    reply_body = NULL;
    q.route->fn(&q);
    if (q.st) srv_db_put(srv, q.st);
    check_reply(&q, method, url);
    unsigned status = q.status;
    MHD_destroy_response(q.resp);
    free(q.body);
    free(path);
    return status;
}

unsigned fuzz_route(const char *method, const char *url)
{
    if (!srv) env_open();
    char *path = strdup(url);
    must(path != NULL, "out of memory");
    char *query = strchr(path, '?');
    if (query) *query = 0;
    size_t n = api_unescape_keep_nul(NULL, NULL, path);
    /* %00 stays literal: the unescaped path is a C string of the length returned */
    must(n == strlen(path) && n <= strlen(url), "api_unescape_keep_nul: wrong length");
    api_req_t q = {.srv = srv, .conn = FAKE_CONN};
    int known = 0;
    free(reply_body);
    reply_body = NULL;
    /* api_http.c's check_request: the route, else 405 with Allow or 404 quoting the path */
    q.route = api_route_find(method, path, q.arg, &known);
    if (q.route) {
        must(strcmp(q.route->method, method) == 0 ||
                 (strcmp(method, "HEAD") == 0 && strcmp(q.route->method, "GET") == 0),
             "api_route_find: a route of another method");
        free(path);
        return 200;
    }
    char allow[64];
    if (known) {
        api_route_allow(path, allow, sizeof allow);
        must(allow[0] != 0 && strlen(allow) < sizeof allow, "api_route_allow: no method");
        api_error(&q, 405, "method_not_allowed", NULL, "%s is not allowed on %s (allowed: %s)",
                  method, path, allow);
    } else {
        api_error(&q, 404, "not_found", NULL, "no such resource: %s", path);
    }
    check_reply(&q, method, url);
    unsigned status = q.status;
    MHD_destroy_response(q.resp);
    free(path);
    return status;
}
