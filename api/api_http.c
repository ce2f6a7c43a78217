/* api_http.c: the HTTP server: a libmicrohttpd daemon with a thread pool on the configured
 * address, and the request life cycle. On the first callback of a request (headers only) the
 * route, the method, the token, the content type and a declared body size are checked, so bad
 * requests are refused before their body is read; JSON bodies are then accumulated up to
 * --max-body (a larger chunked body is read and dropped, then refused with 413); the handler runs
 * on the final callback. Connections of event streams are suspended while they wait (api_sse.c),
 * which is why the daemon allows suspend/resume.
 *
 * Access: writes need a write token when --token is given; with --read-token, reads under /api
 * (but /api/health and /api/openapi.json) need a read or write token (server/srv_token.h: only
 * digests are kept, compared in constant time); GET /api/events also takes ?ticket= of
 * POST /api/events/ticket in place of the header (read-only, short-lived: srv_token.h). CORS is off
 * unless --cors-origin names the one origin allowed: then its requests get
 * Access-Control-Allow-Origin and its preflight OPTIONS requests are answered. Every request ends
 * with a line in the request log (api_log.h). */
#include <arpa/inet.h>
#include <errno.h>
#include <stdarg.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include "base/clock.h"

#include "api_calib_cache.h"
#include "api_conn.h"
#include "api_int.h"
#include "api_log.h"
#include "base/thread_sched.h"
#include "server/srv_token.h"

typedef struct api_http {
    srv_t *srv;
    struct MHD_Daemon *d;
    api_conns_t *conns;             /* open connections and their request deadlines */
    api_calib_cache_t *calib_cache; /* replies of current calibrations (api_calib_cache.h) */
    MHD_socket quiesced;            /* the listening socket after quiesce, closed after the stop */
    int log_fd;                     /* the request log (api_log.h), -1 off */
} api_http_t;

/* What the Authorization header's bearer token grants (SRV_TOKEN_*): its SHA-256 digest is
 * compared with every configured one in constant time (srv_token_level). */
static int bearer_level(const srv_config_t *cfg, const char *header)
{
    if (!header || strncasecmp(header, "Bearer ", 7) != 0) return SRV_TOKEN_NONE;
    const char *tok = header + 7;
    while (*tok == ' ')
        tok++;
    return srv_token_level(cfg, tok, strlen(tok));
}

/* Reads that stay open with --read-token: liveness checks and the API's description. */
static int open_read(const char *url)
{
    return strcmp(url, "/api/health") == 0 || strcmp(url, "/api/openapi.json") == 0;
}

/* The request's Origin when CORS is on and it is the allowed one (or any, for "*"), else NULL. */
static const char *cors_origin(api_req_t *q)
{
    const char *allowed = srv_config(q->srv)->cors_origin;
    if (!allowed[0]) return NULL;
    const char *origin = MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND, "Origin");
    if (!origin) return NULL;
    return strcmp(allowed, "*") == 0 || strcmp(allowed, origin) == 0 ? allowed : NULL;
}

/* A CORS preflight (OPTIONS with Access-Control-Request-Method), answered 204 with what the
 * path allows; only when CORS is on. */
static void preflight(api_req_t *q, const char *url)
{
    char allow[64];
    int api = strncmp(url, "/api/", 5) == 0;
    if (api && !api_route_allow(url, allow, sizeof allow)[0]) {
        api_error(q, 404, "not_found", NULL, "no such resource: %s", url);
        return;
    }
    if (!(q->resp = MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT))) return;
    q->status = 204;
    q->resp_bytes = 0;
    if (!api) snprintf(allow, sizeof allow, "GET, HEAD");
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_ALLOW, allow);
    if (cors_origin(q)) {
        MHD_add_response_header(q->resp, "Access-Control-Allow-Methods", allow);
        MHD_add_response_header(q->resp, "Access-Control-Allow-Headers",
                                "Authorization, Content-Type");
        MHD_add_response_header(q->resp, "Access-Control-Max-Age", "600");
    }
}

