/* sqldb.h: the database driver under storage/: a connection, statements prepared once with
 * numbered parameters (?1, ?2 ...), rows read column by column, and result codes that do not
 * depend on the database. The files of storage/ speak only this; sqldb_sqlite.c speaks SQLite
 * (a file, the embedded default) and sqldb_pg.c PostgreSQL (a postgresql:// URI, a database
 * several benches share). The SQL each one runs is chosen by storage_sql*.c, not here. */
#ifndef IPSD_STORAGE_SQLDB_H
#define IPSD_STORAGE_SQLDB_H

#include <stddef.h>
#include <stdint.h>

#include "base/err.h"

/* What a call did. The errors say why in a way storage.c maps to an errno and a fault. */
typedef enum {
    SQLDB_OK = 0,
    SQLDB_ROW,         /* step: a row is ready */
    SQLDB_DONE,        /* step: no (more) rows */
    SQLDB_BUSY,        /* another writer held the lock past the timeout */
    SQLDB_NOMEM,       /* out of memory */
    SQLDB_FULL,        /* the disk (or the database's size cap) is full */
    SQLDB_READONLY,    /* the database cannot be written */
    SQLDB_IOERR,       /* I/O error, corrupt file, lost connection */
    SQLDB_NOTADB,      /* the file is not a database of this driver */
    SQLDB_UNIQUE,      /* a UNIQUE or PRIMARY KEY constraint */
    SQLDB_FOREIGN_KEY, /* a FOREIGN KEY constraint */
    SQLDB_CONSTRAINT,  /* a CHECK or NOT NULL constraint */
    SQLDB_ERROR        /* anything else (an SQL error) */
} sqldb_rc_t;

typedef struct sqldb sqldb_t;
typedef struct sqldb_stmt sqldb_stmt_t;

/* Which SQL a driver runs: storage_sql.c's (SQLite) or storage_sql_pg.c's (PostgreSQL). */
typedef enum { SQLDB_SQLITE, SQLDB_POSTGRES } sqldb_dialect_t;

struct sqldb_ops {
    sqldb_dialect_t dialect;
    void (*close)(sqldb_t *db);
    sqldb_rc_t (*prepare)(sqldb_t *db, const char *sql, int persistent, sqldb_stmt_t **out);
    void (*finalize)(sqldb_stmt_t *s);
    void (*reset)(sqldb_stmt_t *s); /* back to before the first step, bindings cleared */
    sqldb_rc_t (*bind_null)(sqldb_stmt_t *s, int i);
    sqldb_rc_t (*bind_int64)(sqldb_stmt_t *s, int i, int64_t v);
    sqldb_rc_t (*bind_double)(sqldb_stmt_t *s, int i, double v);
    sqldb_rc_t (*bind_text)(sqldb_stmt_t *s, int i, const char *v);           /* copied */
    sqldb_rc_t (*bind_blob)(sqldb_stmt_t *s, int i, const void *v, size_t n); /* copied */
    sqldb_rc_t (*step)(sqldb_stmt_t *s);
    int (*readonly)(sqldb_stmt_t *s); /* the statement writes nothing */
    int (*col_null)(sqldb_stmt_t *s, int i);
    int64_t (*col_int64)(sqldb_stmt_t *s, int i);
    double (*col_double)(sqldb_stmt_t *s, int i);
    const char *(*col_text)(sqldb_stmt_t *s, int i); /* NULL for SQL NULL; valid until the
                                                      * next step or reset */
    const void *(*col_blob)(sqldb_stmt_t *s, int i); /* likewise */
    size_t (*col_bytes)(sqldb_stmt_t *s, int i);
    sqldb_rc_t (*exec)(sqldb_t *db, const char *sql); /* one or more statements, no rows */
    int64_t (*changes)(sqldb_t *db);                  /* rows the last statement changed */
    int64_t (*total_changes)(sqldb_t *db);            /* rows changed since the connection */
    int64_t (*last_insert_id)(sqldb_t *db);
    int (*in_transaction)(sqldb_t *db);
    const char *(*errmsg)(sqldb_t *db); /* the last error's words, from the database */
    const char *(*name)(sqldb_t *db);   /* the file, or the URI without its password */
    sqldb_rc_t (*busy_timeout)(sqldb_t *db, int ms);
    /* n bytes at offset of BLOB column `column` of table's row id (names: constants of the
     * code, never input) into buf */
    sqldb_rc_t (*blob_read)(sqldb_t *db, const char *table, const char *column, int64_t id,
                            size_t offset, size_t n, void *buf);
    /* SQLite: folds the write-ahead log into the file (SQLDB_BUSY: readers kept some of it);
     * PostgreSQL: nothing to do (the server checkpoints) */
    sqldb_rc_t (*checkpoint)(sqldb_t *db);
};

/* The common head of every driver's connection and statement. */
struct sqldb {
    const struct sqldb_ops *ops;
};
struct sqldb_stmt {
    const struct sqldb_ops *ops;
};

/* 1 when target names a PostgreSQL database (postgresql:// or postgres://), else 0 (a file). */
int sqldb_is_postgres_uri(const char *target);

/* Opens the database target names (sqldb_is_postgres_uri picks the driver) for reading and
 * writing (SQLite: created when missing), or only reading (SQLite only). 0, or a negative errno
 * with "cannot open database ...: why" in err; *out NULL then. */
