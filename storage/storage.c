/* storage.c: opening the database (pragmas, forward migrations), the per-connection statement
 * cache, error mapping, transactions, the clock and the little-endian BLOB codecs that the other
 * files of storage/ share (storage_int.h). */
#include "storage_int.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/clock.h"
#include "base/le.h"
#include "storage_sql_pg.h"

#define STG_BUSY_TIMEOUT_MS 5000

static const char *const state_names[] = {"queued", "running", "done", "failed", "cancelled"};

int storage_schema_version(void) { return stg_n_migrations; }

const char *storage_state_name(int state)
{
    if (state < 0 || state > STORAGE_CANCELLED) return NULL;
    return state_names[state];
}

int storage_state_parse(const char *name, storage_state_t *out)
{
    for (int i = 0; name && i <= STORAGE_CANCELLED; i++) {
        if (strcmp(name, state_names[i]) == 0) {
            *out = (storage_state_t)i;
            return 0;
        }
    }
    return -EINVAL;
}

/* ---- errors and statements ---------------------------------------------------------------- */

/* Statement id's SQL in the database's dialect: PostgreSQL's own text where it has one. */
static const char *stmt_text(storage_t *st, enum stg_id id)
{
    if (sqldb_dialect(st->db) == SQLDB_POSTGRES && stg_sql_pg[id]) return stg_sql_pg[id];
    return stg_sql[id];
}

/* A size's integer (STG_PAGE_COUNT, STG_FREELIST_COUNT), -1 when it cannot be read. Prepared
 * and run without stg_error: it runs while a storage fault is being recorded. */
static int64_t pragma_int(storage_t *st, enum stg_id id)
{
    if (!st->stmt[id] && sqldb_prepare(st->db, stmt_text(st, id), 1, &st->stmt[id]) != SQLDB_OK) {
        st->stmt[id] = NULL;
        return -1;
    }
    int64_t v =
        sqldb_step(st->stmt[id]) == SQLDB_ROW ? sqldb_col_int64(st->stmt[id], 0) : -1;
    sqldb_reset(st->stmt[id]);
    return v;
}

/* A write committed: the storage is healthy again, but after a "full" fault only when the
 * database has more room than it had at the fault (an update in place, e.g. recording
 * the failure, needs no new page and succeeds on a disk still full, and health then said ok).
 * More room: it grew past its size at the fault (the disk or the page cap gave pages), or it
 * has more free pages than then (data was deleted). Unknown sizes: any write clears it. */
static void wrote_ok(storage_t *st)
{
    int64_t pages, free_pages;
    if (stg_gate_full(st, &pages, &free_pages) && pages >= 0 && free_pages >= 0 &&
        pragma_int(st, STG_PAGE_COUNT) <= pages && pragma_int(st, STG_FREELIST_COUNT) <= free_pages)
        return;
    stg_gate_ok(st);
}

/* stg_error with the database's message msg. A storage fault (the disk full, read-only, I/O errors, a
 * corrupt or vanished file) names the database and is recorded in the gate's health. */
static int error_text(storage_t *st, int rc, const char *msg, err_t *err, const char *what)
{
    int code, fault = 0;
    switch (rc) {
    case SQLDB_BUSY: code = -EBUSY; break;
    case SQLDB_NOMEM: code = -ENOMEM; break;
    case SQLDB_FULL: code = fault = -ENOSPC; break;
    case SQLDB_READONLY: code = fault = -EROFS; break;
    case SQLDB_IOERR:
    case SQLDB_NOTADB: code = fault = -EIO; break;
    case SQLDB_UNIQUE: code = -EEXIST; break;
    case SQLDB_FOREIGN_KEY: code = -ENOENT; break;
    case SQLDB_CONSTRAINT: code = -EINVAL; break;
    default: code = -EIO;
    }
    if (!fault) return err_set(err, code, "%s: %s", what, msg);
    const char *db = st && st->db ? sqldb_name(st->db) : NULL;
    err_t e;
    err_set(&e, code, "%s: %s (%s, database %s)", what, msg, storage_fault_name(fault),
            db && *db ? db : "?");
    if (st && st->db && fault == -ENOSPC) /* the room then, which a write must exceed to clear it */
        stg_gate_fault(st, fault, e.msg, pragma_int(st, STG_PAGE_COUNT),
                       pragma_int(st, STG_FREELIST_COUNT));
    else if (st)
        stg_gate_fault(st, fault, e.msg, -1, -1);
    if (err) *err = e;
    return code;
}

