/* srv_config.h: ipsd's configuration: the command line (listen address, database, bench, worker
 * counts, token file, web directory, body limit) parsed and checked into one plain struct. */
#ifndef IPSD_SERVER_SRV_CONFIG_H
#define IPSD_SERVER_SRV_CONFIG_H

#include <stddef.h>

#include "base/err.h"

#define SRV_PATH_MAX 4096

typedef struct srv_config {
    char host[64];                /* numeric IPv4 or IPv6 address to bind ("127.0.0.1") */
    int port;                     /* 0: any free port (see port_file) */
    char db_path[SRV_PATH_MAX];   /* "var/ipsd.db" */
    char bench[16];               /* "sim" or "libcamera" */
    int workers;                  /* fit worker threads (2) */
    int http_threads;             /* HTTP thread pool size (2) */
    char *token;                  /* bearer token for writes, NULL: writes open (owned) */
    char web_dir[SRV_PATH_MAX];   /* static files of the dashboard */
    char port_file[SRV_PATH_MAX]; /* where to write the bound port, "" for nowhere */
    size_t max_body;              /* request body limit in bytes (4 MiB) */
    double max_scan_bytes;        /* largest scan accepted, in frame bytes stored (1 GiB) */
    int max_connections;          /* open HTTP connections at most (4096) */
    int max_per_client;           /* of them from one address at most (128) */
    int request_timeout_s;        /* a request's headers and body must arrive within (60) */
    int max_subscribers;          /* open event streams at most (256) */
    int heartbeat_s;              /* SSE comment heartbeat period (15) */
    int max_attempts;             /* a job claimed this often by crashed runs fails (3) */
    double camera_timeout_s;      /* a frame not delivered within fails the scan (0: camera's) */
} srv_config_t;

/* The defaults above (web_dir: the source tree's web/ when it exists, else ./web). */
srv_config_t srv_config_default(void);

/* Parses argv (argv[0] is the program). Returns 0; 1 after printing --help to stdout (the caller
 * exits 0); or -EINVAL with err naming the bad option (the caller prints it and exits 2).
 * The token file (--token) is read here: its content, whitespace trimmed, must not be empty. */
int srv_config_parse(int argc, char **argv, srv_config_t *cfg, err_t *err);

/* Releases what cfg owns (the token); accepts NULL. */
void srv_config_free(srv_config_t *cfg);

/* The usage text. Static. */
const char *srv_config_usage(void);

#endif
