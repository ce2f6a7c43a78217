/* storage_sql_pg.h: PostgreSQL's SQL texts (storage_sql_pg.c), private to storage/: its version
 * table's bootstrap, its schema migrations and its text of the statements whose SQLite text
 * (storage_sql.c) it does not run. */
#ifndef IPSD_STORAGE_SQL_PG_H
#define IPSD_STORAGE_SQL_PG_H

#include "storage_int.h"

/* Run (one string, one transaction) when a PostgreSQL database is opened, before its version is
 * read: makes the version table ipsd_schema of a new database, at version 0. */
extern const char *const stg_pg_bootstrap;
/* PostgreSQL's schema: stg_pg_migrations[i] brings version i to i + 1, like stg_migrations; a
 * PostgreSQL database begins at the current schema, so entries before the last are NULL (no
 * PostgreSQL database was ever at those versions) and the last creates every table. As many
 * entries as stg_migrations (stg_n_migrations). */
extern const char *const stg_pg_migrations[];
/* PostgreSQL's text of a statement whose SQLite text does not run there; NULL: the SQLite text
 * runs as it is once its ?N placeholders are written $N (the driver does that, in these texts
 * too; it also runs SQLite's two BEGINs its own way). */
extern const char *const stg_sql_pg[STG_N];

/* The channel of stored calibrations: sent inside the transaction that stores one (delivered
 * at its commit), heard by every ipsd on the database (storage_listen.c). */
extern const char *const stg_pg_notify;
extern const char *const stg_pg_listen;
/* storage_lock_name: a connection-held advisory lock of ?1 (a text) in the current schema, in the key
 * space of ipsd's write lock: 1 when this connection holds it already, 2 when it has just taken
 * it, 0 when another connection holds it */
extern const char *const stg_pg_lock_name;

#endif
