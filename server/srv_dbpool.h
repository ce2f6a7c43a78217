/* srv_dbpool.h: a pool of database handles (storage_t) for the threads that serve HTTP requests.
 * A storage_t must be used by one thread at a time (storage.h), and opening one costs a file open
 * and a schema check, so request handlers borrow an idle handle and give it back. The pool grows
 * to the number of requests served at once (the HTTP thread count) and never shrinks. */
#ifndef IPSD_SERVER_SRV_DBPOOL_H
#define IPSD_SERVER_SRV_DBPOOL_H

#include "base/err.h"
#include "storage/storage.h"

typedef struct srv_dbpool srv_dbpool_t;

/* A pool over the database at path (copied); every handle it opens writes through gate
 * (storage_set_gate; NULL: none), which must outlive the pool. *out is the caller's (srv_dbpool_close). */
int srv_dbpool_open(const char *path, const char *claimant, storage_gate_t *gate,
                    srv_dbpool_t **out, err_t *err);

/* Closes every handle and frees the pool; every handle must have been given back. Accepts NULL. */
void srv_dbpool_close(srv_dbpool_t *p);

/* Borrows an idle handle, opening a new one when none is idle. Returns NULL with err set when
 * the database cannot be opened. Give it back with srv_dbpool_put. */
storage_t *srv_dbpool_get(srv_dbpool_t *p, err_t *err);

/* Gives a handle back (accepts NULL). */
void srv_dbpool_put(srv_dbpool_t *p, storage_t *st);

#endif
