/* srv_config.c: ipsd's command line (see srv_config.h). getopt_long does the parsing; every value
 * is checked here so that the daemon never starts half-configured. */
#include "server/srv_config.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/opts.h"
#include "base/parse.h"
#include "base/thread_sched.h"
#include "instrument/stage.h"
#include "server/srv_token.h"
#include "storage/storage.h" /* storage_map_parse */

#ifndef IPSD_WEB_DIR
#define IPSD_WEB_DIR "web"
#endif

static const char usage[] =
    "usage: ipsd [options]\n"
    "  --listen ADDR:PORT   address to serve HTTP on (default 127.0.0.1:8080; [::1]:PORT for\n"
    "                       IPv6; port 0 picks a free port)\n"
    "  --db FILE|URI        SQLite database file (default var/ipsd.db; its directory must exist),\n"
    "                       or a PostgreSQL database several benches share:\n"
    "                       postgresql://USER@HOST[:PORT]/DB (its password from PGPASSFILE or\n"
    "                       ~/.pgpass, never in the URI)\n"
    "  --bench-name NAME    this bench's name on a shared database: its scan jobs are claimed\n"
    "                       only by the ipsd of that name (default: the host name)\n"
    "  --db-copy FROM TO    copies every row of database FROM (e.g. a bench's SQLite file) into\n"
    "                       TO (e.g. the lab's postgresql:// database) under TO's ids, and\n"
    "                       exits; run again, it copies only what is new. FROM's scan jobs\n"
    "                       join --bench-name's bench\n"
    "  --lease S            on a shared database, a job whose ipsd has not reported for S\n"
    "                       seconds is queued again for another (default 30)\n"
    "  --bench BENCH        the instrument: sim (the simulated bench, default), libcamera (a\n"
    "                       V4L2 sensor) or aravis (a GenICam camera: GigE Vision, USB3\n"
    "                       Vision), the first camera found, or libcamera:ID / aravis:ID for\n"
    "                       the camera of that id (see --list-cameras); fails at start when\n"
    "                       the camera is not found; none: no instrument, an ipsd that only\n"
    "                       fits (a fit worker on a shared database)\n"
    "  --list-cameras       prints the cameras every camera backend finds, one a line\n"
    "                       (BACKEND:ID, vendor, model, serial), and exits\n"
    "  --stage STAGE        the motion stage the bench's camera works with: sim (default) or a\n"
    "                       PI GCS 2.0 controller, gcs:tcp://HOST:PORT[?OPTIONS] or\n"
    "                       gcs:serial:/dev/DEVICE[?OPTIONS] (OPTIONS: unit=mm|um, axes=A,B[,C],\n"
    "                       baud=N, timeout=S, move_timeout=S, poll_ms=N, reference=0|1; see\n"
    "                       docs/operations.md); fails at start when it does not answer\n"
    "  --workers N          fit worker threads (default 2)\n"
    "  --http-threads N     HTTP thread pool size (default 2)\n"
    "  --fit-nice N         the fit workers' nice value 0..19 (default 10): fits yield the CPU\n"
    "                       to the HTTP threads (see docs/operations.md)\n"
    "  --fit-sched POLICY   the fit workers' scheduling policy: normal (SCHED_OTHER at\n"
    "                       --fit-nice), batch (SCHED_BATCH) or idle (SCHED_IDLE: they run only\n"
    "                       when no other thread wants the CPU); default normal\n"
    "  --fit-batch          the same as --fit-sched batch\n"
    "  --http-nice N        the HTTP threads' nice value -20..19 (default 0); below 0 they\n"
    "                       preempt other processes' work, which needs CAP_SYS_NICE or an\n"
    "                       RLIMIT_NICE of 20 - N (systemd: LimitNICE=); refused: logged, 0\n"
    "  --http-slice-us N    the HTTP threads' time slice in microseconds, 100..100000, or 0 for\n"
    "                       the kernel's (Linux 6.12+; a short slice preempts busy threads on\n"
    "                       wakeup; default 0)\n"
    "  --token FILE         writes (POST, DELETE) need 'Authorization: Bearer TOKEN', TOKEN one\n"
    "                       of the file's lines: a token, or sha256:HEX of one (see "
    "--hash-token);\n"
    "                       blank and # lines skipped; may be given more than once\n"
    "  --read-token FILE    reads under /api (but /api/health and /api/openapi.json) need a read\n"
    "                       token of FILE or a write token (needs --token); default: reads open\n"
    "  --hash-token         print the sha256:HEX line of the token read from stdin, and exit\n"
    "  --access-log FILE    one line per request (time, client, method, path, status, bytes,\n"
    "                       ms) appended to FILE; '-' stderr (default), 'off' none\n"
    "  --cors-origin ORIGIN allow cross-origin requests from ORIGIN (e.g. "
    "https://lab.example:8443,\n"
    "                       or *); default: no CORS headers, browsers refuse other origins\n"
    "  --backup-dir DIR     POST /api/backup writes online backups of the database into DIR\n"
    "                       (default: none, the endpoint answers 409)\n"
    "  --backup OUT         back the database (--db) up to the new file OUT while any ipsd may\n"
    "                       keep running on it, check it, print what was written, and exit\n"
    "  --web DIR            static files of the dashboard (default the source tree's web/)\n"
    "  --max-body BYTES     largest request body (default 4194304); larger ones get 413\n"
    "  --max-reply-bytes B  largest reply one request may build, in bytes (default 67108864);\n"
    "                       a larger one gets 413 naming how to ask for less\n"
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
    "  --max-fit-points N   largest uploaded scan file a fit takes, in points (default 10000);\n"
    "                       more get 413\n"
    "  --max-fit-r N        largest r_max / ftest_r / geometry_r a fit may ask for, 1..32\n"
    "                       (default 32); more get 422\n"
    "  --max-jitter-evals N largest Airy integration a jitter request may need, estimated in\n"
    "                       radial evaluations (default 40000000, ~1 s); more get 422\n"
    "  --camera-timeout S   a camera that delivers no frame within S seconds fails the scan\n"
    "                       (default 0: the camera's own, the exposure time + 5 s)\n"
    "  --calibration-map M  the map a fit stores as its calibration when its request names\n"
    "                       none (the automatic fit of every scan, re-fits): kriged (default:\n"
    "                       the kriged map, closest to the truth; see docs/numerics.md \"The\n"
    "                       kriged map\"), recommended (the paper's recommended r's own) or\n"
    "                       shrunk\n"
    "SIGINT / SIGTERM stop gracefully: running scans resume at the next start.\n";

