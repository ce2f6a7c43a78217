/* api_http.c: the HTTP server: a libmicrohttpd daemon with a thread pool on the configured
 * address, and the request life cycle. On the first callback of a request (headers only) the
 * route, the method, the token, the content type and a declared body size are checked, so bad
 * requests are refused before their body is read; JSON bodies are then accumulated up to
 * --max-body (a larger chunked body is read and dropped, then refused with 413); the handler runs
 * on the final callback. Connections of event streams are suspended while they wait (api_sse.c),
 * which is why the daemon allows suspend/resume. */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include "api_conn.h"
#include "api_int.h"

typedef struct api_http {
    srv_t *srv;
    struct MHD_Daemon *d;
    api_conns_t *conns;  /* open connections and their request deadlines */
    MHD_socket quiesced; /* the listening socket after quiesce, closed after the stop */
} api_http_t;

/* Compares the bearer token in constant time (no early exit on the first difference). */
static int token_ok(const char *want, const char *header)
{
    if (!header || strncasecmp(header, "Bearer ", 7) != 0) return 0;
    const char *got = header + 7;
    size_t n = strlen(want), m = strlen(got);
    unsigned char diff = (unsigned char)(n != m);
    for (size_t i = 0; i < n; i++)
        diff |= (unsigned char)(want[i] ^ (i < m ? got[i] : 0));
    return diff == 0;
}

/* libmicrohttpd's unescape of the URL path and of query arguments, except that %00 stays as
 * the three characters "%00": decoded, it would end the C string that handlers see, so that
 * "/api/scans/1%00junk" would be scan 1 and "/index.html%00.png" index.html. Kept literal, such
 * a path or value is simply not a valid one (404 / 400). Hand-written because MHD's own
 * MHD_http_unescape decodes every %XX. */
static int hex_digit(char c)
{
    return c >= '0' && c <= '9' ? c - '0'
           : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                  : -1;
}

size_t api_unescape_keep_nul(void *cls, struct MHD_Connection *c, char *s)
{
    (void)cls;
    (void)c;
    char *w = s;
    for (const char *r = s; *r;) {
        int hi = r[0] == '%' ? hex_digit(r[1]) : -1, lo = hi >= 0 ? hex_digit(r[2]) : -1;
        if (lo >= 0 && (hi | lo) != 0) {
            *w++ = (char)(hi << 4 | lo);
            r += 3;
        } else {
            *w++ = *r++;
        }
    }
    *w = 0;
    return (size_t)(w - s);
}

/* The media type of Content-Type (before any ';'), compared with application/json. */
static int is_json_type(const char *ct)
{
    if (!ct) return 0;
    size_t n = strcspn(ct, ";");
    while (n && (ct[n - 1] == ' ' || ct[n - 1] == '\t'))
        n--;
    return n == 16 && strncasecmp(ct, "application/json", 16) == 0;
}

/* The checks of the first callback; replies and returns -1 to refuse the request. */
static int check_request(api_req_t *q, const char *method, const char *url)
{
    const srv_config_t *cfg = srv_config(q->srv);
    int path_known = 0, write = strcmp(method, "GET") && strcmp(method, "HEAD");
    if (strncmp(url, "/api/", 5) != 0 && strcmp(url, "/api") != 0) {
        if (!write) return 0; /* static files */
        api_error(q, 405, "method_not_allowed", NULL, "%s is not allowed on %s", method, url);
        return -1;
    }
    q->route = api_route_find(method, url, q->arg, &path_known);
    if (!q->route) {
        if (path_known) {
            char allow[64];
            api_error(q, 405, "method_not_allowed", NULL, "%s is not allowed on %s (allowed: %s)",
                      method, url, api_route_allow(url, allow, sizeof allow));
            if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_ALLOW, allow);
        } else {
            api_error(q, 404, "not_found", NULL, "no such resource: %s", url);
        }
        return -1;
    }
    if (write && cfg->token &&
        !token_ok(cfg->token, MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND,
                                                          MHD_HTTP_HEADER_AUTHORIZATION))) {
        api_error(q, 401, "unauthorized", NULL, "%s needs 'Authorization: Bearer <token>'", method);
        if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer");
        return -1;
    }
    if (write && srv_stopping(q->srv)) {
        api_error(q, 503, "shutting_down", NULL, "ipsd is shutting down");
        return -1;
    }
    if (q->route->json_body && !is_json_type(MHD_lookup_connection_value(
                                   q->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE))) {
        api_error(q, 415, "unsupported_media_type", NULL,
                  "the body must be JSON with Content-Type: application/json");
        return -1;
    }
    const char *cl =
        MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
    if (cl && strtoull(cl, NULL, 10) > cfg->max_body) {
        api_error(q, 413, "payload_too_large", NULL, "the body is larger than %zu bytes",
                  cfg->max_body);
        return -1;
    }
    return 0;
}

