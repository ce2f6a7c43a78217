/* srv_config.c: ipsd's command line (see srv_config.h). getopt_long does the parsing; every value
 * is checked here so that the daemon never starts half-configured. */
#include "server/srv_config.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "base/opts.h"
#include "base/parse.h"

#ifndef IPSD_WEB_DIR
#define IPSD_WEB_DIR "web"
#endif

static const char usage[] =
    "usage: ipsd [options]\n"
    "  --listen ADDR:PORT   address to serve HTTP on (default 127.0.0.1:8080; [::1]:PORT for\n"
    "                       IPv6; port 0 picks a free port)\n"
    "  --db FILE            SQLite database (default var/ipsd.db; its directory must exist)\n"
    "  --bench sim|libcamera  the instrument: the simulated bench (default) or a libcamera\n"
    "                       camera (fails at start when none is found)\n"
    "  --workers N          fit worker threads (default 2)\n"
    "  --http-threads N     HTTP thread pool size (default 2)\n"
    "  --token FILE         writes (POST, DELETE) need 'Authorization: Bearer TOKEN', TOKEN the\n"
    "                       file's content without surrounding whitespace\n"
    "  --web DIR            static files of the dashboard (default the source tree's web/)\n"
    "  --max-body BYTES     largest request body (default 4194304); larger ones get 413\n"
    "  --max-scan-bytes B   largest scan accepted, in bytes of frames it would store (default\n"
    "                       1073741824); larger ones get 422\n"
    "  --max-connections N  open HTTP connections at most (default 4096)\n"
    "  --max-per-client N   open connections from one address at most (default 128)\n"
    "  --request-timeout S  a request's headers and body must arrive within S seconds of the\n"
    "                       connection's start or its previous request's end (default 60)\n"
    "  --max-subscribers N  open event streams at most (default 256); more get 503\n"
    "  --port-file FILE     write the bound port number to FILE once listening\n"
    "  --heartbeat S        seconds between event-stream heartbeats (default 15)\n"
    "  --max-attempts N     a job interrupted by N crashes fails instead of running again (3)\n"
    "  --camera-timeout S   a camera that delivers no frame within S seconds fails the scan\n"
    "                       (default 0: the camera's own, the exposure time + 5 s)\n"
    "SIGINT / SIGTERM stop gracefully: running scans resume at the next start.\n";

const char *srv_config_usage(void)
{
    return usage;
}

srv_config_t srv_config_default(void)
{
    srv_config_t c = {.port = 8080,
                      .workers = 2,
                      .http_threads = 2,
                      .max_body = 4u << 20,
                      .max_scan_bytes = (double)(1u << 30),
                      .max_connections = 4096,
                      .max_per_client = 128,
                      .request_timeout_s = 60,
                      .max_subscribers = 256,
                      .heartbeat_s = 15,
                      .max_attempts = 3};
    snprintf(c.host, sizeof c.host, "127.0.0.1");
    snprintf(c.db_path, sizeof c.db_path, "var/ipsd.db");
    snprintf(c.bench, sizeof c.bench, "sim");
    struct stat sb;
    snprintf(c.web_dir, sizeof c.web_dir, "%s",
             stat(IPSD_WEB_DIR, &sb) == 0 && S_ISDIR(sb.st_mode) ? IPSD_WEB_DIR : "web");
    return c;
}

void srv_config_free(srv_config_t *cfg)
{
    if (!cfg) return;
    free(cfg->token);
    cfg->token = NULL;
}

/* A whole decimal integer in lo..hi. */
static int parse_long(const char *text, long long lo, long long hi, long long *v)
{
    return parse_ll(text, v) || *v < lo || *v > hi ? -EINVAL : 0;
}

