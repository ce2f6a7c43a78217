/* sqldb_pg.c: the PostgreSQL driver of sqldb.h (libpq), for a database several benches share.
 *
 * What it translates so that storage/ keeps one way of speaking:
 * - placeholders: ?N becomes $N (outside string literals);
 * - statements are prepared on the server at their first step (PQprepare), parameters sent as
 *   text, BLOBs as binary bytea; rows come back as text, bytea hex-decoded on first read;
 * - "BEGIN IMMEDIATE" (SQLite's write transaction, one writer at a time) becomes BEGIN and a
 *   transaction-scoped advisory lock (of the current schema) that every ipsd on it takes to write: writers stay
 *   serialized across instances, so every read-then-write of storage/ keeps the meaning it has on
 *   SQLite; readers never wait;
 * - "BEGIN" (a consistent multi-statement read) becomes a REPEATABLE READ transaction: one
 *   snapshot, as SQLite's read transactions in WAL mode;
 * - the busy timeout is lock_timeout; SQLSTATEs map to sqldb_rc_t (a privilege revoked, 42501,
 *   is SQLDB_READONLY: the storage fault "read-only");
 * - a lost connection (the server restarted, the network dropped) is opened again at the next
 *   statement outside a transaction, its settings and prepared statements made again; a read or
 *   a BEGIN that found it lost is tried once more on the new one (neither can have changed
 *   anything). Inside a transaction the loss is an error until the caller rolls back: the server
 *   rolled the transaction back, so a later COMMIT must not pretend to have stored it.
 * Hand-written over libpq because no maintained C library offers a driver seam over both. */
#include "sqldb.h"

#include <errno.h>
#include <inttypes.h>
#include <libpq-fe.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* the key of the advisory lock a write transaction holds: "ipsd" in ASCII */
#define PG_WRITE_LOCK_KEY 0x69707364
#define BYTEA_OID 17

typedef struct {
    struct sqldb base;
    PGconn *c;
    char name[512]; /* the URI without its password */
    char err[512];  /* the last error's words */
    int64_t changes, total;
    unsigned next_stmt; /* names of server-side prepared statements */
    unsigned epoch;     /* connections made so far: a statement prepared in another is gone */
    int busy_ms;        /* the lock_timeout set (-1: none), set again on a new connection */
    int txn;            /* inside a transaction this driver began */
    int txn_lost;       /* and its connection was lost: only a ROLLBACK ends it */
} pg_t;

typedef enum { PLAIN, BEGIN_WRITE, BEGIN_READ, UTILITY } pg_kind_t;

typedef struct {
    struct sqldb_stmt base;
    pg_t *db;
    pg_kind_t kind;
    char name[24]; /* its server-side name, "" until prepared */
    unsigned epoch; /* the connection it was prepared on (pg_t.epoch) */
    char *sql;     /* with $N placeholders */
    int nparams, readonly;
    char **vals; /* bound values (owned), NULL for SQL NULL */
    int *lens, *fmts;
    PGresult *res;
    int row, nrows;
    unsigned char **blobs; /* the current row's decoded bytea columns */
    size_t *blob_len;
} pg_stmt_t;

static pg_t *DB(sqldb_t *db)
{
    return (pg_t *)db;
}
static pg_stmt_t *ST(sqldb_stmt_t *s)
{
    return (pg_stmt_t *)s;
}

/* Keeps the first line of msg as the connection's last error. */
static void set_err(pg_t *p, const char *msg)
{
    snprintf(p->err, sizeof p->err, "%s", msg && *msg ? msg : "unknown error");
    p->err[strcspn(p->err, "\n")] = '\0';
}

