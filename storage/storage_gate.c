/* storage_gate.c: the write gate (storage.h): a ticket lock, so the connections of one process
 * that share it take the database's write lock in the order they asked for it. SQLite's busy
 * handler only sleeps and retries: a connection committing a scan point every millisecond could
 * take the lock again before a waiting fit worker or a cancel woke up, and starve it past the busy
 * timeout ("database is locked"). In-process writes are short (one point, one fit), so the
 * wait has no deadline of its own; SQLite's busy timeout still applies to other processes.
 * Hand-written: pthreads has no fair mutex. */
#include "storage_int.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>

struct storage_gate {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    unsigned long next, serving; /* the next ticket to hand out; the ticket that may write */
    pthread_t owner;             /* the thread writing now, when owned */
    int owned;
    atomic_uint_least64_t calib_gen; /* committed transactions that stored a calibration */
};

int storage_gate_new(storage_gate_t **out)
{
    storage_gate_t *g = calloc(1, sizeof *g);
    if (!g) return -ENOMEM;
    pthread_mutex_init(&g->mu, NULL);
    pthread_cond_init(&g->cv, NULL);
    *out = g;
    return 0;
}

void storage_gate_free(storage_gate_t *g)
{
    if (!g) return;
    pthread_cond_destroy(&g->cv);
    pthread_mutex_destroy(&g->mu);
    free(g);
}

void storage_set_gate(storage_t *st, storage_gate_t *g)
{
    st->gate = g;
}

int storage_calib_generation(storage_t *st, uint64_t *gen)
{
    if (!st || !st->gate) return -ENOTSUP;
    *gen = atomic_load(&st->gate->calib_gen);
    return 0;
}

void stg_gate_committed(storage_t *st)
{
    /* counted after the commit, so a reader that read the counter before its read either saw
     * the new rows or will find its entry older than the counter */
    if (st->gate && st->calib_dirty) atomic_fetch_add(&st->gate->calib_gen, 1);
    st->calib_dirty = 0;
}

int stg_gate_enter(storage_t *st)
{
    storage_gate_t *g = st->gate;
    if (!g) return 0;
    pthread_mutex_lock(&g->mu);
    if (g->owned && pthread_equal(g->owner, pthread_self())) {
        /* this thread writes through another handle already: waiting would never end */
        pthread_mutex_unlock(&g->mu);
        return -EDEADLK;
    }
    unsigned long mine = g->next++;
    while (g->serving != mine)
        pthread_cond_wait(&g->cv, &g->mu);
    g->owner = pthread_self();
    g->owned = 1;
    pthread_mutex_unlock(&g->mu);
    st->gate_held = 1;
    return 0;
}

void stg_gate_leave(storage_t *st)
{
    storage_gate_t *g = st->gate;
    st->calib_dirty = 0; /* committed (counted already) or rolled back */
    if (!g || !st->gate_held) return;
    st->gate_held = 0;
    pthread_mutex_lock(&g->mu);
    g->owned = 0;
    g->serving++;
    pthread_cond_broadcast(&g->cv);
    pthread_mutex_unlock(&g->mu);
}