/* "HOST:PORT" or "[V6]:PORT" into cfg->host / cfg->port. */
static int parse_listen(const char *text, srv_config_t *cfg, err_t *err)
{
    const char *colon = strrchr(text, ':'), *host = text;
    size_t hlen = colon ? (size_t)(colon - text) : 0;
    if (hlen >= 2 && text[0] == '[' && text[hlen - 1] == ']') {
        host++;
        hlen -= 2;
    }
    long long port;
    if (!colon || hlen == 0 || hlen >= sizeof cfg->host || parse_long(colon + 1, 0, 65535, &port))
        return err_set(err, -EINVAL, "--listen: need ADDR:PORT with a port 0..65535 (got '%s')",
                       text);
    memcpy(cfg->host, host, hlen);
    cfg->host[hlen] = 0;
    cfg->port = (int)port;
    return 0;
}

/* Reads the token file: its content with surrounding whitespace removed, not empty. */
static int read_token(const char *path, srv_config_t *cfg, err_t *err)
{
    FILE *f = fopen(path, "r");
    if (!f) return err_set(err, -errno, "--token: cannot read %s: %s", path, strerror(errno));
    char buf[1024];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    int more = fgetc(f) != EOF;
    fclose(f);
    if (more) return err_set(err, -EINVAL, "--token: %s is longer than 1023 bytes", path);
    buf[n] = 0;
    char *s = buf, *e = buf + n;
    while (*s && strchr(" \t\r\n", *s))
        s++;
    while (e > s && strchr(" \t\r\n", e[-1]))
        *--e = 0;
    if (!*s) return err_set(err, -EINVAL, "--token: %s is empty", path);
    for (char *p = s; *p; p++)
        if ((unsigned char)*p < 0x21 || (unsigned char)*p > 0x7e)
            return err_set(err, -EINVAL,
                           "--token: %s holds whitespace or non-ASCII inside the "
                           "token",
                           path);
    free(cfg->token);
    cfg->token = strdup(s);
    return cfg->token ? 0 : err_set(err, -ENOMEM, "out of memory");
}

/* A path option into a fixed buffer. */
static int copy_path(const char *opt, const char *text, char *dst, size_t n, err_t *err)
{
    if (!*text || strlen(text) >= n) return err_set(err, -EINVAL, "--%s: bad path", opt);
    memcpy(dst, text, strlen(text) + 1);
    return 0;
}

enum {
    O_LISTEN = 256,
    O_DB,
    O_BENCH,
    O_WORKERS,
    O_HTTP,
    O_TOKEN,
    O_WEB,
    O_MAXBODY,
    O_MAXSCAN,
    O_MAXCONN,
    O_PERCLIENT,
    O_REQTIMEOUT,
    O_MAXSUBS,
    O_PORTFILE,
    O_HEARTBEAT,
    O_ATTEMPTS,
    O_CAMTIMEOUT,
    O_HELP
};

static const struct option opts[] = {
    {"listen", required_argument, NULL, O_LISTEN},
    {"db", required_argument, NULL, O_DB},
    {"bench", required_argument, NULL, O_BENCH},
    {"workers", required_argument, NULL, O_WORKERS},
    {"http-threads", required_argument, NULL, O_HTTP},
    {"token", required_argument, NULL, O_TOKEN},
    {"web", required_argument, NULL, O_WEB},
    {"max-body", required_argument, NULL, O_MAXBODY},
    {"max-scan-bytes", required_argument, NULL, O_MAXSCAN},
    {"max-connections", required_argument, NULL, O_MAXCONN},
    {"max-per-client", required_argument, NULL, O_PERCLIENT},
    {"request-timeout", required_argument, NULL, O_REQTIMEOUT},
    {"max-subscribers", required_argument, NULL, O_MAXSUBS},
    {"port-file", required_argument, NULL, O_PORTFILE},
    {"heartbeat", required_argument, NULL, O_HEARTBEAT},
    {"max-attempts", required_argument, NULL, O_ATTEMPTS},
    {"camera-timeout", required_argument, NULL, O_CAMTIMEOUT},
    {"help", no_argument, NULL, O_HELP},
    {NULL, 0, NULL, 0},
};