/* The driver-neutral code of a failed result (its SQLSTATE), its words kept in p->err. */
static sqldb_rc_t result_rc(pg_t *p, const PGresult *r)
{
    if (!r) {
        set_err(p, PQerrorMessage(p->c));
        return PQstatus(p->c) == CONNECTION_BAD ? SQLDB_IOERR : SQLDB_NOMEM;
    }
    const char *primary = PQresultErrorField(r, PG_DIAG_MESSAGE_PRIMARY);
    set_err(p, primary ? primary : PQresultErrorMessage(r));
    if (PQstatus(p->c) == CONNECTION_BAD) return SQLDB_IOERR;
    const char *state = PQresultErrorField(r, PG_DIAG_SQLSTATE);
    if (!state) return SQLDB_IOERR;
    if (!strcmp(state, "23505")) return SQLDB_UNIQUE;
    if (!strcmp(state, "23503")) return SQLDB_FOREIGN_KEY;
    if (!strncmp(state, "23", 2)) return SQLDB_CONSTRAINT;
    if (!strcmp(state, "22P02") || !strcmp(state, "22003")) return SQLDB_CONSTRAINT; /* bad value */
    if (!strcmp(state, "55P03") || !strcmp(state, "40001") || !strcmp(state, "40P01"))
        return SQLDB_BUSY;
    if (!strcmp(state, "53100")) return SQLDB_FULL; /* disk full */
    if (!strcmp(state, "53200")) return SQLDB_NOMEM;
    if (!strcmp(state, "25006")) return SQLDB_READONLY; /* read-only transaction */
    /* insufficient_privilege: ipsd's role lost a privilege (revoked by the lab): to ipsd the
     * database is read-only, like an SQLite file it may not write; the words stay PostgreSQL's
     * ("permission denied for table frames") */
    if (!strcmp(state, "42501")) return SQLDB_READONLY;
    if (!strncmp(state, "08", 2) || !strncmp(state, "57P", 3) || !strncmp(state, "58", 2) ||
        !strncmp(state, "XX", 2))
        return SQLDB_IOERR;
    return SQLDB_ERROR;
}

/* Runs sql without parameters and no rows wanted. */
static sqldb_rc_t run(pg_t *p, const char *sql)
{
    PGresult *r = PQexec(p->c, sql);
    ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
    sqldb_rc_t rc = st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK ? SQLDB_OK : result_rc(p, r);
    if (rc == SQLDB_OK) {
        p->changes = strtoll(PQcmdTuples(r), NULL, 10);
        p->total += p->changes;
    }
    PQclear(r);
    return rc;
}

/* ---- statements ---------------------------------------------------------------------------- */

/* sql with every ?N outside a string literal or quoted name written $N; the highest N. */
static char *translate(const char *sql, int *nparams)
{
    size_t n = strlen(sql);
    char *out = malloc(n + 1), *o = out;
    if (!out) return NULL;
    char quote = 0;
    *nparams = 0;
    for (const char *s = sql; *s; s++) {
        if (quote) {
            if (*s == quote) quote = 0;
        } else if (*s == '\'' || *s == '"') {
            quote = *s;
        } else if (*s == '?' && s[1] >= '0' && s[1] <= '9') {
            int k = (int)strtol(s + 1, NULL, 10);
            if (k > *nparams) *nparams = k;
            *o++ = '$';
            continue;
        }
        *o++ = *s;
    }
    *o = '\0';
    return out;
}

static int starts_with_word(const char *sql, const char *word)
{
    while (*sql == ' ' || *sql == '\n' || *sql == '\t')
        sql++;
    size_t n = strlen(word);
    return !strncasecmp(sql, word, n) && (sql[n] == '\0' || sql[n] == ' ' || sql[n] == ';');
}

static void drop_row(pg_stmt_t *q)
{
    if (!q->blobs || !q->res) return;
    for (int i = 0; i < PQnfields(q->res); i++) {
        PQfreemem(q->blobs[i]);
        q->blobs[i] = NULL;
    }
}

static void drop_result(pg_stmt_t *q)
{
    drop_row(q);
    free(q->blobs);
    free(q->blob_len);
    q->blobs = NULL;
    q->blob_len = NULL;
    PQclear(q->res);
    q->res = NULL;
    q->row = q->nrows = 0;
}

static sqldb_rc_t pg_prepare(sqldb_t *db, const char *sql, int persistent, sqldb_stmt_t **out)
{
    (void)persistent; /* every statement is kept on the server once prepared */
    *out = NULL;
    pg_stmt_t *q = calloc(1, sizeof *q);
    if (!q) return SQLDB_NOMEM;
    q->base.ops = db->ops;
    q->db = DB(db);
    q->kind = starts_with_word(sql, "BEGIN IMMEDIATE")                               ? BEGIN_WRITE
              : starts_with_word(sql, "BEGIN")                                       ? BEGIN_READ
              : starts_with_word(sql, "COMMIT") || starts_with_word(sql, "ROLLBACK") ? UTILITY
                                                                                     : PLAIN;
    q->readonly = starts_with_word(sql, "SELECT") || q->kind == BEGIN_READ;
    if (!(q->sql = translate(sql, &q->nparams))) goto oom;
    if (q->nparams) {
        q->vals = calloc((size_t)q->nparams, sizeof *q->vals);
        q->lens = calloc((size_t)q->nparams, sizeof *q->lens);
        q->fmts = calloc((size_t)q->nparams, sizeof *q->fmts);
        if (!q->vals || !q->lens || !q->fmts) goto oom;
    }
    *out = &q->base;
    return SQLDB_OK;
oom:
    free(q->sql);
    free(q->vals);
    free(q->lens);
    free(q->fmts);
    free(q);
    return SQLDB_NOMEM;
}