int stg_error(storage_t *st, int rc, err_t *err, const char *what)
{
    return error_text(st, rc, st && st->db ? sqldb_errmsg(st->db) : sqldb_rc_text(rc), err,
                      what);
}

/* The test hook's injected fault for a write about to begin (see storage_gate_set_test_faults):
 * 0, or the error as the database would have reported it. */
static int injected(storage_t *st, err_t *err, const char *what)
{
    int rc = stg_gate_injected(st);
    return rc == SQLDB_OK ? 0 : error_text(st, rc, sqldb_rc_text(rc), err, what);
}

int stg_stmt(storage_t *st, enum stg_id id, sqldb_stmt_t **out, err_t *err)
{
    *out = NULL;
    if (!st->stmt[id]) {
        int rc = sqldb_prepare(st->db, stmt_text(st, id), 1, &st->stmt[id]);
        if (rc != SQLDB_OK) {
            st->stmt[id] = NULL;
            return stg_error(st, rc, err, "preparing a statement");
        }
    }
    *out = st->stmt[id];
    return 0;
}

void stg_reset(sqldb_stmt_t *s)
{
    sqldb_reset(s);
}

void stg_bind_int(sqldb_stmt_t *s, int i, int64_t v, int *rc)
{
    if (*rc == SQLDB_OK) *rc = sqldb_bind_int64(s, i, v);
}

void stg_bind_id(sqldb_stmt_t *s, int i, int64_t v, int *rc)
{
    if (*rc == SQLDB_OK) *rc = v ? sqldb_bind_int64(s, i, v) : sqldb_bind_null(s, i);
}

void stg_bind_double(sqldb_stmt_t *s, int i, double v, int *rc)
{
    if (*rc == SQLDB_OK) *rc = isnan(v) ? sqldb_bind_null(s, i) : sqldb_bind_double(s, i, v);
}

void stg_bind_text(sqldb_stmt_t *s, int i, const char *v, int *rc)
{
    if (*rc == SQLDB_OK)
        *rc = v ? sqldb_bind_text(s, i, v) : sqldb_bind_null(s, i);
}

void stg_bind_blob(sqldb_stmt_t *s, int i, const void *v, size_t n, int *rc)
{
    if (*rc == SQLDB_OK) *rc = sqldb_bind_blob(s, i, v, n);
}

double stg_col_double(sqldb_stmt_t *s, int i)
{
    return sqldb_col_null(s, i) ? NAN : sqldb_col_double(s, i);
}

int64_t stg_col_id(sqldb_stmt_t *s, int i)
{
    return sqldb_col_null(s, i) ? 0 : sqldb_col_int64(s, i);
}

char *stg_col_text(sqldb_stmt_t *s, int i, int *oom)
{
    if (sqldb_col_null(s, i)) return NULL;
    const char *t = sqldb_col_text(s, i);
    char *copy = t ? strdup((const char *)t) : NULL;
    if (!copy) *oom = 1;
    return copy;
}

storage_map_t stg_col_map(sqldb_stmt_t *s, int i)
{
    int m = storage_map_parse((const char *)sqldb_col_text(s, i));
    return m < 0 ? STORAGE_MAP_RECOMMENDED : (storage_map_t)m;
}

static const char *const map_words[] = {"recommended", "shrunk", "kriged"};

const char *storage_map_name(storage_map_t m)
{
    return m >= 0 && m < (int)(sizeof map_words / sizeof *map_words) ? map_words[m] : "recommended";
}

int storage_map_parse(const char *word)
{
    for (int m = 0; word && m < (int)(sizeof map_words / sizeof *map_words); m++)
        if (strcmp(word, map_words[m]) == 0) return m;
    return -1;
}

int stg_bind_f64_or_null(sqldb_stmt_t *q, int i, const double *v, size_t n, unsigned char **buf,
                         int *rc)
{
    *buf = NULL;
    if (!v) {
        if (*rc == SQLDB_OK) *rc = sqldb_bind_null(q, i);
        return 0;
    }
    if (!(*buf = stg_blob_from_f64(v, n))) return -ENOMEM;
    stg_bind_blob(q, i, *buf, n * 8, rc);
    return 0;
}