/* Appends a chunk of the body (JSON routes only; other bodies are ignored). */
static void take_body(api_req_t *q, const char *data, size_t n)
{
    size_t max = srv_config(q->srv)->max_body;
    if (q->too_big || !q->route || !q->route->json_body) return;
    if (q->body_len + n > max) {
        q->too_big = 1;
        free(q->body);
        q->body = NULL;
        q->body_len = q->body_cap = 0;
        return;
    }
    if (q->body_len + n + 1 > q->body_cap) {
        size_t cap = q->body_cap ? q->body_cap : 4096;
        while (cap < q->body_len + n + 1)
            cap *= 2;
        char *b = realloc(q->body, cap);
        if (!b) {
            q->too_big = 1; /* cannot hold it: refuse it like an oversized one */
            return;
        }
        q->body = b;
        q->body_cap = cap;
    }
    memcpy(q->body + q->body_len, data, n);
    q->body_len += n;
    q->body[q->body_len] = 0;
}

/* Queues the reply built so far (a 500 if none) and gives the database handle back. */
static enum MHD_Result send_reply(api_req_t *q)
{
    if (q->st) {
        srv_db_put(q->srv, q->st);
        q->st = NULL;
    }
    if (!q->resp) api_error(q, 500, "internal", NULL, "no reply");
    if (!q->resp) return MHD_NO;
    enum MHD_Result r = MHD_queue_response(q->conn, q->status, q->resp);
    MHD_destroy_response(q->resp);
    q->resp = NULL;
    api_conn_answering(q->conn, 1); /* read in time: no deadline while it is answered */
    return r;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version, const char *upload_data,
                                  size_t *upload_size, void **con_cls)
{
    (void)version;
    api_http_t *h = cls;
    api_req_t *q = *con_cls;
    if (!q) {
        if (!(q = calloc(1, sizeof *q))) return MHD_NO;
        q->srv = h->srv;
        q->conns = h->conns;
        q->conn = conn;
        *con_cls = q;
        if (check_request(q, method, url)) return send_reply(q);
        return MHD_YES;
    }
    if (*upload_size) {
        take_body(q, upload_data, *upload_size);
        *upload_size = 0;
        return MHD_YES;
    }
    if (q->too_big) {
        api_error(q, 413, "payload_too_large", NULL, "the body is larger than %zu bytes",
                  srv_config(q->srv)->max_body);
    } else if (q->route) {
        q->route->fn(q);
    } else {
        api_h_static(q, url);
    }
    return send_reply(q);
}

static void on_completed(void *cls, struct MHD_Connection *conn, void **con_cls,
                         enum MHD_RequestTerminationCode code)
{
    (void)code;
    api_http_t *h = cls;
    api_conn_answering(conn, 0); /* the next request's deadline starts now */
    api_req_t *q = *con_cls;
    if (!q) return;
    if (q->st) srv_db_put(h->srv, q->st);
    if (q->resp) MHD_destroy_response(q->resp);
    free(q->body);
    free(q);
    *con_cls = NULL;
}