/* One option with its value (opts_fn). */
static int one_option(int c, const char *arg, void *user, err_t *err)
{
    srv_config_t *cfg = user;
    long long v;
    switch (c) {
    case O_LISTEN:
        return parse_listen(arg, cfg, err);
    case O_DB:
        return copy_path("db", arg, cfg->db_path, sizeof cfg->db_path, err);
    case O_WEB:
        return copy_path("web", arg, cfg->web_dir, sizeof cfg->web_dir, err);
    case O_PORTFILE:
        return copy_path("port-file", arg, cfg->port_file, sizeof cfg->port_file, err);
    case O_TOKEN:
        return read_token(arg, cfg, err);
    case O_BENCH:
        if (strcmp(arg, "sim") && strcmp(arg, "libcamera"))
            return err_set(err, -EINVAL, "--bench must be sim or libcamera (got '%s')", arg);
        snprintf(cfg->bench, sizeof cfg->bench, "%s", arg);
        return 0;
    case O_WORKERS:
    case O_HTTP:
        if (parse_long(arg, 1, 64, &v))
            return err_set(err, -EINVAL, "--%s must be 1..64 (got '%s')",
                           c == O_WORKERS ? "workers" : "http-threads", arg);
        *(c == O_WORKERS ? &cfg->workers : &cfg->http_threads) = (int)v;
        return 0;
    case O_MAXBODY:
        if (parse_long(arg, 1024, 1LL << 30, &v))
            return err_set(err, -EINVAL, "--max-body must be 1024..1073741824 bytes (got '%s')",
                           arg);
        cfg->max_body = (size_t)v;
        return 0;
    case O_MAXCONN:
    case O_PERCLIENT:
    case O_REQTIMEOUT:
    case O_MAXSUBS: {
        static const struct {
            int opt;
            const char *name;
            long long lo, hi;
        } lim[] = {{O_MAXCONN, "max-connections", 16, 1000000},
                   {O_PERCLIENT, "max-per-client", 1, 1000000},
                   {O_REQTIMEOUT, "request-timeout", 1, 86400},
                   {O_MAXSUBS, "max-subscribers", 1, 1000000}};
        size_t i = 0;
        while (lim[i].opt != c)
            i++;
        if (parse_long(arg, lim[i].lo, lim[i].hi, &v))
            return err_set(err, -EINVAL, "--%s must be %lld..%lld (got '%s')", lim[i].name,
                           lim[i].lo, lim[i].hi, arg);
        int *field[] = {&cfg->max_connections, &cfg->max_per_client, &cfg->request_timeout_s,
                        &cfg->max_subscribers};
        *field[i] = (int)v;
        return 0;
    }
    case O_MAXSCAN:
        if (parse_long(arg, 1LL << 20, 1LL << 50, &v))
            return err_set(err, -EINVAL,
                           "--max-scan-bytes must be 1048576..1125899906842624 (got '%s')", arg);
        cfg->max_scan_bytes = (double)v;
        return 0;
    case O_HEARTBEAT:
    case O_ATTEMPTS:
        if (parse_long(arg, 1, 3600, &v))
            return err_set(err, -EINVAL, "--%s must be 1..3600 (got '%s')",
                           c == O_HEARTBEAT ? "heartbeat" : "max-attempts", arg);
        *(c == O_HEARTBEAT ? &cfg->heartbeat_s : &cfg->max_attempts) = (int)v;
        return 0;
    case O_CAMTIMEOUT: {
        double t;
        if (parse_double(arg, &t) || !(t >= 0 && t <= 3600))
            return err_set(err, -EINVAL, "--camera-timeout must be 0..3600 seconds (got '%s')",
                           arg);
        cfg->camera_timeout_s = t;
        return 0;
    }
    default:
        return err_set(err, -EINVAL, "unknown option");
    }
}

int srv_config_parse(int argc, char **argv, srv_config_t *cfg, err_t *err)
{
    int first, ret = opts_parse(argc, argv, "", opts, O_HELP, "ipsd --help", one_option, cfg,
                                &first, err);
    if (ret == 1) fputs(usage, stdout);
    if (ret) return ret;
    if (first < argc) return err_set(err, -EINVAL, "unexpected argument '%s'", argv[first]);
    return 0;
}