const char *srv_config_usage(void)
{
    return usage;
}

/* A password in a connection URI: "user:secret@" or a password= parameter. */
static int uri_has_password(const char *uri)
{
    const char *auth = strstr(uri, "://");
    if (auth) {
        auth += 3;
        size_t n = strcspn(auth, "@/?");
        if (auth[n] == '@' && memchr(auth, ':', n)) return 1;
    }
    return strstr(uri, "?password=") || strstr(uri, "&password=");
}

/* --bench-name: 1 to 63 letters, digits, '.', '_' or '-' (it names jobs in the database). */
static int bench_name(const char *arg, srv_config_t *cfg, err_t *err)
{
    size_t n = strlen(arg);
    if (n == 0 || n >= sizeof cfg->bench_name ||
        strspn(arg, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-") != n)
        return err_set(err, -EINVAL,
                       "--bench-name must be 1 to 63 letters, digits, '.', '_' or '-' (got '%s')",
                       arg);
    snprintf(cfg->bench_name, sizeof cfg->bench_name, "%s", arg);
    return 0;
}

srv_config_t srv_config_default(void)
{
    srv_config_t c = {.port = 8080,
                      .workers = 2,
                      .http_threads = 2,
                      .fit_nice = 10,
                      .max_body = 4u << 20,
                      .max_reply_bytes = 64u << 20,
                      .max_scan_bytes = (double)(1u << 30),
                      .max_connections = 4096,
                      .max_per_client = 128,
                      .request_timeout_s = 60,
                      .max_subscribers = 256,
                      .heartbeat_s = 15,
                      .max_attempts = 3,
                      .max_fit_points = 10000,
                      .max_fit_r = 32,
                      .max_jitter_evals = 40000000,
                      .lease_s = 30,
                      .calibration_map = STORAGE_MAP_KRIGED};
    snprintf(c.host, sizeof c.host, "127.0.0.1");
    snprintf(c.db_path, sizeof c.db_path, "var/ipsd.db");
    snprintf(c.bench, sizeof c.bench, "sim");
    snprintf(c.stage, sizeof c.stage, "sim");
    char host[256] = "";
    err_t ignored;
    if (gethostname(host, sizeof host - 1) != 0 || bench_name(host, &c, &ignored) != 0)
        snprintf(c.bench_name, sizeof c.bench_name, "bench");
    struct stat sb;
    snprintf(c.web_dir, sizeof c.web_dir, "%s",
             stat(IPSD_WEB_DIR, &sb) == 0 && S_ISDIR(sb.st_mode) ? IPSD_WEB_DIR : "web");
    return c;
}

void srv_config_free(srv_config_t *cfg)
{
    if (!cfg) return;
    explicit_bzero(cfg->tokens, sizeof cfg->tokens);
    cfg->n_tokens = 0;
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

/* A path option into a fixed buffer ("" only for --access-log -, stderr). */
static int copy_path(const char *opt, const char *text, char *dst, size_t n, err_t *err)
{
    if ((!*text && strcmp(opt, "access-log")) || strlen(text) >= n)
        return err_set(err, -EINVAL, "--%s: bad path", opt);
    memcpy(dst, text, strlen(text) + 1);
    return 0;
}

/* --cors-origin: "*" or an origin as browsers send it, SCHEME://HOST[:PORT] without a path;
 * it is echoed in a header, so only printable ASCII without spaces or commas. */
static int parse_origin(const char *text, srv_config_t *cfg, err_t *err)
{
    const char *sep = strstr(text, "://");
    int ok = strlen(text) < sizeof cfg->cors_origin &&
             (strcmp(text, "*") == 0 || (sep && sep > text && sep[3] && !strchr(sep + 3, '/')));
    for (const char *p = text; ok && *p; p++)
        ok = (unsigned char)*p > 0x20 && (unsigned char)*p < 0x7f && *p != ',';
    if (!ok)
        return err_set(err, -EINVAL,
                       "--cors-origin: need * or SCHEME://HOST[:PORT] without a path (got '%s')",
                       text);
    snprintf(cfg->cors_origin, sizeof cfg->cors_origin, "%s", text);
    return 0;
}

enum {
    O_LISTEN = 256,
    O_DB,
    O_BENCH,
    O_STAGE,
    O_WORKERS,
    O_HTTP,
    O_FITNICE,
    O_FITBATCH,
    O_FITSCHED,
    O_HTTPSLICE,
    O_HTTPNICE,
    O_TOKEN,
    O_READTOKEN,
    O_HASHTOKEN,
    O_ACCESSLOG,
    O_CORS,
    O_BACKUPDIR,
    O_BACKUP,
    O_LISTCAMERAS,
    O_WEB,
    O_MAXBODY,
    O_MAXSCAN,
    O_MAXREPLY,
    O_MAXCONN,
    O_PERCLIENT,
    O_REQTIMEOUT,
    O_MAXSUBS,
    O_MAXFITPTS,
    O_MAXFITR,
    O_MAXJITTER,
    O_PORTFILE,
    O_HEARTBEAT,
    O_ATTEMPTS,
    O_CAMTIMEOUT,
    O_CALIBMAP,
    O_BENCHNAME,
    O_LEASE,
    O_DBCOPY,
    O_HELP
};

static const struct option opts[] = {
    {"listen", required_argument, NULL, O_LISTEN},
    {"db", required_argument, NULL, O_DB},
    {"bench", required_argument, NULL, O_BENCH},
    {"stage", required_argument, NULL, O_STAGE},
    {"workers", required_argument, NULL, O_WORKERS},
    {"http-threads", required_argument, NULL, O_HTTP},
    {"fit-nice", required_argument, NULL, O_FITNICE},
    {"fit-batch", no_argument, NULL, O_FITBATCH},
    {"fit-sched", required_argument, NULL, O_FITSCHED},
    {"http-slice-us", required_argument, NULL, O_HTTPSLICE},
    {"http-nice", required_argument, NULL, O_HTTPNICE},
    {"token", required_argument, NULL, O_TOKEN},
    {"read-token", required_argument, NULL, O_READTOKEN},
    {"hash-token", no_argument, NULL, O_HASHTOKEN},
    {"access-log", required_argument, NULL, O_ACCESSLOG},
    {"cors-origin", required_argument, NULL, O_CORS},
    {"backup-dir", required_argument, NULL, O_BACKUPDIR},
    {"backup", required_argument, NULL, O_BACKUP},
    {"list-cameras", no_argument, NULL, O_LISTCAMERAS},
    {"web", required_argument, NULL, O_WEB},
    {"max-body", required_argument, NULL, O_MAXBODY},
    {"max-scan-bytes", required_argument, NULL, O_MAXSCAN},
    {"max-reply-bytes", required_argument, NULL, O_MAXREPLY},
    {"max-connections", required_argument, NULL, O_MAXCONN},
    {"max-per-client", required_argument, NULL, O_PERCLIENT},
    {"request-timeout", required_argument, NULL, O_REQTIMEOUT},
    {"max-subscribers", required_argument, NULL, O_MAXSUBS},
    {"max-fit-points", required_argument, NULL, O_MAXFITPTS},
    {"max-fit-r", required_argument, NULL, O_MAXFITR},
    {"max-jitter-evals", required_argument, NULL, O_MAXJITTER},
    {"port-file", required_argument, NULL, O_PORTFILE},
    {"heartbeat", required_argument, NULL, O_HEARTBEAT},
    {"max-attempts", required_argument, NULL, O_ATTEMPTS},
    {"camera-timeout", required_argument, NULL, O_CAMTIMEOUT},
    {"calibration-map", required_argument, NULL, O_CALIBMAP},
    {"bench-name", required_argument, NULL, O_BENCHNAME},
    {"lease", required_argument, NULL, O_LEASE},
    {"db-copy", required_argument, NULL, O_DBCOPY},
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
        if (storage_is_postgres(arg) && uri_has_password(arg))
            return err_set(err, -EINVAL,
                           "--db: a password in the URI would show in the process list and the "
                           "logs; put it in PGPASSFILE or ~/.pgpass");
        return copy_path("db", arg, cfg->db_path, sizeof cfg->db_path, err);
    case O_BENCHNAME:
        return bench_name(arg, cfg, err);
    case O_DBCOPY:
        if (storage_is_postgres(arg) && uri_has_password(arg))
            return err_set(err, -EINVAL, "--db-copy: a password in the URI would show in the "
                                         "process list; put it in PGPASSFILE or ~/.pgpass");
        return copy_path("db-copy", arg, cfg->copy_from, sizeof cfg->copy_from, err);
    case O_LEASE:
        if (parse_long(arg, 2, 86400, &v))
            return err_set(err, -EINVAL, "--lease must be 2..86400 seconds (got '%s')", arg);
        cfg->lease_s = (int)v;
        return 0;
    case O_WEB:
        return copy_path("web", arg, cfg->web_dir, sizeof cfg->web_dir, err);
    case O_PORTFILE:
        return copy_path("port-file", arg, cfg->port_file, sizeof cfg->port_file, err);
    case O_TOKEN:
        return srv_token_load("--token", arg, SRV_TOKEN_WRITE, cfg, err);
    case O_READTOKEN:
        cfg->reads_closed = 1;
        return srv_token_load("--read-token", arg, SRV_TOKEN_READ, cfg, err);
    case O_HASHTOKEN:
        cfg->hash_token = 1;
        return 0;
    case O_ACCESSLOG:
        return copy_path("access-log", strcmp(arg, "-") ? arg : "", cfg->access_log,
                         sizeof cfg->access_log, err);
    case O_CORS:
        return parse_origin(arg, cfg, err);
    case O_BACKUPDIR:
        return copy_path("backup-dir", arg, cfg->backup_dir, sizeof cfg->backup_dir, err);
    case O_BACKUP:
        return copy_path("backup", arg, cfg->backup_out, sizeof cfg->backup_out, err);
    case O_BENCH: {
        size_t kind = strcspn(arg, ":");
        int named = arg[kind] == ':';
        if (!((kind == 3 && !strncmp(arg, "sim", 3) && !named) ||
              (kind == 4 && !strncmp(arg, "none", 4) && !named) ||
              (kind == 9 && !strncmp(arg, "libcamera", 9)) ||
              (kind == 6 && !strncmp(arg, "aravis", 6))) ||
            (named && !arg[kind + 1]) || strlen(arg) >= sizeof cfg->bench)
            return err_set(err, -EINVAL,
                           "--bench must be sim, libcamera[:ID], aravis[:ID] or none (got '%s')",
                           arg);
        snprintf(cfg->bench, sizeof cfg->bench, "%s", arg);
        return 0;
    }
    case O_LISTCAMERAS:
        cfg->list_cameras = 1;
        return 0;
    case O_STAGE: {
        err_t e;
        if (strlen(arg) >= sizeof cfg->stage)
            return err_set(err, -EINVAL, "--stage: too long");
        if (stage_url_check(arg, NULL, &e)) return err_set(err, -EINVAL, "--stage: %s", e.msg);
        snprintf(cfg->stage, sizeof cfg->stage, "%s", arg);
        return 0;
    }
    case O_WORKERS:
    case O_HTTP:
        if (parse_long(arg, 1, 64, &v))
            return err_set(err, -EINVAL, "--%s must be 1..64 (got '%s')",
                           c == O_WORKERS ? "workers" : "http-threads", arg);
        *(c == O_WORKERS ? &cfg->workers : &cfg->http_threads) = (int)v;
        return 0;
    case O_FITNICE:
        if (parse_long(arg, 0, 19, &v))
            return err_set(err, -EINVAL, "--fit-nice must be 0..19 (got '%s')", arg);
        cfg->fit_nice = (int)v;
        return 0;
    case O_FITBATCH:
        cfg->fit_sched = THREAD_SCHED_BATCH;
        return 0;
    case O_FITSCHED: {
        static const char *const names[] = {[THREAD_SCHED_NORMAL] = "normal",
                                            [THREAD_SCHED_BATCH] = "batch",
                                            [THREAD_SCHED_IDLE] = "idle"};
        for (int i = 0; i < 3; i++)
            if (strcmp(arg, names[i]) == 0) {
                cfg->fit_sched = i;
                return 0;
            }
        return err_set(err, -EINVAL, "--fit-sched must be normal, batch or idle (got '%s')", arg);
    }
    case O_HTTPNICE:
        if (parse_long(arg, -20, 19, &v))
            return err_set(err, -EINVAL, "--http-nice must be -20..19 (got '%s')", arg);
        cfg->http_nice = (int)v;
        return 0;
    case O_HTTPSLICE:
        if (parse_long(arg, 0, 100000, &v) || (v > 0 && v < 100))
            return err_set(err, -EINVAL, "--http-slice-us must be 0 or 100..100000 (got '%s')",
                           arg);
        cfg->http_slice_us = (int)v;
        return 0;
    case O_MAXBODY:
        if (parse_long(arg, 1024, 1LL << 30, &v))
            return err_set(err, -EINVAL, "--max-body must be 1024..1073741824 bytes (got '%s')",
                           arg);
        cfg->max_body = (size_t)v;
        return 0;
    case O_MAXREPLY:
        if (parse_long(arg, 1LL << 20, 1LL << 30, &v))
            return err_set(err, -EINVAL,
                           "--max-reply-bytes must be 1048576..1073741824 bytes (got '%s')", arg);
        cfg->max_reply_bytes = (size_t)v;
        return 0;
    case O_MAXCONN:
    case O_PERCLIENT:
    case O_REQTIMEOUT:
    case O_MAXSUBS:
    case O_MAXFITPTS:
    case O_MAXFITR:
    case O_MAXJITTER: {
        static const struct {
            int opt;
            const char *name;
            long long lo, hi;
        } lim[] = {{O_MAXCONN, "max-connections", 16, 1000000},
                   {O_PERCLIENT, "max-per-client", 1, 1000000},
                   {O_REQTIMEOUT, "request-timeout", 1, 86400},
                   {O_MAXFITPTS, "max-fit-points", 1, 10000000},
                   {O_MAXFITR, "max-fit-r", 1, 32},
                   {O_MAXJITTER, "max-jitter-evals", 100000, 2000000000},
                   {O_MAXSUBS, "max-subscribers", 1, 1000000}};
        size_t i = 0;
        while (lim[i].opt != c)
            i++;
        if (parse_long(arg, lim[i].lo, lim[i].hi, &v))
            return err_set(err, -EINVAL, "--%s must be %lld..%lld (got '%s')", lim[i].name,
                           lim[i].lo, lim[i].hi, arg);
        int *field[] = {&cfg->max_connections, &cfg->max_per_client, &cfg->request_timeout_s,
                        &cfg->max_fit_points, &cfg->max_fit_r, &cfg->max_jitter_evals,
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
    case O_CALIBMAP: {
        int m = storage_map_parse(arg);
        if (m < 0)
            return err_set(err, -EINVAL,
                           "--calibration-map must be " STORAGE_MAP_WORDS " (got '%s')", arg);
        cfg->calibration_map = m;
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
    if (cfg->copy_from[0]) { /* --db-copy FROM TO: TO is the one argument after the options */
        if (first != argc - 1)
            return err_set(err, -EINVAL, "--db-copy FROM TO: give the target TO (a database "
                                         "file or postgresql:// URI) after the options");
        if (storage_is_postgres(argv[first]) && uri_has_password(argv[first]))
            return err_set(err, -EINVAL, "--db-copy: a password in the URI would show in the "
                                         "process list; put it in PGPASSFILE or ~/.pgpass");
        if ((ret = copy_path("db-copy", argv[first], cfg->copy_to, sizeof cfg->copy_to, err)))
            return ret;
        first = argc;
    }
    if (first < argc) return err_set(err, -EINVAL, "unexpected argument '%s'", argv[first]);
    int writes = 0;
    for (int i = 0; i < cfg->n_tokens; i++)
        writes += cfg->tokens[i].level == SRV_TOKEN_WRITE;
    if (cfg->reads_closed && !writes)
        return err_set(err, -EINVAL, "--read-token needs --token (else writes would stay open)");
    return 0;
}
