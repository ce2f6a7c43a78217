/* srv_events.c: the event hub (see srv_events.h): a ring of events under one mutex, readers in a
 * list, and a ticker thread for heartbeats. Wake callbacks run outside the lock; a woken reader
 * is claimed (waiting cleared) under the lock first, so no two threads wake it. */
#include "server/srv_events.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"

struct srv_sub {
    srv_sub_t *next;
    uint64_t next_seq;    /* seq of the next event to read */
    uint64_t heartbeats;  /* heartbeats seen */
    int waiting;          /* asleep, to be woken once */
    srv_sub_t *wake_next; /* link in a wake list being built (only by who claimed it) */
    void (*sleep)(void *), (*wake)(void *);
    void *ctx;
};

struct srv_events {
    pthread_mutex_t mu;
    pthread_cond_t tick_cv; /* the ticker sleeps on it; signalled at shutdown */
    pthread_t ticker;
    int have_ticker, closed, heartbeat_ms;
    srv_event_t *ring;
    size_t capacity;
    uint64_t next_seq; /* seq the next published event gets */
    uint64_t heartbeats;
    srv_sub_t *subs;
    size_t n_subs;
};

/* Under the lock: claims every waiting reader into a list to wake after unlocking. */
static srv_sub_t *claim_waiting(srv_events_t *h)
{
    srv_sub_t *list = NULL;
    for (srv_sub_t *s = h->subs; s; s = s->next) {
        if (!s->waiting) continue;
        s->waiting = 0;
        s->wake_next = list;
        list = s;
    }
    return list;
}

/* Outside the lock: wakes a claimed list. The link is read before the call, because a woken
 * reader may finish and unsubscribe at once. */
static void wake_list(srv_sub_t *s)
{
    while (s) {
        srv_sub_t *next = s->wake_next;
        if (s->wake) s->wake(s->ctx);
        s = next;
    }
}

static void *ticker_main(void *arg)
{
    srv_events_t *h = arg;
    pthread_mutex_lock(&h->mu);
    while (!h->closed) {
        struct timespec until = clock_deadline(CLOCK_MONOTONIC, h->heartbeat_ms);
        int rc = 0;
        while (!h->closed && rc != ETIMEDOUT)
            rc = pthread_cond_timedwait(&h->tick_cv, &h->mu, &until);
        if (h->closed) break;
        h->heartbeats++;
        srv_sub_t *list = claim_waiting(h);
        pthread_mutex_unlock(&h->mu);
        wake_list(list);
        pthread_mutex_lock(&h->mu);
    }
    pthread_mutex_unlock(&h->mu);
    return NULL;
}

int srv_events_open(size_t capacity, int heartbeat_ms, srv_events_t **out, err_t *err)
{
    *out = NULL;
    if (capacity < 1 || heartbeat_ms < 0)
        return err_set(err, -EINVAL, "event hub: capacity >= 1 and heartbeat >= 0 needed");
    srv_events_t *h = calloc(1, sizeof *h);
    if (!h || !(h->ring = calloc(capacity, sizeof *h->ring))) {
        free(h);
        return err_set(err, -ENOMEM, "event hub: out of memory");
    }
    h->capacity = capacity;
    h->heartbeat_ms = heartbeat_ms;
    h->next_seq = 1;
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_mutex_init(&h->mu, NULL);
    pthread_cond_init(&h->tick_cv, &ca);
    pthread_condattr_destroy(&ca);
    if (heartbeat_ms > 0) {
        int rc = pthread_create(&h->ticker, NULL, ticker_main, h);
        if (rc) {
            srv_events_close(h);
            return err_set(err, -rc, "event hub: cannot start the ticker: %s", strerror(rc));
        }
        h->have_ticker = 1;
    }
    *out = h;
    return 0;
}

void srv_events_shutdown(srv_events_t *h)
{
    if (!h) return;
    pthread_mutex_lock(&h->mu);
    h->closed = 1;
    pthread_cond_broadcast(&h->tick_cv);
    srv_sub_t *list = claim_waiting(h);
    pthread_mutex_unlock(&h->mu);
    wake_list(list);
}

void srv_events_close(srv_events_t *h)
{
    if (!h) return;
    srv_events_shutdown(h);
    if (h->have_ticker) pthread_join(h->ticker, NULL);
    pthread_cond_destroy(&h->tick_cv);
    pthread_mutex_destroy(&h->mu);
    free(h->ring);
    free(h);
}

void srv_events_publish(srv_events_t *h, const srv_event_t *ev)
{
    if (!h || !ev) return;
    pthread_mutex_lock(&h->mu);
    srv_event_t *slot = &h->ring[h->next_seq % h->capacity];
    *slot = *ev;
    slot->seq = h->next_seq++;
    srv_sub_t *list = claim_waiting(h);
    pthread_mutex_unlock(&h->mu);
    wake_list(list);
}

int srv_events_subscribe(srv_events_t *h, void (*sleep)(void *), void (*wake)(void *), void *ctx,
                         srv_sub_t **out)
{
    srv_sub_t *s = calloc(1, sizeof *s);
    *out = NULL;
    if (!s) return -ENOMEM;
    s->sleep = sleep;
    s->wake = wake;
    s->ctx = ctx;
    pthread_mutex_lock(&h->mu);
    s->next_seq = h->next_seq;
    s->heartbeats = h->heartbeats;
    s->next = h->subs;
    h->subs = s;
    h->n_subs++;
    pthread_mutex_unlock(&h->mu);
    *out = s;
    return 0;
}

void srv_events_unsubscribe(srv_events_t *h, srv_sub_t *s)
{
    if (!h || !s) return;
    pthread_mutex_lock(&h->mu);
    for (srv_sub_t **p = &h->subs; *p; p = &(*p)->next) {
        if (*p == s) {
            *p = s->next;
            h->n_subs--;
            break;
        }
    }
    pthread_mutex_unlock(&h->mu);
    free(s);
}

int srv_events_next(srv_events_t *h, srv_sub_t *s, srv_event_t *out)
{
    int ret = SRV_EV_NONE;
    pthread_mutex_lock(&h->mu);
    uint64_t oldest = h->next_seq > h->capacity ? h->next_seq - h->capacity : 1;
    if (h->closed) {
        ret = SRV_EV_CLOSED;
    } else if (s->next_seq < oldest) {
        s->next_seq = oldest; /* the ring overwrote what this reader had not read */
        ret = SRV_EV_LOST;
    } else if (s->next_seq < h->next_seq) {
        *out = h->ring[s->next_seq % h->capacity];
        s->next_seq++;
        ret = SRV_EV_EVENT;
    } else if (s->heartbeats < h->heartbeats) {
        s->heartbeats = h->heartbeats;
        ret = SRV_EV_HEARTBEAT;
    } else {
        s->waiting = 1;
        if (s->sleep) s->sleep(s->ctx);
    }
    pthread_mutex_unlock(&h->mu);
    return ret;
}

size_t srv_events_readers(srv_events_t *h)
{
    pthread_mutex_lock(&h->mu);
    size_t n = h->n_subs;
    pthread_mutex_unlock(&h->mu);
    return n;
}