int sqldb_open(const char *target, int readonly, sqldb_t **out, err_t *err);
int sqldb_sqlite_open(const char *path, int readonly, sqldb_t **out, err_t *err);
int sqldb_pg_open(const char *uri, sqldb_t **out, err_t *err);

/* Once per process, before any connection: SQLite's global settings. 0 or -EBUSY. */
int sqldb_process_setup(void);

/* The words SQLite gives rc, for errors made without a connection (the test hooks' faults). */
const char *sqldb_rc_text(sqldb_rc_t rc);

/* PostgreSQL's notifications, on a connection of sqldb_pg_open that ran LISTEN: waits up to
 * timeout_ms for the server to say something and returns how many notifications arrived whose
 * payload is not ignore (NULL: all; 0: none in that time), *ignored (NULL: not wanted) getting
 * how many that were, or -EIO when the connection is lost. -ENOTSUP on another driver. */
int sqldb_pg_wait_notify(sqldb_t *db, int timeout_ms, const char *ignore, int *ignored);

/* The SQLite connection under db (sqlite3 *), NULL for another driver: for what only SQLite
 * does (its online backup, WAL checkpoint, page counts). */
void *sqldb_sqlite_handle(sqldb_t *db);

static inline void sqldb_close(sqldb_t *db)
{
    if (db) db->ops->close(db);
}
static inline sqldb_rc_t sqldb_prepare(sqldb_t *db, const char *sql, int persistent,
                                       sqldb_stmt_t **out)
{
    return db->ops->prepare(db, sql, persistent, out);
}
static inline void sqldb_finalize(sqldb_stmt_t *s)
{
    if (s) s->ops->finalize(s);
}
static inline void sqldb_reset(sqldb_stmt_t *s)
{
    s->ops->reset(s);
}
static inline sqldb_rc_t sqldb_bind_null(sqldb_stmt_t *s, int i)
{
    return s->ops->bind_null(s, i);
}
static inline sqldb_rc_t sqldb_bind_int64(sqldb_stmt_t *s, int i, int64_t v)
{
    return s->ops->bind_int64(s, i, v);
}
static inline sqldb_rc_t sqldb_bind_double(sqldb_stmt_t *s, int i, double v)
{
    return s->ops->bind_double(s, i, v);
}
static inline sqldb_rc_t sqldb_bind_text(sqldb_stmt_t *s, int i, const char *v)
{
    return s->ops->bind_text(s, i, v);
}
static inline sqldb_rc_t sqldb_bind_blob(sqldb_stmt_t *s, int i, const void *v, size_t n)
{
    return s->ops->bind_blob(s, i, v, n);
}
static inline sqldb_rc_t sqldb_step(sqldb_stmt_t *s)
{
    return s->ops->step(s);
}
static inline int sqldb_readonly(sqldb_stmt_t *s)
{
    return s->ops->readonly(s);
}
static inline int sqldb_col_null(sqldb_stmt_t *s, int i)
{
    return s->ops->col_null(s, i);
}
static inline int64_t sqldb_col_int64(sqldb_stmt_t *s, int i)
{
    return s->ops->col_int64(s, i);
}
static inline int sqldb_col_int(sqldb_stmt_t *s, int i)
{
    return (int)s->ops->col_int64(s, i);
}
static inline double sqldb_col_double(sqldb_stmt_t *s, int i)
{
    return s->ops->col_double(s, i);
}
static inline const char *sqldb_col_text(sqldb_stmt_t *s, int i)
{
    return s->ops->col_text(s, i);
}
static inline const void *sqldb_col_blob(sqldb_stmt_t *s, int i)
{
    return s->ops->col_blob(s, i);
}
static inline size_t sqldb_col_bytes(sqldb_stmt_t *s, int i)
{
    return s->ops->col_bytes(s, i);
}
static inline sqldb_rc_t sqldb_exec(sqldb_t *db, const char *sql)
{
    return db->ops->exec(db, sql);
}
static inline int64_t sqldb_changes(sqldb_t *db)
{
    return db->ops->changes(db);
}
static inline int64_t sqldb_total_changes(sqldb_t *db)
{
    return db->ops->total_changes(db);
}
static inline int64_t sqldb_last_insert_id(sqldb_t *db)
{
    return db->ops->last_insert_id(db);
}
static inline int sqldb_in_transaction(sqldb_t *db)
{
    return db->ops->in_transaction(db);
}
static inline const char *sqldb_errmsg(sqldb_t *db)
{
    return db->ops->errmsg(db);
}
static inline const char *sqldb_name(sqldb_t *db)
{
    return db->ops->name(db);
}
static inline sqldb_dialect_t sqldb_dialect(sqldb_t *db)
{
    return db->ops->dialect;
}
static inline sqldb_rc_t sqldb_busy_timeout(sqldb_t *db, int ms)
{
    return db->ops->busy_timeout(db, ms);
}
static inline sqldb_rc_t sqldb_checkpoint(sqldb_t *db)
{
    return db->ops->checkpoint(db);
}
static inline sqldb_rc_t sqldb_blob_read(sqldb_t *db, const char *table, const char *column,
                                         int64_t id, size_t offset, size_t n, void *buf)
{
    return db->ops->blob_read(db, table, column, id, offset, n, buf);
}

#endif
