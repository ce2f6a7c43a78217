/* srv_config.h: ipsd's configuration: the command line (listen address, database, bench, stage,
 * worker counts, token files, web directory, limits, logs, CORS, backups) parsed and checked into
 * one plain struct (no pointers: it is copied by value). */
#ifndef IPSD_SERVER_SRV_CONFIG_H
#define IPSD_SERVER_SRV_CONFIG_H

#include <stddef.h>

#include "base/err.h"

#define SRV_PATH_MAX 4096
#define SRV_TOKENS_MAX 64   /* bearer tokens of all token files together */
#define SRV_TOKEN_DIGEST 32 /* SHA-256 */

/* What a bearer token grants (srv_token.h). */
enum { SRV_TOKEN_NONE = 0, SRV_TOKEN_READ = 1, SRV_TOKEN_WRITE = 2 };

/* A bearer token, kept only as its SHA-256 digest (srv_token.h). */
typedef struct srv_token {
    unsigned char sha256[SRV_TOKEN_DIGEST];
    int level; /* SRV_TOKEN_READ or SRV_TOKEN_WRITE */
} srv_token_t;

typedef struct srv_config {
    char host[64];                /* numeric IPv4 or IPv6 address to bind ("127.0.0.1") */
    int port;                     /* 0: any free port (see port_file) */
    char db_path[SRV_PATH_MAX];   /* "var/ipsd.db", or a postgresql:// URI (no password) */
    char bench_name[64];          /* --bench-name: this ipsd on a shared database (the host name) */
    int lease_s;                  /* --lease: another ipsd's running job is taken over after its
                                     claimant's heartbeat is this old (30; a shared database) */
    char bench[160];              /* --bench: "sim", or a camera backend ("libcamera", "aravis")
                                     with ":DEVICE-ID" when one camera is named */
    char stage[1024];             /* --stage: "sim" or a stage string (instrument/stage.h) */
    int workers;                  /* fit worker threads (2) */
    int http_threads;             /* HTTP thread pool size (2) */
    int fit_nice;                 /* --fit-nice: the fit workers' nice value, 0..19 (10) */
    int fit_sched;                /* --fit-sched: the fit workers' policy, a THREAD_SCHED_* */
    int http_slice_us;            /* --http-slice-us: the HTTP threads' time slice, 0 kernel's */
    int http_nice;                /* --http-nice: the HTTP threads' nice value, -20..19 (0) */
    srv_token_t tokens[SRV_TOKENS_MAX]; /* --token (write) and --read-token (read) digests */
    int n_tokens;                 /* 0: writes open */
    int reads_closed;             /* --read-token given: reads under /api need a token too */
    char access_log[SRV_PATH_MAX]; /* request log: "" stderr (default), "off", or a file */
    char cors_origin[256];        /* --cors-origin: the one origin allowed, "" CORS off */
    char backup_dir[SRV_PATH_MAX]; /* where POST /api/backup writes, "" backups off */
    char backup_out[SRV_PATH_MAX]; /* --backup OUT: back the database up to OUT and exit */
    char copy_from[SRV_PATH_MAX];  /* --db-copy FROM TO: copy FROM into TO (copy_to) and exit */
    char copy_to[SRV_PATH_MAX];
    int hash_token;               /* --hash-token: print the hash line of stdin's token, exit */
    int list_cameras;             /* --list-cameras: print every backend's cameras, exit */
    char web_dir[SRV_PATH_MAX];   /* static files of the dashboard */
    char port_file[SRV_PATH_MAX]; /* where to write the bound port, "" for nowhere */
    size_t max_body;              /* request body limit in bytes (4 MiB) */
    size_t max_reply_bytes;       /* largest reply one request may build, in bytes (64 MiB) */
    double max_scan_bytes;        /* largest scan accepted, in frame bytes stored (1 GiB) */
    int max_connections;          /* open HTTP connections at most (4096) */
    int max_per_client;           /* of them from one address at most (128) */
    int request_timeout_s;        /* a request's headers and body must arrive within (60) */
    int max_subscribers;          /* open event streams at most (256) */
    int heartbeat_s;              /* SSE comment heartbeat period (15) */
    int max_attempts;             /* a job claimed this often by crashed runs fails (3) */
    int max_fit_points;           /* largest uploaded scan file a fit takes, in points (10000) */
    int max_fit_r;                /* largest r a fit request may ask for (32) */
    int max_jitter_evals;         /* largest estimated Airy integration of a jitter request, in
                                     radial evaluations (fit_jitter_cost; 40000000, ~1 s) */
    double camera_timeout_s;      /* a frame not delivered within fails the scan (0: camera's) */
    /* --calibration-map: the map a fit stores as its calibration when its request names none
       (the automatic fit of a scan, re-fits without "map"; a storage_map_t: 0 recommended;
       1 shrunk; 2 kriged, the default) */
    int calibration_map;
} srv_config_t;

/* The defaults above (web_dir: the source tree's web/ when it exists, else ./web). */
srv_config_t srv_config_default(void);

/* Parses argv (argv[0] is the program). Returns 0; 1 after printing --help to stdout (the caller
 * exits 0); or -EINVAL with err naming the bad option (the caller prints it and exits 2).
 * The token files (--token, --read-token) are read here into digests (srv_token.h); a file
 * without a token is refused, and so is --read-token without --token. */
int srv_config_parse(int argc, char **argv, srv_config_t *cfg, err_t *err);

/* Wipes the token digests; accepts NULL. (cfg owns no memory.) */
void srv_config_free(srv_config_t *cfg);

/* The usage text. Static. */
const char *srv_config_usage(void);

#endif
