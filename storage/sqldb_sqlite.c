/* sqldb_sqlite.c: the SQLite driver of sqldb.h, the embedded default: one database file,
 * multi-thread mode (one connection per thread), extended result codes mapped to sqldb_rc_t. */
#include "sqldb.h"

#include <errno.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    struct sqldb base;
    sqlite3 *db;
} lite_t;

typedef struct {
    struct sqldb_stmt base;
    sqlite3_stmt *s;
} lite_stmt_t;

static sqlite3 *DB(sqldb_t *db)
{
    return ((lite_t *)db)->db;
}
static sqlite3_stmt *ST(sqldb_stmt_t *s)
{
    return ((lite_stmt_t *)s)->s;
}

/* An SQLite (extended) result code as a driver-neutral one. */
static sqldb_rc_t map_rc(int rc)
{
    switch (rc & 0xff) {
    case SQLITE_OK:
        return SQLDB_OK;
    case SQLITE_ROW:
        return SQLDB_ROW;
    case SQLITE_DONE:
        return SQLDB_DONE;
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
        return SQLDB_BUSY;
    case SQLITE_NOMEM:
        return SQLDB_NOMEM;
    case SQLITE_FULL:
        return SQLDB_FULL;
    case SQLITE_READONLY:
        return SQLDB_READONLY;
    case SQLITE_NOTADB:
        return SQLDB_NOTADB;
    case SQLITE_IOERR:
    case SQLITE_CORRUPT:
    case SQLITE_CANTOPEN:
        return SQLDB_IOERR;
    case SQLITE_CONSTRAINT:
        if (rc == SQLITE_CONSTRAINT_UNIQUE || rc == SQLITE_CONSTRAINT_PRIMARYKEY)
            return SQLDB_UNIQUE;
        if (rc == SQLITE_CONSTRAINT_FOREIGNKEY) return SQLDB_FOREIGN_KEY;
        return SQLDB_CONSTRAINT;
    default:
        return SQLDB_ERROR;
    }
}

const char *sqldb_rc_text(sqldb_rc_t rc)
{
    static const int lite[] = {
        [SQLDB_OK] = SQLITE_OK,
        [SQLDB_ROW] = SQLITE_ROW,
        [SQLDB_DONE] = SQLITE_DONE,
        [SQLDB_BUSY] = SQLITE_BUSY,
        [SQLDB_NOMEM] = SQLITE_NOMEM,
        [SQLDB_FULL] = SQLITE_FULL,
        [SQLDB_READONLY] = SQLITE_READONLY,
        [SQLDB_IOERR] = SQLITE_IOERR,
        [SQLDB_NOTADB] = SQLITE_NOTADB,
        [SQLDB_UNIQUE] = SQLITE_CONSTRAINT,
        [SQLDB_FOREIGN_KEY] = SQLITE_CONSTRAINT,
        [SQLDB_CONSTRAINT] = SQLITE_CONSTRAINT,
        [SQLDB_ERROR] = SQLITE_ERROR,
    };
    return sqlite3_errstr((unsigned)rc < sizeof lite / sizeof *lite ? lite[rc] : SQLITE_ERROR);
}

static void lite_close(sqldb_t *db)
{
    sqlite3_close_v2(DB(db)); /* frees once nothing is pending */
    free(db);
}

static sqldb_rc_t lite_prepare(sqldb_t *db, const char *sql, int persistent, sqldb_stmt_t **out)
{
    *out = NULL;
    lite_stmt_t *s = calloc(1, sizeof *s);
    if (!s) return SQLDB_NOMEM;
    s->base.ops = db->ops;
    int rc = sqlite3_prepare_v3(DB(db), sql, -1, persistent ? SQLITE_PREPARE_PERSISTENT : 0, &s->s,
                                NULL);
    if (rc != SQLITE_OK) {
        free(s);
        return map_rc(rc);
    }
    *out = &s->base;
    return SQLDB_OK;
}

static void lite_finalize(sqldb_stmt_t *s)
{
    sqlite3_finalize(ST(s));
    free(s);
}

static void lite_reset(sqldb_stmt_t *s)
{
    /* reset returns the error of the last step, which the caller has handled already */
    (void)sqlite3_reset(ST(s));
    (void)sqlite3_clear_bindings(ST(s));
}