double *stg_col_f64_or_null(sqldb_stmt_t *s, int i, size_t n, int *bad, int *oom)
{
    if (sqldb_col_null(s, i)) return NULL;
    int b = 0;
    double *v = stg_f64_from_blob(sqldb_col_blob(s, i), (size_t)sqldb_col_bytes(s, i), n,
                                  &b);
    if (b) *bad = 1;
    else if (!v) *oom = 1;
    return v;
}

int stg_run(storage_t *st, sqldb_stmt_t *s, err_t *err, const char *what)
{
    /* a write outside a transaction (one statement) takes its turn at the gate too */
    int gated = st->gate && !st->gate_held && !sqldb_readonly(s) &&
                !sqldb_in_transaction(st->db);
    if (gated && stg_gate_enter(st)) {
        stg_reset(s);
        return err_set(err, -EDEADLK, "%s: this thread is writing through another handle", what);
    }
    int ret = gated ? injected(st, err, what) : 0;
    if (ret == 0) {
        int rc = sqldb_step(s);
        ret = rc == SQLDB_DONE ? 0 : stg_error(st, rc, err, what);
        if (ret == 0 && gated && sqldb_changes(st->db)) wrote_ok(st);
    }
    stg_reset(s);
    if (gated) stg_gate_leave(st);
    return ret;
}

int stg_run_ids(storage_t *st, enum stg_id id, int64_t a, int64_t b, err_t *err,
                const char *what)
{
    sqldb_stmt_t *q;
    int ret, rc = SQLDB_OK;
    if ((ret = stg_stmt(st, id, &q, err))) return ret;
    stg_bind_id(q, 1, a, &rc);
    stg_bind_id(q, 2, b, &rc);
    if (rc != SQLDB_OK) {
        stg_reset(q);
        return stg_error(st, rc, err, what);
    }
    return stg_run(st, q, err, what);
}

int stg_row(storage_t *st, sqldb_stmt_t *s, err_t *err, const char *what)
{
    int rc = sqldb_step(s);
    if (rc == SQLDB_ROW) return 0;
    if (rc == SQLDB_DONE) return -ENOENT;
    return stg_error(st, rc, err, what);
}

int stg_count(storage_t *st, sqldb_stmt_t *s, int rc, int64_t *total, err_t *err,
              const char *what)
{
    int ret = rc == SQLDB_OK ? stg_row(st, s, err, what) : stg_error(st, rc, err, what);
    if (ret == 0) *total = sqldb_col_int64(s, 0);
    stg_reset(s);
    return ret == -ENOENT ? err_set(err, -EIO, "%s: no row", what) : ret;
}

int stg_collect(storage_t *st, sqldb_stmt_t *s, size_t size, stg_reader_fn read, void **items,
                size_t *n, err_t *err, const char *what)
{
    size_t cap = 0;
    int rc, ret = 0;
    while ((rc = sqldb_step(s)) == SQLDB_ROW) {
        if (*n == cap) {
            size_t ncap = cap ? 2 * cap : 16;
            void *grown = realloc(*items, ncap * size);
            if (!grown) {
                ret = err_set(err, -ENOMEM, "%s: out of memory", what);
                break;
            }
            *items = grown;
            cap = ncap;
        }
        if ((ret = read(s, (char *)*items + *n * size))) {
            err_set(err, ret, "%s: %s", what,
                    ret == -ENOMEM ? "out of memory" : "a stored BLOB has the wrong size");
            break;
        }
        (*n)++;
    }
    if (ret == 0 && rc != SQLDB_DONE) ret = stg_error(st, rc, err, what);
    stg_reset(s);
    return ret;
}

int stg_bind_map(sqldb_stmt_t *q, const storage_calib_t *c, unsigned char **s, unsigned char **e,
                 int *rc)
{
    size_t n = (size_t)c->r * (size_t)c->r;
    *s = stg_blob_from_f64(c->S, n);
    *e = stg_blob_from_f64(c->S_err, n);
    if (!*s || !*e) return -ENOMEM;
    stg_bind_int(q, 2, c->sensor_id, rc);
    stg_bind_int(q, 3, c->pixel_col, rc);
    stg_bind_int(q, 4, c->pixel_row, rc);
    stg_bind_int(q, 5, c->r, rc);
    stg_bind_blob(q, 6, *s, n * 8, rc);
    stg_bind_blob(q, 7, *e, n * 8, rc);
    stg_bind_double(q, 8, c->I0, rc);
    stg_bind_double(q, 9, c->chi2_red, rc);
    stg_bind_text(q, 10, c->status, rc);
    return 0;
}