static void clear_bindings(pg_stmt_t *q)
{
    for (int i = 0; i < q->nparams; i++) {
        free(q->vals[i]);
        q->vals[i] = NULL;
        q->lens[i] = q->fmts[i] = 0;
    }
}

static void pg_reset(sqldb_stmt_t *s)
{
    pg_stmt_t *q = ST(s);
    drop_result(q);
    clear_bindings(q);
}

static void pg_finalize(sqldb_stmt_t *s)
{
    pg_stmt_t *q = ST(s);
    pg_reset(s);
    if (q->name[0] && q->epoch == q->db->epoch && PQstatus(q->db->c) == CONNECTION_OK) {
        char sql[64];
        snprintf(sql, sizeof sql, "DEALLOCATE %s", q->name);
        PQclear(PQexec(q->db->c, sql));
    }
    free(q->sql);
    free(q->vals);
    free(q->lens);
    free(q->fmts);
    free(q);
}

/* Stores a copy of n bytes as parameter i (1-based), text (fmt 0) or binary (fmt 1). */
static sqldb_rc_t bind(sqldb_stmt_t *s, int i, const void *v, size_t n, int fmt)
{
    pg_stmt_t *q = ST(s);
    if (i < 1 || i > q->nparams) return SQLDB_ERROR;
    free(q->vals[i - 1]);
    q->vals[i - 1] = NULL;
    if (v) {
        char *c = malloc(n + 1);
        if (!c) return SQLDB_NOMEM;
        memcpy(c, v, n);
        c[n] = '\0';
        q->vals[i - 1] = c;
    }
    q->lens[i - 1] = (int)n;
    q->fmts[i - 1] = fmt;
    return SQLDB_OK;
}

static sqldb_rc_t pg_bind_null(sqldb_stmt_t *s, int i)
{
    return bind(s, i, NULL, 0, 0);
}
static sqldb_rc_t pg_bind_int64(sqldb_stmt_t *s, int i, int64_t v)
{
    char t[24];
    int n = snprintf(t, sizeof t, "%" PRId64, v);
    return bind(s, i, t, (size_t)n, 0);
}
static sqldb_rc_t pg_bind_double(sqldb_stmt_t *s, int i, double v)
{
    char t[40];
    int n = snprintf(t, sizeof t, "%.17g", v);
    if (!strcmp(t, "inf"))
        n = snprintf(t, sizeof t, "Infinity");
    else if (!strcmp(t, "-inf"))
        n = snprintf(t, sizeof t, "-Infinity");
    else if (!strcmp(t, "nan") || !strcmp(t, "-nan"))
        n = snprintf(t, sizeof t, "NaN");
    return bind(s, i, t, (size_t)n, 0);
}
static sqldb_rc_t pg_bind_text(sqldb_stmt_t *s, int i, const char *v)
{
    return bind(s, i, v, v ? strlen(v) : 0, 0);
}
static sqldb_rc_t pg_bind_blob(sqldb_stmt_t *s, int i, const void *v, size_t n)
{
    static const char empty = 0;
    return bind(s, i, v ? v : &empty, n, 1); /* an empty BLOB is not NULL */
}

static int lost(pg_t *p) { return PQstatus(p->c) != CONNECTION_OK; }

