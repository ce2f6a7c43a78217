/* storage_gate.c: the write gate (storage.h): a ticket lock, so the connections of one process
 * that share it take the database's write lock in the order they asked for it. SQLite's busy
 * handler only sleeps and retries: a connection committing a scan point every millisecond could
 * take the lock again before a waiting fit worker or a cancel woke up, and starve it past the busy
 * timeout ("database is locked"). In-process writes are short (one point, one fit), so the
 * wait has no deadline of its own; SQLite's busy timeout still applies to other processes.
 * Hand-written: pthreads has no fair mutex.
 *
 * Every handle of the process passes here to write, so the gate also keeps the storage's health
 * (storage.h: the last storage fault, cleared by a write that commits) and the test hooks that
 * make storage faults on purpose (a fault file, a page cap). */
#include "storage_int.h"

#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/clock.h"

struct storage_gate {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    unsigned long next, serving; /* the next ticket to hand out; the ticket that may write */
    pthread_t owner;             /* the thread writing now, when owned */
    int owned;
    atomic_uint_least64_t calib_gen; /* committed transactions that stored a calibration */
    pthread_mutex_t health_mu; /* guards health */
    storage_health_t health;
    int64_t full_pages, full_free; /* at the last "full" fault: the database's (free) pages */
    char fault_file[PATH_MAX]; /* test hook: "" none */
    long long max_pages;       /* test hook: 0 none */
    struct stg_listener *listener; /* a shared database's calibrations (storage_listen.c) */
    char token[64];      /* this gate's name in its notifications (its own are not heard) */
    char notify_sql[96]; /* NOTIFY ipsd_calibrations, 'token' */
};

int storage_gate_new(storage_gate_t **out)
{
    storage_gate_t *g = calloc(1, sizeof *g);
    if (!g) return -ENOMEM;
    pthread_mutex_init(&g->mu, NULL);
    pthread_cond_init(&g->cv, NULL);
    pthread_mutex_init(&g->health_mu, NULL);
    /* unique among the instances sharing a database: the host's process id, the gate's address
     * and the wall clock (a token made of digits and hex letters needs no quoting) */
    snprintf(g->token, sizeof g->token, "%ld-%lx-%lld", (long)getpid(), (unsigned long)(uintptr_t)g,
             (long long)clock_wall_ms());
    snprintf(g->notify_sql, sizeof g->notify_sql, "NOTIFY ipsd_calibrations, '%s'", g->token);
    *out = g;
    return 0;
}

const char *stg_gate_notify_sql(const storage_gate_t *g)
{
    return g->notify_sql;
}

void storage_gate_free(storage_gate_t *g)
{
    if (!g) return;
    stg_listener_stop(g->listener);
    pthread_cond_destroy(&g->cv);
    pthread_mutex_destroy(&g->mu);
    pthread_mutex_destroy(&g->health_mu);
    free(g);
}

void storage_set_gate(storage_t *st, storage_gate_t *g)
{
    st->gate = g;
    if (g && g->max_pages > 0) {
        char sql[64];
        snprintf(sql, sizeof sql, "PRAGMA max_page_count = %lld", g->max_pages);
        if (sqldb_exec(st->db, sql) != SQLDB_OK)
            fprintf(stderr, "ipsd: test hook: %s failed: %s\n", sql, sqldb_errmsg(st->db));
    }
}

int storage_gate_set_test_faults(storage_gate_t *g, const char *fault_file, long long max_pages)
{
    const char *f = fault_file ? fault_file : "";
    if (strlen(f) >= sizeof g->fault_file) return -ENAMETOOLONG;
    snprintf(g->fault_file, sizeof g->fault_file, "%s", f);
    g->max_pages = max_pages > 0 ? max_pages : 0;
    return 0;
}

const char *storage_fault_name(int fault)
{
    switch (fault) {
    case 0: return "ok";
    case -ENOSPC: return "full";
    case -EROFS: return "read-only";
    default: return "io-error";
    }
}

