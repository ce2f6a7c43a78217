/* srv_backup.c: online backups of the running server's database into --backup-dir
 * (srv_backup, srv.h): names the file, lets one backup run at a time, and stops a backup when
 * the server stops. The copying itself is storage's (storage_backup); a PostgreSQL database is
 * pg_dump's, and is refused here. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "srv_int.h"

/* Between the backup's steps: a stopping server ends it. */
static int keep_going(void *ctx, int remaining, int total)
{
    (void)remaining;
    (void)total;
    return srv_stopping(ctx);
}

int srv_backup(srv_t *srv, storage_t *st, char *name, size_t n, storage_backup_info_t *info,
               err_t *err)
{
    const srv_config_t *cfg = &srv->cfg;
    /* with or without --backup-dir: the directory would not help */
    if (storage_is_postgres(cfg->db_path))
        return err_set(err, -ENOTSUP, "backups through ipsd copy an SQLite database; a "
                                      "PostgreSQL database is backed up with pg_dump "
                                      "(docs/operations.md)");
    if (!cfg->backup_dir[0])
        return err_set(err, -ENOTSUP, "backups are off: start ipsd with --backup-dir DIR");
    if (srv_stopping(srv)) return err_set(err, -ESHUTDOWN, "ipsd is shutting down");
    if (atomic_exchange(&srv->backup_running, 1))
        return err_set(err, -EBUSY, "a backup is running already; try again when it is done");
    char stamp[32], path[SRV_PATH_MAX + 64];
    time_t now = time(NULL);
    struct tm tm;
    strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", gmtime_r(&now, &tm));
    int ret = -EEXIST;
    for (int i = 1; ret == -EEXIST && i <= 100; i++) {
        if (i == 1)
            snprintf(name, n, "ipsd-backup-%s.db", stamp);
        else
            snprintf(name, n, "ipsd-backup-%s-%d.db", stamp, i);
        snprintf(path, sizeof path, "%s/%s", cfg->backup_dir, name);
        struct stat sb;
        if (stat(path, &sb) == 0) continue; /* taken: the next suffix */
        ret = storage_backup(st, path, 0, keep_going, srv, info, err);
    }
    atomic_store(&srv->backup_running, 0);
    if (ret == -ECANCELED) return err_set(err, -ESHUTDOWN, "ipsd is shutting down");
    return ret;
}
