/* srv_main.h: ipsd's main program: configuration, signals and the order of start-up and graceful
 * shutdown. The HTTP front end (api/) plugs in through srv_frontend_t, so that server/ does not
 * depend on api/ (the dependency points api -> server); api/ipsd.c is the whole main(). */
#ifndef IPSD_SERVER_SRV_MAIN_H
#define IPSD_SERVER_SRV_MAIN_H

#include "base/err.h"
#include "server/srv.h"

typedef struct srv_frontend {
    /* starts serving srv; *handle is the front end's state, *port the bound port */
    int (*start)(srv_t *srv, void **handle, int *port, err_t *err);
    /* stops accepting new connections (requests in progress go on) */
    void (*quiesce)(void *handle);
    /* ends every connection and frees the front end (after srv_stop ended the event streams) */
    void (*stop)(void *handle);
    /* reopens the front end's log files (SIGHUP, after logrotate renamed them); NULL: none */
    void (*reopen_logs)(void *handle);
} srv_frontend_t;

/* Runs ipsd: parses argv, opens the server, starts the workers and the front end, waits for
 * SIGINT or SIGTERM (SIGHUP meanwhile reopens the log files: fe->reopen_logs), then stops in order:
 * no new connections, workers stop (the scan in flight stores its point and goes back to the
 * queue), event streams end, connections close. Returns the process exit code: 0 (also after
 * --help), 1 (cannot start), 2 (bad arguments). */
int srv_main(int argc, char **argv, const srv_frontend_t *fe);

#endif