void storage_gate_health(storage_gate_t *g, storage_health_t *out)
{
    memset(out, 0, sizeof *out);
    if (!g) return;
    pthread_mutex_lock(&g->health_mu);
    *out = g->health;
    pthread_mutex_unlock(&g->health_mu);
}

void stg_gate_fault(storage_t *st, int code, const char *msg, int64_t pages, int64_t free_pages)
{
    storage_gate_t *g = st->gate;
    if (!g) return;
    pthread_mutex_lock(&g->health_mu);
    g->full_pages = pages;
    g->full_free = free_pages;
    if (!g->health.fault || g->health.fault != code) g->health.since_ms = clock_wall_ms();
    g->health.fault = code;
    g->health.faults++;
    snprintf(g->health.msg, sizeof g->health.msg, "%s", msg);
    pthread_mutex_unlock(&g->health_mu);
}

int stg_gate_full(storage_t *st, int64_t *pages, int64_t *free_pages)
{
    storage_gate_t *g = st->gate;
    if (!g) return 0;
    pthread_mutex_lock(&g->health_mu);
    int full = g->health.fault == -ENOSPC;
    *pages = g->full_pages;
    *free_pages = g->full_free;
    pthread_mutex_unlock(&g->health_mu);
    return full;
}

void stg_gate_ok(storage_t *st)
{
    storage_gate_t *g = st->gate;
    if (!g) return;
    pthread_mutex_lock(&g->health_mu);
    if (g->health.fault)
        fprintf(stderr, "ipsd: storage: writes succeed again (after: %s)\n", g->health.msg);
    g->health.fault = 0;
    g->health.since_ms = 0;
    pthread_mutex_unlock(&g->health_mu);
}

int stg_gate_injected(storage_t *st)
{
    storage_gate_t *g = st->gate;
    if (!g || !g->fault_file[0]) return SQLDB_OK;
    FILE *f = fopen(g->fault_file, "r");
    if (!f) return SQLDB_OK;
    char word[32] = "";
    if (fscanf(f, "%31s", word) != 1) word[0] = '\0';
    fclose(f);
    if (!strcmp(word, "ioerr")) return SQLDB_IOERR;
    if (!strcmp(word, "readonly")) return SQLDB_READONLY;
    return SQLDB_FULL; /* "full", or anything else */
}

int storage_gate_listen(storage_gate_t *g, const char *target, err_t *err)
{
    if (!g || g->listener || !sqldb_is_postgres_uri(target)) return 0;
    return stg_listener_start(&g->calib_gen, target, g->token, &g->listener, err);
}

int storage_calib_generation(storage_t *st, uint64_t *gen)
{
    if (!st || !st->gate) return -ENOTSUP;
    /* a shared database: only while other instances' calibrations are heard of */
    if (sqldb_dialect(st->db) == SQLDB_POSTGRES && !stg_listener_listening(st->gate->listener))
        return -ENOTSUP;
    *gen = atomic_load(&st->gate->calib_gen);
    return *gen & 1 ? -EBUSY : 0; /* odd: a calibration is being written */
}

/* The generation is a sequence lock: even while no calibration write is in flight, odd from the
 * first calibration a transaction stores until it commits or rolls back (one writer at a time
 * passes the gate). A reader that finds it odd neither uses nor fills the cache, so no reply
 * read before a commit is served after it: between the COMMIT and the count after it, a reader
 * that finds the job done must not get the entry of the calibration before (a stale read seen
 * in test_server_calib_cache on a busy machine). */
void stg_gate_calib_written(storage_t *st)
{
    if (st->gate && !st->calib_dirty) atomic_fetch_add(&st->gate->calib_gen, 1);
    st->calib_dirty = 1;
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
    /* committed (counted already), or rolled back: the generation even again */
    if (g && st->calib_dirty) atomic_fetch_add(&g->calib_gen, 1);
    st->calib_dirty = 0;
    if (!g || !st->gate_held) return;
    st->gate_held = 0;
    pthread_mutex_lock(&g->mu);
    g->owned = 0;
    g->serving++;
    pthread_cond_broadcast(&g->cv);
    pthread_mutex_unlock(&g->mu);
}