/* Outside a transaction: a lost connection opened again (PQreset), with its settings. */
static sqldb_rc_t reconnect(pg_t *p)
{
    if (!lost(p)) return SQLDB_OK;
    PQreset(p->c);
    if (lost(p)) {
        char why[sizeof p->err];
        snprintf(why, sizeof why, "the database connection is lost, and opening it again failed: %s",
                 PQerrorMessage(p->c));
        set_err(p, why);
        return SQLDB_IOERR;
    }
    p->epoch++;
    char sql[64];
    snprintf(sql, sizeof sql, "SET lock_timeout = %d", p->busy_ms > 0 ? p->busy_ms : 0);
    sqldb_rc_t rc = run(p, "SET client_min_messages = warning");
    if (rc == SQLDB_OK && p->busy_ms >= 0) rc = run(p, sql);
    return rc;
}

/* A statement without result rows, run again once on a new connection when the first try found
 * the connection lost (for what changes nothing: BEGIN, SET). */
static sqldb_rc_t run_retry(pg_t *p, const char *sql)
{
    sqldb_rc_t rc = reconnect(p);
    if (rc == SQLDB_OK && (rc = run(p, sql)) != SQLDB_OK && lost(p) && reconnect(p) == SQLDB_OK)
        rc = run(p, sql);
    return rc;
}

/* COMMIT and ROLLBACK, with the driver's view of the transaction. */
static sqldb_rc_t end_transaction(pg_stmt_t *q)
{
    pg_t *p = q->db;
    int rollback = starts_with_word(q->sql, "ROLLBACK");
    if (p->txn_lost || (p->txn && lost(p))) {
        p->txn = p->txn_lost = 0;
        if (rollback) return SQLDB_OK; /* the server rolled it back when the connection went */
        set_err(p, "the database connection was lost inside the transaction: the server rolled "
                   "it back, nothing of it was stored");
        return SQLDB_IOERR;
    }
    sqldb_rc_t rc = run(p, q->sql);
    p->txn = 0; /* COMMIT ends the transaction even when it fails (a deferred key) */
    return rc;
}

/* BEGIN IMMEDIATE and BEGIN, as the top of the file says. */
static sqldb_rc_t begin(pg_stmt_t *q)
{
    pg_t *p = q->db;
    if (p->txn) {
        set_err(p, "a transaction is open already");
        return SQLDB_ERROR;
    }
    if (q->kind == BEGIN_READ) {
        sqldb_rc_t rc = run_retry(p, "BEGIN ISOLATION LEVEL REPEATABLE READ");
        p->txn = rc == SQLDB_OK;
        return rc;
    }
    /* one lock per schema: each schema is a database of its own to ipsd; BEGIN and the lock in
     * one round trip (a scan stores a point in each such transaction) */
    char sql[160];
    snprintf(sql, sizeof sql,
             "BEGIN ISOLATION LEVEL READ COMMITTED; "
             "SELECT pg_advisory_xact_lock(%d, hashtext(current_schema()))",
             PG_WRITE_LOCK_KEY);
    sqldb_rc_t rc = run_retry(p, sql);
    if (rc != SQLDB_OK && PQtransactionStatus(p->c) == PQTRANS_INERROR) {
        /* BEGIN ran, the lock did not (its timeout): the transaction is open, and ends here */
        char why[sizeof p->err];
        memcpy(why, p->err, sizeof why);
        run(p, "ROLLBACK");
        memcpy(p->err, why, sizeof why);
    }
    p->txn = rc == SQLDB_OK;
    return rc;
}

/* Prepares q on the current connection when it is not (yet, or since a reconnection). */
static sqldb_rc_t prepare_on_server(pg_stmt_t *q)
{
    pg_t *p = q->db;
    if (q->name[0] && q->epoch == p->epoch) return SQLDB_OK;
    char name[sizeof q->name];
    snprintf(name, sizeof name, "ipsd_%u", p->next_stmt++);
    PGresult *r = PQprepare(p->c, name, q->sql, q->nparams, NULL);
    sqldb_rc_t rc = r && PQresultStatus(r) == PGRES_COMMAND_OK ? SQLDB_OK : result_rc(p, r);
    PQclear(r);
    if (rc != SQLDB_OK) return rc;
    memcpy(q->name, name, sizeof name);
    q->epoch = p->epoch;
    return SQLDB_OK;
}

/* Prepares (when needed) and executes q: its result, or NULL with the code in *rc. */
static PGresult *execute(pg_stmt_t *q, sqldb_rc_t *rc)
{
    pg_t *p = q->db;
    if ((*rc = prepare_on_server(q)) != SQLDB_OK) return NULL;
    PGresult *r = PQexecPrepared(p->c, q->name, q->nparams, (const char *const *)q->vals, q->lens,
                                 q->fmts, 0);
    ExecStatusType st = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
    if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK) {
        *rc = SQLDB_OK;
        return r;
    }
    *rc = result_rc(p, r);
    PQclear(r);
    return NULL;
}