/* ---- transactions ------------------------------------------------------------------------- */

static int run_fixed(storage_t *st, enum stg_id id, err_t *err, const char *what)
{
    sqldb_stmt_t *s;
    int ret = stg_stmt(st, id, &s, err);
    return ret ? ret : stg_run(st, s, err, what);
}

int stg_begin_write(storage_t *st, err_t *err)
{
    if (stg_gate_enter(st))
        return err_set(err, -EDEADLK, "starting a write transaction: this thread is writing "
                                      "through another handle");
    int ret = injected(st, err, "starting a write transaction");
    if (ret == 0) ret = run_fixed(st, STG_BEGIN_WRITE, err, "starting a write transaction");
    if (ret) stg_gate_leave(st);
    st->changes_at_begin = sqldb_total_changes(st->db);
    return ret;
}

int stg_begin_read(storage_t *st, err_t *err)
{
    return run_fixed(st, STG_BEGIN_READ, err, "starting a read transaction");
}

int stg_commit(storage_t *st, err_t *err)
{
    /* a write transaction that changed rows: the storage took a write (a claim that found no
     * job changes nothing and proves nothing) */
    int wrote = st->gate_held && sqldb_total_changes(st->db) != st->changes_at_begin;
    int ret = 0;
    /* a shared database: the other instances hear of a calibration when this commits */
    if (st->calib_dirty && sqldb_dialect(st->db) == SQLDB_POSTGRES &&
        sqldb_exec(st->db, st->gate ? stg_gate_notify_sql(st->gate) : stg_pg_notify) != SQLDB_OK)
        ret = stg_error(st, SQLDB_IOERR, err, "announcing a calibration");
    if (ret == 0) ret = run_fixed(st, STG_COMMIT, err, "committing");
    if (ret) {
        stg_rollback(st); /* e.g. a deferred foreign key failed: the transaction stays open */
    } else {
        stg_gate_committed(st);
        /* health is cleared while this handle still holds the gate: after it leaves, the next
         * writer's fault can be recorded first, and a late clear would hide it (a race seen in
         * test_server_storfault on a busy machine) */
        if (wrote) wrote_ok(st);
        stg_gate_leave(st);
    }
    return ret;
}

void stg_rollback(storage_t *st)
{
    if (sqldb_in_transaction(st->db)) /* else none (the database may have ended it) */
        /* a failed ROLLBACK leaves nothing to do but report; the connection rolls back on close */
        (void)run_fixed(st, STG_ROLLBACK, NULL, "rolling back");
    stg_gate_leave(st);
}

/* ---- clock -------------------------------------------------------------------------------- */

void storage_set_clock(storage_t *st, storage_clock_fn fn, void *ctx)
{
    st->clock = fn;
    st->clock_ctx = ctx;
}

int storage_is_postgres(const char *target) { return sqldb_is_postgres_uri(target); }

int storage_lock_name(storage_t *st, const char *name, err_t *err)
{
    if (!st || !name) return err_set(err, -EINVAL, "lock: NULL argument");
    if (sqldb_dialect(st->db) != SQLDB_POSTGRES)
        return err_set(err, -ENOTSUP, "a named lock is a shared database's");
    sqldb_stmt_t *s = NULL;
    int rc = sqldb_prepare(st->db, stg_pg_lock_name, 0, &s), ret = 0;
    if (rc == SQLDB_OK) rc = sqldb_bind_text(s, 1, name);
    if (rc == SQLDB_OK) rc = sqldb_step(s);
    if (rc == SQLDB_ROW)
        ret = sqldb_col_int64(s, 0) == 1   ? 0
              : sqldb_col_int64(s, 0) == 2 ? 1
                                           : err_set(err, -EBUSY, "%s is held by another connection",
                                                     name);
    else
        ret = stg_error(st, rc == SQLDB_DONE ? SQLDB_ERROR : rc, err, "taking a named lock");
    sqldb_finalize(s);
    return ret;
}

