/* sqldb.c: which driver opens a database: a postgresql:// (or postgres://) URI is PostgreSQL's,
 * anything else an SQLite file. */
#include "sqldb.h"

#include <errno.h>
#include <string.h>

int sqldb_is_postgres_uri(const char *target)
{
    return target && (!strncmp(target, "postgresql://", 13) || !strncmp(target, "postgres://", 11));
}

int sqldb_open(const char *target, int readonly, sqldb_t **out, err_t *err)
{
    *out = NULL;
    if (!sqldb_is_postgres_uri(target)) return sqldb_sqlite_open(target, readonly, out, err);
    if (readonly)
        return err_set(err, -ENOTSUP,
                       "a read-only open is for an SQLite file, not a PostgreSQL "
                       "database");
    return sqldb_pg_open(target, out, err);
}
