/* api_conn.c: connection tracking and the request deadline (api_conn.h). The reaper shuts a
 * late connection's socket down (shutdown(2), not close): libmicrohttpd then sees the end of the
 * stream, closes the connection itself and tells us (MHD_CONNECTION_NOTIFY_CLOSED) before it
 * closes the descriptor, so under the tracker's lock a listed descriptor is always still this
 * connection's. */
#include "api_conn.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <time.h>

#include "base/clock.h"

typedef struct api_conn {
    struct api_conn *prev, *next;
    api_conns_t *owner;
    int fd;
    int answering;
    double since_s; /* start of the wait for the current request (monotonic seconds) */
} api_conn_t;

struct api_conns {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    pthread_t reaper;
    int have_reaper, stop;
    double timeout_s;
    api_conn_t *head;
    size_t open;
    uint64_t reaped;
};

static void *reap(void *arg)
{
    api_conns_t *cs = arg;
    pthread_mutex_lock(&cs->mu);
    while (!cs->stop) {
        double now = clock_mono_s();
        for (api_conn_t *c = cs->head; c; c = c->next) {
            if (c->answering || c->fd < 0 || now - c->since_s <= cs->timeout_s) continue;
            shutdown(c->fd, SHUT_RDWR);
            c->fd = -1; /* shut once; the CLOSED notification removes it */
            cs->reaped++;
        }
        /* a quarter of the deadline, at most 1 s: a late connection goes within 1.25 x it */
        double wait = cs->timeout_s / 4 < 1 ? cs->timeout_s / 4 : 1;
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        long ns = until.tv_nsec + (long)(wait * 1e9);
        until.tv_sec += ns / 1000000000L;
        until.tv_nsec = ns % 1000000000L;
        pthread_cond_timedwait(&cs->cv, &cs->mu, &until);
    }
    pthread_mutex_unlock(&cs->mu);
    return NULL;
}

api_conns_t *api_conns_open(double timeout_s)
{
    api_conns_t *cs = calloc(1, sizeof *cs);
    if (!cs) return NULL;
    pthread_mutex_init(&cs->mu, NULL);
    pthread_cond_init(&cs->cv, NULL);
    cs->timeout_s = timeout_s;
    if (timeout_s > 0) {
        if (pthread_create(&cs->reaper, NULL, reap, cs) != 0) {
            api_conns_close(cs);
            return NULL;
        }
        cs->have_reaper = 1;
    }
    return cs;
}

void api_conns_close(api_conns_t *cs)
{
    if (!cs) return;
    pthread_mutex_lock(&cs->mu);
    cs->stop = 1;
    pthread_cond_signal(&cs->cv);
    pthread_mutex_unlock(&cs->mu);
    if (cs->have_reaper) pthread_join(cs->reaper, NULL);
    while (cs->head) { /* none after MHD_stop_daemon; freed in case */
        api_conn_t *c = cs->head;
        cs->head = c->next;
        free(c);
    }
    pthread_cond_destroy(&cs->cv);
    pthread_mutex_destroy(&cs->mu);
    free(cs);
}

void api_conns_notify(void *cls, struct MHD_Connection *conn, void **socket_context,
                      enum MHD_ConnectionNotificationCode code)
{
    api_conns_t *cs = cls;
    api_conn_t *c = *socket_context;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo *info =
            MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CONNECTION_FD);
        if (!info || !(c = calloc(1, sizeof *c))) return; /* untracked: no deadline */
        c->owner = cs;
        c->fd = info->connect_fd;
        c->since_s = clock_mono_s();
        pthread_mutex_lock(&cs->mu);
        c->next = cs->head;
        if (cs->head) cs->head->prev = c;
        cs->head = c;
        cs->open++;
        pthread_mutex_unlock(&cs->mu);
        *socket_context = c;
    } else if (code == MHD_CONNECTION_NOTIFY_CLOSED && c) {
        pthread_mutex_lock(&cs->mu);
        if (c->prev) c->prev->next = c->next;
        else cs->head = c->next;
        if (c->next) c->next->prev = c->prev;
        cs->open--;
        pthread_mutex_unlock(&cs->mu);
        free(c);
        *socket_context = NULL;
    }
}

void api_conn_answering(struct MHD_Connection *conn, int answering)
{
    const union MHD_ConnectionInfo *info =
        MHD_get_connection_info(conn, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    api_conn_t *c = info ? info->socket_context : NULL;
    if (!c) return;
    pthread_mutex_lock(&c->owner->mu);
    c->answering = answering;
    c->since_s = clock_mono_s();
    pthread_mutex_unlock(&c->owner->mu);
}

void api_conns_counts(api_conns_t *cs, size_t *open, uint64_t *reaped)
{
    pthread_mutex_lock(&cs->mu);
    *open = cs->open;
    *reaped = cs->reaped;
    pthread_mutex_unlock(&cs->mu);
}