int storage_set_claimant(storage_t *st, const char *name)
{
    if (!st || (name && !*name)) return -EINVAL;
    char *copy = name ? strdup(name) : NULL;
    if (name && !copy) return -ENOMEM;
    free(st->claimant);
    st->claimant = copy;
    return 0;
}

int64_t storage_now_ms(storage_t *st)
{
    if (st->clock) return st->clock(st->clock_ctx);
    return clock_wall_ms();
}

int storage_set_busy_timeout(storage_t *st, int ms, err_t *err)
{
    if (!st || ms < 0) return err_set(err, -EINVAL, "busy timeout: need a handle and ms >= 0");
    int rc = sqldb_busy_timeout(st->db, ms);
    return rc == SQLDB_OK ? 0 : stg_error(st, rc, err, "setting the busy timeout");
}

/* ---- BLOB codecs: little-endian whatever the host (docs/schema.md) ------------------------ */

unsigned char *stg_blob_from_f64(const double *v, size_t n)
{
    unsigned char *b = malloc(n ? n * 8 : 1);
    for (size_t i = 0; b && i < n; i++) le_put_f64(b + 8 * i, v[i]);
    return b;
}

unsigned char *stg_blob_from_u16(const uint16_t *v, size_t n)
{
    unsigned char *b = malloc(n ? n * 2 : 1);
    for (size_t i = 0; b && i < n; i++) le_put_u16(b + 2 * i, v[i]);
    return b;
}

double *stg_f64_from_blob(const void *blob, size_t bytes, size_t n, int *bad)
{
    *bad = bytes != n * 8 || (n && !blob);
    if (*bad) return NULL;
    double *v = malloc(n ? n * sizeof *v : 1);
    for (size_t i = 0; v && i < n; i++) v[i] = le_get_f64((const unsigned char *)blob + 8 * i);
    return v;
}

uint16_t *stg_u16_from_blob(const void *blob, size_t bytes, size_t n, int *bad)
{
    *bad = bytes != n * 2 || (n && !blob);
    if (*bad) return NULL;
    const unsigned char *p = blob;
    uint16_t *v = malloc(n ? n * sizeof *v : 1);
    for (size_t i = 0; v && i < n; i++) v[i] = le_get_u16(p + 2 * i);
    return v;
}

/* ---- open, migrate, close ----------------------------------------------------------------- */

static int user_version(storage_t *st, int *v, err_t *err)
{
    sqldb_stmt_t *s;
    int ret = stg_stmt(st, STG_USER_VERSION, &s, err);
    if (ret) return ret;
    ret = stg_row(st, s, err, "reading user_version");
    if (ret == 0) *v = sqldb_col_int(s, 0);
    stg_reset(s);
    return ret == -ENOENT ? err_set(err, -EIO, "reading user_version: no row") : ret;
}

/* Applies migration `to` (bringing to - 1 to to) unless another connection did it meanwhile.
 * A PostgreSQL database begins at the current schema: its migrations before the last are NULL,
 * and only step the version. */
static int migrate_one(storage_t *st, int to, err_t *err)
{
    int pg = sqldb_dialect(st->db) == SQLDB_POSTGRES;
    int ret = stg_begin_write(st, err), v = -1;
    if (ret) return ret;
    if ((ret = user_version(st, &v, err))) goto out;
    if (v > stg_n_migrations)
        ret = err_set(err, -ENOTSUP, "schema version %d appeared meanwhile, newer than %d", v,
                      stg_n_migrations);
    if (ret || v >= to) goto out; /* done by another process between our check and our lock */
    const char *sql = pg ? stg_pg_migrations[to - 1] : stg_migrations[to - 1];
    char step[64];
    if (!sql) {
        snprintf(step, sizeof step, "UPDATE ipsd_schema SET version = %d", to);
        sql = step;
    }
    int rc = sqldb_exec(st->db, sql);
    if (rc != SQLDB_OK) {
        ret = err_set(err, -EIO, "migration %d: %s", to, sqldb_errmsg(st->db));
        goto out;
    }
    if ((ret = user_version(st, &v, err))) goto out;
    if (v != to) ret = err_set(err, -EIO, "migration %d left user_version %d", to, v);
out:
    if (ret) {
        stg_rollback(st);
        return ret;
    }
    return stg_commit(st, err);
}