static sqldb_rc_t lite_bind_null(sqldb_stmt_t *s, int i)
{
    return map_rc(sqlite3_bind_null(ST(s), i));
}
static sqldb_rc_t lite_bind_int64(sqldb_stmt_t *s, int i, int64_t v)
{
    return map_rc(sqlite3_bind_int64(ST(s), i, v));
}
static sqldb_rc_t lite_bind_double(sqldb_stmt_t *s, int i, double v)
{
    return map_rc(sqlite3_bind_double(ST(s), i, v));
}
static sqldb_rc_t lite_bind_text(sqldb_stmt_t *s, int i, const char *v)
{
    return map_rc(sqlite3_bind_text(ST(s), i, v, -1, SQLITE_TRANSIENT));
}
static sqldb_rc_t lite_bind_blob(sqldb_stmt_t *s, int i, const void *v, size_t n)
{
    return map_rc(sqlite3_bind_blob64(ST(s), i, v, n, SQLITE_TRANSIENT));
}
static sqldb_rc_t lite_step(sqldb_stmt_t *s)
{
    return map_rc(sqlite3_step(ST(s)));
}
static int lite_readonly(sqldb_stmt_t *s)
{
    return sqlite3_stmt_readonly(ST(s));
}
static int lite_col_null(sqldb_stmt_t *s, int i)
{
    return sqlite3_column_type(ST(s), i) == SQLITE_NULL;
}
static int64_t lite_col_int64(sqldb_stmt_t *s, int i)
{
    return sqlite3_column_int64(ST(s), i);
}
static double lite_col_double(sqldb_stmt_t *s, int i)
{
    return sqlite3_column_double(ST(s), i);
}
static const char *lite_col_text(sqldb_stmt_t *s, int i)
{
    return (const char *)sqlite3_column_text(ST(s), i);
}
static const void *lite_col_blob(sqldb_stmt_t *s, int i)
{
    return sqlite3_column_blob(ST(s), i);
}
static size_t lite_col_bytes(sqldb_stmt_t *s, int i)
{
    return (size_t)sqlite3_column_bytes(ST(s), i);
}
static sqldb_rc_t lite_exec(sqldb_t *db, const char *sql)
{
    return map_rc(sqlite3_exec(DB(db), sql, NULL, NULL, NULL));
}
static int64_t lite_changes(sqldb_t *db)
{
    return sqlite3_changes64(DB(db));
}
static int64_t lite_total_changes(sqldb_t *db)
{
    return sqlite3_total_changes64(DB(db));
}
static int64_t lite_last_insert_id(sqldb_t *db)
{
    return sqlite3_last_insert_rowid(DB(db));
}
static int lite_in_transaction(sqldb_t *db)
{
    return !sqlite3_get_autocommit(DB(db));
}
static const char *lite_errmsg(sqldb_t *db)
{
    return sqlite3_errmsg(DB(db));
}
static const char *lite_name(sqldb_t *db)
{
    const char *f = sqlite3_db_filename(DB(db), "main");
    return f && *f ? f : "?";
}
static sqldb_rc_t lite_busy_timeout(sqldb_t *db, int ms)
{
    return map_rc(sqlite3_busy_timeout(DB(db), ms));
}

/* Incremental BLOB I/O: only the pages holding the bytes asked for are read. */
static sqldb_rc_t lite_blob_read(sqldb_t *db, const char *table, const char *column, int64_t id,
                                 size_t offset, size_t n, void *buf)
{
    sqlite3_blob *b = NULL;
    int rc = sqlite3_blob_open(DB(db), "main", table, column, id, 0, &b);
    if (rc == SQLITE_OK) rc = sqlite3_blob_read(b, buf, (int)n, (int)offset);
    sqlite3_blob_close(b);
    return map_rc(rc);
}

static sqldb_rc_t lite_checkpoint(sqldb_t *db)
{
    return map_rc(sqlite3_wal_checkpoint_v2(DB(db), NULL, SQLITE_CHECKPOINT_TRUNCATE, NULL, NULL));
}

int sqldb_process_setup(void)
{
    return sqlite3_config(SQLITE_CONFIG_MEMSTATUS, 0) == SQLITE_OK ? 0 : -EBUSY;
}

static const struct sqldb_ops lite_ops = {
    .dialect = SQLDB_SQLITE,
    .close = lite_close,
    .prepare = lite_prepare,
    .finalize = lite_finalize,
    .reset = lite_reset,
    .bind_null = lite_bind_null,
    .bind_int64 = lite_bind_int64,
    .bind_double = lite_bind_double,
    .bind_text = lite_bind_text,
    .bind_blob = lite_bind_blob,
    .step = lite_step,
    .readonly = lite_readonly,
    .col_null = lite_col_null,
    .col_int64 = lite_col_int64,
    .col_double = lite_col_double,
    .col_text = lite_col_text,
    .col_blob = lite_col_blob,
    .col_bytes = lite_col_bytes,
    .exec = lite_exec,
    .changes = lite_changes,
    .total_changes = lite_total_changes,
    .last_insert_id = lite_last_insert_id,
    .in_transaction = lite_in_transaction,
    .errmsg = lite_errmsg,
    .name = lite_name,
    .busy_timeout = lite_busy_timeout,
    .blob_read = lite_blob_read,
    .checkpoint = lite_checkpoint,
};

void *sqldb_sqlite_handle(sqldb_t *db)
{
    return db && db->ops == &lite_ops ? DB(db) : NULL;
}

int sqldb_sqlite_open(const char *path, int readonly, sqldb_t **out, err_t *err)
{
    *out = NULL;
    lite_t *l = calloc(1, sizeof *l);
    if (!l) return err_set(err, -ENOMEM, "cannot open database %s: out of memory", path);
    l->base.ops = &lite_ops;
    /* multi-thread mode: one handle per thread (storage.h); read-only is never created */
    int flags = readonly ? SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX
                         : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
    int rc = sqlite3_open_v2(path, &l->db, flags, NULL);
    if (rc == SQLITE_OK) rc = sqlite3_extended_result_codes(l->db, 1);
    if (rc != SQLITE_OK) {
        int ret = err_set(err, rc == SQLITE_NOMEM ? -ENOMEM : -EIO, "cannot open database %s: %s",
                          path, l->db ? sqlite3_errmsg(l->db) : sqlite3_errstr(rc));
        lite_close(&l->base);
        return ret;
    }
    *out = &l->base;
    return 0;
}