static sqldb_rc_t pg_step(sqldb_stmt_t *s)
{
    pg_stmt_t *q = ST(s);
    pg_t *p = q->db;
    if (q->res) { /* the next row of the result */
        drop_row(q);
        return ++q->row < q->nrows ? SQLDB_ROW : SQLDB_DONE;
    }
    if (q->kind != PLAIN) {
        sqldb_rc_t rc = q->kind == UTILITY ? end_transaction(q) : begin(q);
        return rc == SQLDB_OK ? SQLDB_DONE : rc;
    }
    sqldb_rc_t rc;
    if (p->txn && (p->txn_lost || lost(p))) {
        p->txn_lost = 1;
        set_err(p, "the database connection was lost inside the transaction: the server rolled "
                   "it back");
        return SQLDB_IOERR;
    }
    if (!p->txn && (rc = reconnect(p)) != SQLDB_OK) return rc;
    PGresult *r = execute(q, &rc);
    /* a read alone found the connection lost: nothing changed, so once more on a new one */
    if (!r && !p->txn && q->readonly && lost(p) && reconnect(p) == SQLDB_OK) r = execute(q, &rc);
    if (!r) {
        if (p->txn && lost(p)) p->txn_lost = 1;
        return rc;
    }
    ExecStatusType st = PQresultStatus(r);
    p->changes = strtoll(PQcmdTuples(r), NULL, 10);
    p->total += p->changes;
    if (st == PGRES_COMMAND_OK) {
        PQclear(r);
        return SQLDB_DONE;
    }
    int nf = PQnfields(r);
    q->blobs = calloc((size_t)(nf ? nf : 1), sizeof *q->blobs);
    q->blob_len = calloc((size_t)(nf ? nf : 1), sizeof *q->blob_len);
    if (!q->blobs || !q->blob_len) {
        free(q->blobs);
        free(q->blob_len);
        q->blobs = NULL;
        q->blob_len = NULL;
        PQclear(r);
        return SQLDB_NOMEM;
    }
    q->res = r;
    q->nrows = PQntuples(r);
    q->row = 0;
    return q->nrows > 0 ? SQLDB_ROW : SQLDB_DONE;
}

static int pg_readonly(sqldb_stmt_t *s)
{
    return ST(s)->readonly;
}

static int in_row(pg_stmt_t *q, int i)
{
    return q->res && q->row < q->nrows && i >= 0 && i < PQnfields(q->res);
}

static int pg_col_null(sqldb_stmt_t *s, int i)
{
    pg_stmt_t *q = ST(s);
    return !in_row(q, i) || PQgetisnull(q->res, q->row, i);
}

static int64_t pg_col_int64(sqldb_stmt_t *s, int i)
{
    pg_stmt_t *q = ST(s);
    if (pg_col_null(s, i)) return 0;
    const char *v = PQgetvalue(q->res, q->row, i);
    if (v[0] == 't' && !v[1]) return 1; /* a boolean */
    return strtoll(v, NULL, 10);
}

static double pg_col_double(sqldb_stmt_t *s, int i)
{
    pg_stmt_t *q = ST(s);
    return pg_col_null(s, i) ? 0.0 : strtod(PQgetvalue(q->res, q->row, i), NULL);
}

static const char *pg_col_text(sqldb_stmt_t *s, int i)
{
    pg_stmt_t *q = ST(s);
    return pg_col_null(s, i) ? NULL : PQgetvalue(q->res, q->row, i);
}

/* A bytea column decoded once per row; any other column is its text. */
static const void *pg_col_blob(sqldb_stmt_t *s, int i)
{
    pg_stmt_t *q = ST(s);
    if (pg_col_null(s, i)) return NULL;
    if (PQftype(q->res, i) != BYTEA_OID) return PQgetvalue(q->res, q->row, i);
    if (!q->blobs[i])
        q->blobs[i] =
            PQunescapeBytea((const unsigned char *)PQgetvalue(q->res, q->row, i), &q->blob_len[i]);
    return q->blobs[i];
}