/* libmicrohttpd's unescape of the URL path and of query arguments, except that %00 stays as
 * the three characters "%00": decoded, it would end the C string that handlers see, so that
 * "/api/scans/1%00junk" would be scan 1 and "/index.html%00.png" index.html. Kept literal, such
 * a path or value is simply not a valid one (404 / 400). Hand-written because MHD's own
 * MHD_http_unescape decodes every %XX. */
static int hex_digit(char c)
{
    return c >= '0' && c <= '9'   ? c - '0'
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

/* The request's own limits: libmicrohttpd answers a request line or header
 * fields that overflow its per-connection buffer (MHD_OPTION_CONNECTION_MEMORY_LIMIT) itself,
 * with 414 or 431 and a short HTML body that no option of 0.9.75 replaces. So the buffer is
 * made larger than the limits ipsd enforces here: a target over API_MAX_TARGET or header fields
 * over API_MAX_HEADERS get the JSON error, and only a request beyond the buffer still gets
 * libmicrohttpd's answer (docs/api.md). 8 KiB and 16 KiB are nginx's and Apache's defaults for a
 * request line and more than any client of ipsd sends; the buffer bounds a connection's memory
 * (docs/operations.md: times --max-connections). */
#define API_MAX_TARGET (8u << 10)
#define API_MAX_HEADERS (16u << 10)
#define API_CONN_MEMORY (64u << 10)

/* MHD_get_connection_values' iterator: adds a field's "key: value\r\n" (or "key=value&") size. */
static enum MHD_Result add_field_size(void *cls, enum MHD_ValueKind kind, const char *key,
                                      const char *value)
{
    (void)kind;
    *(size_t *)cls += strlen(key) + (value ? strlen(value) : 0) + 4;
    return MHD_YES;
}

/* Refuses (414 / 431, the JSON error) a request over the limits above; 0 when within them. The
 * target is measured decoded (path and query arguments), a lower bound of the bytes sent. */
static int check_size(api_req_t *q, const char *url)
{
    size_t target = strlen(url), fields = 0;
    MHD_get_connection_values(q->conn, MHD_GET_ARGUMENT_KIND, add_field_size, &target);
    if (target > API_MAX_TARGET) {
        api_error(q, 414, "uri_too_long", NULL, "the request target is longer than %u bytes",
                  API_MAX_TARGET);
        return -1;
    }
    MHD_get_connection_values(q->conn, MHD_HEADER_KIND, add_field_size, &fields);
    if (fields > API_MAX_HEADERS) {
        api_error(q, 431, "header_fields_too_large",
                  NULL, "the request's header fields are larger than %u bytes", API_MAX_HEADERS);
        return -1;
    }
    return 0;
}

/* The checks of the first callback; replies and returns -1 to refuse the request. */
static int check_request(api_req_t *q, const char *method, const char *url)
{
    const srv_config_t *cfg = srv_config(q->srv);
    int path_known = 0, write = strcmp(method, "GET") && strcmp(method, "HEAD");
    if (check_size(q, url)) return -1;
    if (cfg->cors_origin[0] && strcmp(method, "OPTIONS") == 0 &&
        MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND, "Access-Control-Request-Method")) {
        preflight(q, url); /* before the token: a preflight never carries one */
        return -1;
    }
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
    /* what the request needs and what its token grants (no tokens configured: all open) */
    int need = SRV_TOKEN_NONE, computes = write && api_route_computes_only(q->route);
    if (computes) write = 0; /* POST /api/jitter, /api/events/ticket */
    if (write)
        need = SRV_TOKEN_WRITE;
    else if (cfg->reads_closed && !open_read(url))
        need = SRV_TOKEN_READ;
    /* jitter photometry takes an HTTP thread for up to a second: never open to anyone when ipsd
     * has tokens. With reads open there is no read token, so it takes a write token then */
    if (computes && need == SRV_TOKEN_NONE && q->route->fn == api_h_jitter)
        need = SRV_TOKEN_WRITE;
    const char *auth =
        MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_AUTHORIZATION);
    int have = need && cfg->n_tokens ? bearer_level(cfg, auth) : need;
    if (have < need && need == SRV_TOKEN_READ && !auth && q->route->fn == api_h_events &&
        srv_token_ticket_check(
            MHD_lookup_connection_value(q->conn, MHD_GET_ARGUMENT_KIND, "ticket"),
            (long long)clock_mono_ms()))
        have = SRV_TOKEN_READ; /* a browser's EventSource: the ticket in place of the header */
    if (have < need && have == SRV_TOKEN_NONE) {
        api_error(q, 401, "unauthorized", NULL, "%s %s needs 'Authorization: Bearer <token>'%s",
                  method, url, need == SRV_TOKEN_READ ? " (a read or write token)" : "");
        if (q->resp) MHD_add_response_header(q->resp, MHD_HTTP_HEADER_WWW_AUTHENTICATE, "Bearer");
        return -1;
    }
    if (have < need) {
        api_error(q, 403, "forbidden", NULL, "%s %s needs a write token; this one may only read",
                  method, url);
        return -1;
    }
    if (write && srv_stopping(q->srv)) {
        api_error(q, 503, "shutting_down", NULL, "ipsd is shutting down");
        return -1;
    }
    if (q->route->json_body == 1 && !is_json_type(MHD_lookup_connection_value(
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
    const char *origin = cors_origin(q);
    if (origin) {
        MHD_add_response_header(q->resp, "Access-Control-Allow-Origin", origin);
        MHD_add_response_header(q->resp, "Vary", "Origin");
    }
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
    static _Thread_local int sched_set; /* this pool thread's nice and slice, once */
    if (!sched_set) {
        sched_set = 1;
        const srv_config_t *cfg = srv_config(h->srv);
        int slice_us = cfg->http_slice_us, nice = cfg->http_nice, ret = 0;
        if ((slice_us || nice) &&
            (ret = thread_sched_set(nice, slice_us, THREAD_SCHED_NORMAL)) == -EPERM && nice < 0) {
            fprintf(stderr, "ipsd: HTTP thread: nice %d refused (needs CAP_SYS_NICE or "
                    "RLIMIT_NICE >= %d); at nice 0\n", nice, 20 - nice);
            ret = slice_us ? thread_sched_set(0, slice_us, THREAD_SCHED_NORMAL) : 0;
        }
        if (ret && ret != -EPERM)
            fprintf(stderr, "ipsd: HTTP thread: the kernel refused a %d us slice\n", slice_us);
    }
    if (!q) {
        if (!(q = calloc(1, sizeof *q))) return MHD_NO;
        q->srv = h->srv;
        q->conns = h->conns;
        q->calib_cache = h->calib_cache;
        q->conn = conn;
        q->resp_bytes = -1;
        clock_gettime(CLOCK_MONOTONIC, &q->t0);
        if (h->log_fd >= 0) { /* the request's text may be gone by its completion: a copy */
            char m[24], p[600];
            api_log_escape(method, m, sizeof m);
            api_log_escape(url, p, sizeof p);
            q->log_method = strdup(m);
            q->log_path = strdup(p);
        }
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
    if (h->log_fd >= 0)
        api_log_request(h->log_fd, conn, q->log_method, q->log_path, q->status, q->resp_bytes,
                        &q->t0, code != MHD_REQUEST_TERMINATED_COMPLETED_OK);
    if (q->st) srv_db_put(h->srv, q->st);
    if (q->resp) MHD_destroy_response(q->resp);
    free(q->log_method);
    free(q->log_path);
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

/* libmicrohttpd's error log (MHD_OPTION_EXTERNAL_LOGGER): to stderr with ipsd's prefix, except
 * the reports of a client that went away mid-reply ("Failed to send ... The socket is no longer
 * available for sending" when a dashboard tab with an event stream closes): a closed tab is
 * normal, and a log full of them hides what matters. */
static void http_log(void *cls, const char *fmt, va_list ap)
{
    (void)cls;
    char line[512];
    vsnprintf(line, sizeof line, fmt, ap);
    if (strncmp(line, "Failed to send", 14) == 0 &&
        (strstr(line, "no longer available") || strstr(line, "reset by peer") ||
         strstr(line, "Broken pipe")))
        return;
    size_t n = strlen(line);
    while (n && line[n - 1] == '\n')
        line[--n] = 0;
    fprintf(stderr, "ipsd: http: %s\n", line);
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
    if ((ret = api_log_open(cfg->access_log, &h->log_fd, err))) {
        free(h);
        return ret;
    }
    if (!(h->conns = api_conns_open(cfg->request_timeout_s))) {
        api_log_close(h->log_fd);
        free(h);
        return err_set(err, -ENOMEM, "out of memory starting the connection tracker");
    }
    /* 4096 pixels, 32 MiB: a sensor's worth of typical (r <= 8, ~4 KB) maps */
    if (!(h->calib_cache = api_calib_cache_new(4096, (size_t)32 << 20))) {
        api_conns_close(h->conns);
        api_log_close(h->log_fd);
        free(h);
        return err_set(err, -ENOMEM, "out of memory starting the calibration cache");
    }
    raise_fd_limit(cfg);
    /* poll(), not epoll (MHD_USE_AUTO's choice on Linux): MHD_quiesce_daemon on an epoll thread
     * pool races the pool threads over removing the listening socket from their epoll sets, and
     * the loser's epoll_ctl (ENOENT) ends in MHD_PANIC, an abort at SIGTERM (libmicrohttpd
     * 0.9.75; docs/server.md, "Threads"). poll() is stateless: a quiesced pool thread just stops
     * adding the socket, told by its inter-thread channel (MHD_USE_ITC). */
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_POLL | MHD_USE_ITC |
                     MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG |
                     (ss.ss_family == AF_INET6 ? MHD_USE_IPv6 : 0);
    h->d = MHD_start_daemon(
        flags, (uint16_t)cfg->port, NULL, NULL, on_request, h,
        /* the logger must come first, or MHD logs the options before it on its own */
        MHD_OPTION_EXTERNAL_LOGGER, http_log, NULL, MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss,
        MHD_OPTION_THREAD_POOL_SIZE, (unsigned)cfg->http_threads, MHD_OPTION_NOTIFY_COMPLETED,
        on_completed, h, MHD_OPTION_NOTIFY_CONNECTION, api_conns_notify, h->conns,
        MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)60, MHD_OPTION_CONNECTION_MEMORY_LIMIT,
        (size_t)API_CONN_MEMORY, MHD_OPTION_CONNECTION_LIMIT,
        (unsigned)cfg->max_connections, MHD_OPTION_PER_IP_CONNECTION_LIMIT,
        (unsigned)cfg->max_per_client, MHD_OPTION_UNESCAPE_CALLBACK, api_unescape_keep_nul, NULL,
        MHD_OPTION_END);
    if (!h->d) {
        api_conns_close(h->conns);
        api_calib_cache_free(h->calib_cache);
        api_log_close(h->log_fd);
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
    api_calib_cache_free(h->calib_cache);
    if (h->quiesced != MHD_INVALID_SOCKET) close(h->quiesced);
    api_log_close(h->log_fd);
    free(h);
}

/* SIGHUP: the request log's file reopened by name (api_log_reopen); stderr is left alone. */
static void http_reopen_logs(void *handle)
{
    api_http_t *h = handle;
    err_t err = {{0}};
    if (!h || h->log_fd <= STDERR_FILENO) return;
    if (api_log_reopen(srv_config(h->srv)->access_log, h->log_fd, &err))
        fprintf(stderr, "ipsd: SIGHUP: %s (still writing to the old file)\n", err.msg);
    else
        fprintf(stderr, "ipsd: SIGHUP: reopened the request log %s\n",
                srv_config(h->srv)->access_log);
}

const srv_frontend_t api_frontend = {http_start, http_quiesce, http_stop, http_reopen_logs};
