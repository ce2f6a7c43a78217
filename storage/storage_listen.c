/* storage_listen.c: on a PostgreSQL database several ipsd share, the calibrations another ipsd
 * stores must reach this one's reply cache (api/api_calib_cache.h), whose entries live while the
 * gate's calibration generation stands still. Every transaction that stores a calibration sends
 * NOTIFY ipsd_calibrations (stg_commit; delivered when it commits) with its gate's token; this
 * thread, on a connection of its own that LISTENs, moves the generation for each notification
 * but its own gate's (counted at its commit already). While it is not listening
 * (not yet connected, or the connection was lost) storage_calib_generation says -ENOTSUP and the
 * cache is not used; each (re)connection moves the generation, since a notification may have
 * been missed meanwhile. */
#include "storage_int.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "storage_sql_pg.h"

#define LISTEN_POLL_MS 250 /* how often the thread looks at its stop flag */
#define RECONNECT_MS 1000  /* between two attempts to connect again */

struct stg_listener {
    pthread_t thread;
    char *uri;
    atomic_uint_least64_t *gen; /* the gate's calibration generation */
    char *own;                  /* the payload of the gate's own notifications: not counted */
    atomic_int stop, listening;
};

static void pause_ms(struct stg_listener *l, int ms)
{
    for (int t = 0; t < ms && !atomic_load(&l->stop); t += 50)
        usleep(50 * 1000);
}

static void *listen_main(void *arg)
{
    struct stg_listener *l = arg;
    int reported = 0;
    while (!atomic_load(&l->stop)) {
        sqldb_t *db = NULL;
        err_t err = {{0}};
        if (sqldb_pg_open(l->uri, &db, &err) || sqldb_exec(db, stg_pg_listen) != SQLDB_OK) {
            if (!reported++)
                fprintf(stderr,
                        "ipsd: storage: cannot listen for other instances' calibrations "
                        "(%s); the calibration cache is off until it can\n",
                        db ? sqldb_errmsg(db) : err.msg);
            sqldb_close(db);
            pause_ms(l, RECONNECT_MS);
            continue;
        }
        if (reported) fprintf(stderr, "ipsd: storage: listening for calibrations again\n");
        reported = 0;
        atomic_fetch_add(l->gen, 2); /* what was cached before may have been missed (by 2: the
                                        generation's parity says whether a write is in flight) */
        atomic_store(&l->listening, 1);
        int n;
        while (!atomic_load(&l->stop) && (n = sqldb_pg_wait_notify(db, LISTEN_POLL_MS, l->own, NULL)) >= 0)
            if (n > 0) atomic_fetch_add(l->gen, 2);
        atomic_store(&l->listening, 0);
        atomic_fetch_add(l->gen, 2);
        if (!atomic_load(&l->stop))
            fprintf(stderr,
                    "ipsd: storage: the calibrations' listening connection was lost (%s); "
                    "the calibration cache is off until it is back\n",
                    sqldb_errmsg(db));
        sqldb_close(db);
        reported = 1;
    }
    return NULL;
}

int stg_listener_start(atomic_uint_least64_t *gen, const char *uri, const char *own_token,
                       struct stg_listener **out, err_t *err)
{
    struct stg_listener *l = calloc(1, sizeof *l);
    if (!l || !(l->uri = strdup(uri)) || !(l->own = strdup(own_token ? own_token : ""))) {
        if (l) free(l->uri);
        free(l);
        return err_set(err, -ENOMEM, "out of memory");
    }
    l->gen = gen;
    int rc = pthread_create(&l->thread, NULL, listen_main, l);
    if (rc) {
        free(l->uri), free(l->own);
        free(l);
        return err_set(err, -rc, "cannot start the calibrations' listener: %s", strerror(rc));
    }
    *out = l;
    return 0;
}

int stg_listener_listening(const struct stg_listener *l)
{
    return l && atomic_load(&l->listening);
}

void stg_listener_stop(struct stg_listener *l)
{
    if (!l) return;
    atomic_store(&l->stop, 1);
    pthread_join(l->thread, NULL);
    free(l->uri), free(l->own);
    free(l);
}