static size_t pg_col_bytes(sqldb_stmt_t *s, int i)
{
    pg_stmt_t *q = ST(s);
    if (pg_col_null(s, i)) return 0;
    if (PQftype(q->res, i) != BYTEA_OID) return (size_t)PQgetlength(q->res, q->row, i);
    return pg_col_blob(s, i) ? q->blob_len[i] : 0;
}

/* ---- the connection ------------------------------------------------------------------------ */

static sqldb_rc_t pg_exec(sqldb_t *db, const char *sql)
{
    return run(DB(db), sql);
}
static int64_t pg_changes(sqldb_t *db)
{
    return DB(db)->changes;
}
static int64_t pg_total_changes(sqldb_t *db)
{
    return DB(db)->total;
}

static int64_t pg_last_insert_id(sqldb_t *db)
{
    PGresult *r = PQexec(DB(db)->c, "SELECT lastval()");
    int64_t id = r && PQresultStatus(r) == PGRES_TUPLES_OK && PQntuples(r) == 1
                     ? strtoll(PQgetvalue(r, 0, 0), NULL, 10)
                     : 0;
    PQclear(r);
    return id;
}

static int pg_in_transaction(sqldb_t *db) { return DB(db)->txn; }

static const char *pg_errmsg(sqldb_t *db)
{
    return DB(db)->err;
}
static const char *pg_name(sqldb_t *db)
{
    return DB(db)->name;
}

static sqldb_rc_t pg_busy_timeout(sqldb_t *db, int ms)
{
    char sql[48];
    snprintf(sql, sizeof sql, "SET lock_timeout = %d", ms);
    DB(db)->busy_ms = ms;
    return DB(db)->txn ? run(DB(db), sql) : run_retry(DB(db), sql);
}

static sqldb_rc_t pg_blob_read(sqldb_t *db, const char *table, const char *column, int64_t id,
                               size_t offset, size_t n, void *buf)
{
    pg_t *p = DB(db);
    char sql[256], ids[24];
    if (!p->txn && reconnect(p) != SQLDB_OK) return SQLDB_IOERR;
    snprintf(sql, sizeof sql, "SELECT substring(%s from %zu for %zu) FROM %s WHERE id = $1", column,
             offset + 1, n, table);
    snprintf(ids, sizeof ids, "%" PRId64, id);
    const char *vals[1] = {ids};
    PGresult *r = PQexecParams(p->c, sql, 1, NULL, vals, NULL, NULL, 1); /* binary: the bytes */
    sqldb_rc_t rc = SQLDB_OK;
    if (!r || PQresultStatus(r) != PGRES_TUPLES_OK) {
        rc = result_rc(p, r);
    } else if (PQntuples(r) != 1 || (size_t)PQgetlength(r, 0, 0) != n) {
        set_err(p, "the BLOB is shorter than the part asked for");
        rc = SQLDB_IOERR;
    } else {
        memcpy(buf, PQgetvalue(r, 0, 0), n);
    }
    PQclear(r);
    return rc;
}

static sqldb_rc_t pg_checkpoint(sqldb_t *db)
{
    (void)db;
    return SQLDB_OK;
}

static void pg_close(sqldb_t *db)
{
    PQfinish(DB(db)->c);
    free(db);
}

static const struct sqldb_ops pg_ops = {
    .dialect = SQLDB_POSTGRES,
    .close = pg_close,
    .prepare = pg_prepare,
    .finalize = pg_finalize,
    .reset = pg_reset,
    .bind_null = pg_bind_null,
    .bind_int64 = pg_bind_int64,
    .bind_double = pg_bind_double,
    .bind_text = pg_bind_text,
    .bind_blob = pg_bind_blob,
    .step = pg_step,
    .readonly = pg_readonly,
    .col_null = pg_col_null,
    .col_int64 = pg_col_int64,
    .col_double = pg_col_double,
    .col_text = pg_col_text,
    .col_blob = pg_col_blob,
    .col_bytes = pg_col_bytes,
    .exec = pg_exec,
    .changes = pg_changes,
    .total_changes = pg_total_changes,
    .last_insert_id = pg_last_insert_id,
    .in_transaction = pg_in_transaction,
    .errmsg = pg_errmsg,
    .name = pg_name,
    .busy_timeout = pg_busy_timeout,
    .blob_read = pg_blob_read,
    .checkpoint = pg_checkpoint,
};