/* Refuses a schema this code does not know; *v gets the database's version. Only reads. */
static int check_version(storage_t *st, const char *path, int *v_out, err_t *err)
{
    int v = 0, ret = user_version(st, &v, err);
    if (ret) {
        err_t inner = {{0}};
        if (err) memcpy(&inner, err, sizeof inner);
        return err_set(err, ret, "database %s: %s", path, inner.msg);
    }
    if (v > stg_n_migrations)
        return err_set(err, -ENOTSUP,
                       "database %s has schema version %d, newer than this ipsd knows (%d): "
                       "use a newer ipsd",
                       path, v, stg_n_migrations);
    if (v < 0) return err_set(err, -EIO, "database %s has a negative schema version %d", path, v);
    *v_out = v;
    return 0;
}

static int migrate(storage_t *st, int v, err_t *err)
{
    int ret = 0;
    for (int to = v + 1; to <= stg_n_migrations; to++)
        if ((ret = migrate_one(st, to, err))) return ret;
    return 0;
}

/* Runs a constant statement and checks the single-row answer when want is not NULL. */
static int pragma(storage_t *st, const char *sql, const char *want, err_t *err)
{
    sqldb_stmt_t *s = NULL;
    int rc = sqldb_prepare(st->db, sql, 0, &s);
    if (rc != SQLDB_OK) return stg_error(st, rc, err, sql);
    rc = sqldb_step(s);
    int ret = 0;
    if (rc != SQLDB_ROW && rc != SQLDB_DONE) {
        ret = stg_error(st, rc, err, sql);
    } else if (want) {
        const char *got = rc == SQLDB_ROW ? sqldb_col_text(s, 0) : NULL;
        if (!got || strcmp(got, want) != 0)
            ret = err_set(err, -EIO, "%s: got '%s', need '%s'", sql, got ? got : "nothing", want);
    }
    sqldb_finalize(s);
    return ret;
}

/* After migrations: every foreign key must hold (PRAGMA foreign_key_check returns no row). */
static int fk_check(storage_t *st, err_t *err)
{
    sqldb_stmt_t *s = NULL;
    int rc = sqldb_prepare(st->db, "PRAGMA foreign_key_check", 0, &s);
    if (rc != SQLDB_OK) return stg_error(st, rc, err, "PRAGMA foreign_key_check");
    rc = sqldb_step(s);
    int ret = 0;
    if (rc == SQLDB_ROW)
        ret = err_set(err, -EIO, "after migrating: table %s row %lld breaks a foreign key to %s",
                      sqldb_col_text(s, 0), (long long)sqldb_col_int64(s, 1),
                      sqldb_col_text(s, 2));
    else if (rc != SQLDB_DONE)
        ret = stg_error(st, rc, err, "PRAGMA foreign_key_check");
    sqldb_finalize(s);
    return ret;
}

int storage_process_setup(void) { return sqldb_process_setup(); }

/* SQLite: the version check comes first: a database we refuse is not even switched to WAL.
 * Migrations run with foreign keys off (a table rebuild drops a referenced table, SQLite's
 * documented procedure); the keys are checked (no row may violate them) and turned on after. */
static int open_sqlite(storage_t *st, const char *path, err_t *err)
{
    int v = 0, ret;
    if ((ret = pragma(st, "PRAGMA foreign_keys = OFF", NULL, err)) ||
        (ret = check_version(st, path, &v, err)) ||
        (ret = pragma(st, "PRAGMA journal_mode = WAL", "wal", err)) ||
        (ret = pragma(st, "PRAGMA synchronous = FULL", NULL, err)) ||
        (ret = migrate(st, v, err)) ||
        (v < stg_n_migrations && (ret = fk_check(st, err))) ||
        (ret = pragma(st, "PRAGMA foreign_keys = ON", NULL, err)))
        return ret;
    return pragma(st, "PRAGMA foreign_keys", "1", err);
}

/* PostgreSQL: the version table is made first (in one locked transaction, so that two ipsd
 * starting on a new database do not both make it), then the version is checked and migrated. */
static int open_postgres(storage_t *st, const char *uri, err_t *err)
{
    int v = 0, ret;
    if (sqldb_exec(st->db, stg_pg_bootstrap) != SQLDB_OK)
        return err_set(err, -EIO, "database %s: cannot make its version table: %s", uri,
                       sqldb_errmsg(st->db));
    if ((ret = check_version(st, uri, &v, err))) return ret;
    return migrate(st, v, err);
}

