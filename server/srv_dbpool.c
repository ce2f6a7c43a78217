/* srv_dbpool.c: the database handle pool (see srv_dbpool.h): a stack of idle handles under a
 * mutex; opening a new handle happens outside the lock. */
#include "srv_dbpool.h"

#include <errno.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

struct srv_dbpool {
    pthread_mutex_t mu;
    char *path, *claimant; /* claimant: storage_set_claimant of every handle, NULL none */
    storage_gate_t *gate;
    storage_t **idle;
    size_t n_idle, cap;
};

int srv_dbpool_open(const char *path, const char *claimant, storage_gate_t *gate,
                    srv_dbpool_t **out, err_t *err)
{
    srv_dbpool_t *p = calloc(1, sizeof *p);
    *out = NULL;
    if (!p || !(p->path = strdup(path)) || (claimant && !(p->claimant = strdup(claimant)))) {
        if (p) free(p->path);
        free(p);
        return err_set(err, -ENOMEM, "database pool: out of memory");
    }
    pthread_mutex_init(&p->mu, NULL);
    p->gate = gate;
    *out = p;
    return 0;
}

void srv_dbpool_close(srv_dbpool_t *p)
{
    if (!p) return;
    for (size_t i = 0; i < p->n_idle; i++)
        storage_close(p->idle[i]);
    free(p->idle);
    free(p->path);
    free(p->claimant);
    pthread_mutex_destroy(&p->mu);
    free(p);
}

storage_t *srv_dbpool_get(srv_dbpool_t *p, err_t *err)
{
    storage_t *st = NULL;
    pthread_mutex_lock(&p->mu);
    if (p->n_idle) st = p->idle[--p->n_idle];
    pthread_mutex_unlock(&p->mu);
    if (st) return st;
    if (storage_open(p->path, &st, err)) return NULL;
    if (storage_set_claimant(st, p->claimant)) {
        storage_close(st);
        err_set(err, -ENOMEM, "database pool: out of memory");
        return NULL;
    }
    storage_set_gate(st, p->gate);
    return st;
}

void srv_dbpool_put(srv_dbpool_t *p, storage_t *st)
{
    if (!st) return;
    pthread_mutex_lock(&p->mu);
    if (p->n_idle == p->cap) {
        size_t cap = p->cap ? 2 * p->cap : 8;
        storage_t **grown = realloc(p->idle, cap * sizeof *grown);
        if (!grown) { /* cannot keep it: close it instead */
            pthread_mutex_unlock(&p->mu);
            storage_close(st);
            return;
        }
        p->idle = grown;
        p->cap = cap;
    }
    p->idle[p->n_idle++] = st;
    pthread_mutex_unlock(&p->mu);
}