int sqldb_pg_wait_notify(sqldb_t *db, int timeout_ms, const char *ignore, int *ignored)
{
    if (ignored) *ignored = 0;
    if (!db || db->ops != &pg_ops) return -ENOTSUP;
    pg_t *p = DB(db);
    int sock = PQsocket(p->c);
    if (sock < 0 || PQstatus(p->c) != CONNECTION_OK) return -EIO;
    struct pollfd fd = {.fd = sock, .events = POLLIN};
    int n = 0;
    if (poll(&fd, 1, timeout_ms) < 0 && errno != EINTR) return -EIO;
    if (!PQconsumeInput(p->c) || PQstatus(p->c) != CONNECTION_OK) {
        set_err(p, PQerrorMessage(p->c));
        return -EIO;
    }
    PGnotify *note;
    while ((note = PQnotifies(p->c))) {
        int skip = ignore && note->extra && strcmp(note->extra, ignore) == 0;
        n += !skip;
        if (ignored) *ignored += skip;
        PQfreemem(note);
    }
    return n;
}

/* uri without a password: "user:secret@" becomes "user@", and a password= parameter goes. */
static void redact(const char *uri, char *out, size_t size)
{
    snprintf(out, size, "%s", uri);
    char *auth = strstr(out, "://");
    if (auth) {
        auth += 3;
        char *at = strchr(auth, '@'), *slash = strchr(auth, '/');
        char *colon = at ? memchr(auth, ':', (size_t)(at - auth)) : NULL;
        if (at && colon && (!slash || at < slash)) memmove(colon, at, strlen(at) + 1);
    }
    char *pw = strstr(out, "password=");
    if (pw && (pw[-1] == '?' || pw[-1] == '&')) {
        char *end = strchr(pw, '&');
        if (end)
            memmove(pw, end + 1, strlen(end + 1) + 1);
        else
            pw[-1] = '\0';
    }
}

static void ignore_notice(void *arg, const char *message)
{
    (void)arg;
    (void)message;
}

int sqldb_pg_open(const char *uri, sqldb_t **out, err_t *err)
{
    *out = NULL;
    pg_t *p = calloc(1, sizeof *p);
    if (!p) return err_set(err, -ENOMEM, "cannot open database: out of memory");
    p->base.ops = &pg_ops;
    p->busy_ms = -1;
    redact(uri, p->name, sizeof p->name);
    /* the open errors name the database without its parameters: a long query string (options,
     * sslrootcert=/a/long/path) would otherwise push libpq's reason off the end of the line */
    char where[sizeof p->name];
    snprintf(where, sizeof where, "%s", p->name);
    where[strcspn(where, "?")] = '\0';
    /* a malformed URI is the caller's mistake, not the server's: say so before connecting */
    char *why = NULL;
    PQconninfoOption *opts = PQconninfoParse(uri, &why);
    if (!opts) {
        int ret = err_set(err, -EINVAL, "cannot open database %s: %s", where,
                          why ? why : "not a valid connection URI");
        if (why) {
            char *nl = strchr(err ? err->msg : "", '\n');
            if (nl) *nl = '\0';
        }
        PQfreemem(why);
        free(p);
        return ret;
    }
    PQconninfoFree(opts);
    p->c = PQconnectdb(uri);
    if (!p->c || PQstatus(p->c) != CONNECTION_OK) {
        set_err(p, p->c ? PQerrorMessage(p->c) : "out of memory");
        /* refused credentials are the caller's to fix (-EACCES), not a fault of the server: a
         * password the server refused, or a server certificate TLS refused (sslmode=verify-ca
         * or verify-full: "certificate verify failed", "server certificate for ... does not
         * match host name", a missing root certificate file) */
        int denied = p->c && (PQconnectionNeedsPassword(p->c) ||
                              strstr(p->err, "password authentication failed") ||
                              strstr(p->err, "no password supplied") ||
                              strstr(p->err, "certificate"));
        int ret = err_set(err, denied ? -EACCES : -EIO, "cannot open database %s: %s", where,
                          p->err);
        pg_close(&p->base);
        return ret;
    }
    PQsetNoticeProcessor(p->c, ignore_notice, NULL);
    if (run(p, "SET client_min_messages = warning") != SQLDB_OK) {
        int ret = err_set(err, -EIO, "cannot open database %s: %s", where, p->err);
        pg_close(&p->base);
        return ret;
    }
    *out = &p->base;
    return 0;
}