int storage_open(const char *path, storage_t **out, err_t *err)
{
    if (!out) return err_set(err, -EINVAL, "storage_open: out is NULL");
    *out = NULL;
    if (!path || !*path) return err_set(err, -EINVAL, "storage_open: no database path");
    storage_t *st = calloc(1, sizeof *st);
    if (!st) return err_set(err, -ENOMEM, "storage_open: out of memory");
    int ret = sqldb_open(path, 0, &st->db, err), rc;
    if (ret) goto out;
    if ((rc = sqldb_busy_timeout(st->db, STG_BUSY_TIMEOUT_MS)) != SQLDB_OK) {
        ret = stg_error(st, rc, err, sqldb_name(st->db));
        goto out;
    }
    ret = sqldb_dialect(st->db) == SQLDB_POSTGRES ? open_postgres(st, sqldb_name(st->db), err)
                                                   : open_sqlite(st, path, err);
out:
    if (ret) {
        storage_close(st);
        return ret;
    }
    *out = st;
    return 0;
}

int storage_open_readonly(const char *path, storage_t **out, err_t *err)
{
    if (!out) return err_set(err, -EINVAL, "storage_open_readonly: out is NULL");
    *out = NULL;
    if (!path || !*path) return err_set(err, -EINVAL, "storage_open_readonly: no database path");
    if (sqldb_is_postgres_uri(path))
        return err_set(err, -ENOTSUP, "a read-only open is for an SQLite file, not a PostgreSQL "
                                      "database");
    storage_t *st = calloc(1, sizeof *st);
    if (!st) return err_set(err, -ENOMEM, "storage_open_readonly: out of memory");
    int ret = 0, v = 0, tables = 0, rc;
    /* read-only and never created: nothing is written to the file, not even its journal mode */
    if ((ret = sqldb_sqlite_open(path, 1, &st->db, err))) goto out;
    if ((rc = sqldb_busy_timeout(st->db, STG_BUSY_TIMEOUT_MS)) != SQLDB_OK) {
        ret = err_set(err, -EIO, "cannot open database %s: %s", path, sqldb_errmsg(st->db));
        goto out;
    }
    sqldb_stmt_t *s = NULL;
    rc = sqldb_prepare(st->db,
                       "SELECT (SELECT user_version FROM pragma_user_version), "
                       "(SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN "
                       "('sensors', 'scans', 'frames', 'jobs'))",
                       0, &s);
    if (rc == SQLDB_OK && (rc = sqldb_step(s)) == SQLDB_ROW) {
        v = sqldb_col_int(s, 0);
        tables = sqldb_col_int(s, 1);
        rc = SQLDB_OK;
    }
    sqldb_finalize(s);
    if (rc == SQLDB_NOTADB)
        ret = err_set(err, -EINVAL, "%s is not an SQLite database", path);
    else if (rc != SQLDB_OK)
        ret = err_set(err, -EIO, "reading database %s: %s", path, sqldb_errmsg(st->db));
    else if (v > stg_n_migrations)
        ret = err_set(err, -ENOTSUP,
                      "database %s has schema version %d, newer than this ipsd knows (%d): "
                      "use a newer ipsd",
                      path, v, stg_n_migrations);
    else if (v < 1 || tables != 4)
        ret = err_set(err, -EINVAL,
                      "%s is not an ipsd database (schema version %d, %d of its 4 first tables)",
                      path, v, tables);
out:
    if (ret) {
        storage_close(st);
        return ret;
    }
    *out = st;
    return 0;
}

int storage_checkpoint(storage_t *st, err_t *err)
{
    if (!st) return err_set(err, -EINVAL, "checkpoint: NULL handle");
    int rc = sqldb_checkpoint(st->db);
    if (rc == SQLDB_BUSY) return err_set(err, -EBUSY, "checkpointing the write-ahead log: busy");
    return rc == SQLDB_OK ? 0 : stg_error(st, rc, err, "checkpointing the write-ahead log");
}

void storage_close(storage_t *st)
{
    if (!st) return;
    stg_gate_leave(st); /* a transaction left open is rolled back by the close */
    for (int i = 0; i < STG_N; i++) sqldb_finalize(st->stmt[i]);
    sqldb_close(st->db);
    free(st->claimant);
    free(st);
}