/* The address to bind from the configuration. */
static int make_addr(const srv_config_t *cfg, struct sockaddr_storage *ss, err_t *err)
{
    memset(ss, 0, sizeof *ss);
    struct sockaddr_in *a4 = (struct sockaddr_in *)ss;
    struct sockaddr_in6 *a6 = (struct sockaddr_in6 *)ss;
    if (inet_pton(AF_INET, cfg->host, &a4->sin_addr) == 1) {
        a4->sin_family = AF_INET;
        a4->sin_port = htons((uint16_t)cfg->port);
        return 0;
    }
    if (inet_pton(AF_INET6, cfg->host, &a6->sin6_addr) == 1) {
        a6->sin6_family = AF_INET6;
        a6->sin6_port = htons((uint16_t)cfg->port);
        return 0;
    }
    return err_set(err, -EINVAL, "--listen: '%s' is not a numeric IPv4 or IPv6 address", cfg->host);
}

/* Each connection is a descriptor: lifts the soft limit toward the hard one so that
 * --max-connections can be reached (libmicrohttpd's default limit, FD_SETSIZE - 4, was what
 * let about 1020 connections lock everyone out). */
static void raise_fd_limit(const srv_config_t *cfg)
{
    struct rlimit rl;
    rlim_t want = (rlim_t)cfg->max_connections + 256; /* + database, log, camera, spare */
    if (getrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur >= want) return;
    rl.rlim_cur = rl.rlim_max == RLIM_INFINITY || rl.rlim_max > want ? want : rl.rlim_max;
    setrlimit(RLIMIT_NOFILE, &rl);
}

static int http_start(srv_t *srv, void **handle, int *port, err_t *err)
{
    const srv_config_t *cfg = srv_config(srv);
    struct sockaddr_storage ss;
    int ret = make_addr(cfg, &ss, err);
    if (ret) return ret;
    api_http_t *h = calloc(1, sizeof *h);
    if (!h) return err_set(err, -ENOMEM, "out of memory");
    h->srv = srv;
    h->quiesced = MHD_INVALID_SOCKET;
    if (!(h->conns = api_conns_open(cfg->request_timeout_s))) {
        free(h);
        return err_set(err, -ENOMEM, "out of memory starting the connection tracker");
    }
    raise_fd_limit(cfg);
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_AUTO | MHD_ALLOW_SUSPEND_RESUME |
                     MHD_USE_ERROR_LOG | (ss.ss_family == AF_INET6 ? MHD_USE_IPv6 : 0);
    h->d = MHD_start_daemon(
        flags, (uint16_t)cfg->port, NULL, NULL, on_request, h, MHD_OPTION_SOCK_ADDR,
        (struct sockaddr *)&ss, MHD_OPTION_THREAD_POOL_SIZE, (unsigned)cfg->http_threads,
        MHD_OPTION_NOTIFY_COMPLETED, on_completed, h, MHD_OPTION_NOTIFY_CONNECTION,
        api_conns_notify, h->conns, MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)60,
        MHD_OPTION_CONNECTION_LIMIT, (unsigned)cfg->max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, (unsigned)cfg->max_per_client,
        MHD_OPTION_UNESCAPE_CALLBACK, api_unescape_keep_nul, NULL, MHD_OPTION_END);
    if (!h->d) {
        api_conns_close(h->conns);
        free(h);
        return err_set(err, -EADDRINUSE,
                       "cannot listen on %s port %d (in use, or not an "
                       "address of this machine)",
                       cfg->host, cfg->port);
    }
    const union MHD_DaemonInfo *info = MHD_get_daemon_info(h->d, MHD_DAEMON_INFO_BIND_PORT);
    *port = info ? info->port : cfg->port;
    *handle = h;
    return 0;
}

static void http_quiesce(void *handle)
{
    api_http_t *h = handle;
    if (h && h->quiesced == MHD_INVALID_SOCKET) h->quiesced = MHD_quiesce_daemon(h->d);
}

static void http_stop(void *handle)
{
    api_http_t *h = handle;
    if (!h) return;
    api_sse_drain(h->srv, 2000);
    MHD_stop_daemon(h->d);
    api_conns_close(h->conns);
    if (h->quiesced != MHD_INVALID_SOCKET) close(h->quiesced);
    free(h);
}

const srv_frontend_t api_frontend = {http_start, http_quiesce, http_stop};
