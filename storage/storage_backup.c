/* storage_backup.c: an online backup of the database (storage.h, storage_backup) with SQLite's
 * backup API (sqlite3_backup_init / _step / _finish). The source connection holds one read
 * transaction for the whole copy, so the copy is the snapshot of that moment: in WAL mode a
 * reader blocks no writer, and the backup is not restarted by other connections' commits (it
 * would be, step after step, if every step began a new read transaction). The statements here
 * run on the backup's own destination connection, not through the statement cache. */
#include "storage_int.h"

#include <sqlite3.h>

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define BACKUP_PAGES_PER_STEP 256 /* 1 MiB of 4 KiB pages between two looks at the world */

/* The first column of the first row of sql on db, as text, into out (n bytes). */
static int first_text(sqlite3 *db, const char *sql, char *out, size_t n, err_t *err)
{
    sqlite3_stmt *s = NULL;
    int rc = sqlite3_prepare_v2(db, sql, -1, &s, NULL);
    if (rc == SQLITE_OK) rc = sqlite3_step(s);
    if (rc == SQLITE_ROW) {
        const unsigned char *t = sqlite3_column_text(s, 0);
        snprintf(out, n, "%s", t ? (const char *)t : "");
        rc = SQLITE_OK;
    }
    int ret = rc == SQLITE_OK || rc == SQLITE_DONE
                  ? 0
                  : err_set(err, rc == SQLITE_FULL ? -ENOSPC : -EIO, "backup: %s: %s", sql,
                            sqlite3_errmsg(db));
    sqlite3_finalize(s);
    return ret;
}

/* fsync of a file or a directory by path. */
static int sync_path(const char *path, int dir, err_t *err)
{
    int fd = open(path, (dir ? O_RDONLY | O_DIRECTORY : O_RDWR) | O_CLOEXEC);
    if (fd < 0 || fsync(fd) != 0) {
        int e = errno;
        if (fd >= 0) close(fd);
        return err_set(err, -e, "backup: syncing %s: %s", path, strerror(e));
    }
    close(fd);
    return 0;
}

/* Copies st's snapshot into the open destination dst; *pages gets the page count. */
static int copy_pages(storage_t *st, sqlite3 *dst, int per_step, storage_backup_step_fn step,
                      void *ctx, int *pages, err_t *err)
{
    sqlite3_backup *bk = sqlite3_backup_init(dst, "main", sqldb_sqlite_handle(st->db), "main");
    if (!bk) return err_set(err, -EIO, "backup: %s", sqlite3_errmsg(dst));
    int rc, ret = 0;
    while ((rc = sqlite3_backup_step(bk, per_step)) == SQLITE_OK || rc == SQLITE_BUSY ||
           rc == SQLITE_LOCKED) {
        if (rc != SQLITE_OK) sqlite3_sleep(5); /* a lock of the destination: a moment */
        if (step && step(ctx, sqlite3_backup_remaining(bk), sqlite3_backup_pagecount(bk))) {
            ret = err_set(err, -ECANCELED, "backup: stopped");
            break;
        }
    }
    *pages = sqlite3_backup_pagecount(bk);
    if (!ret && rc != SQLITE_DONE)
        ret = err_set(err, (rc & 0xff) == SQLITE_FULL ? -ENOSPC : -EIO, "backup: copying: %s",
                      sqlite3_errstr(rc));
    rc = sqlite3_backup_finish(bk);
    if (!ret && rc != SQLITE_OK)
        ret = err_set(err, (rc & 0xff) == SQLITE_FULL ? -ENOSPC : -EIO, "backup: finishing: %s",
                      sqlite3_errmsg(dst));
    return ret;
}

/* The copy in dst made a self-contained file and checked: journal_mode DELETE (the source's
 * header says WAL), PRAGMA integrity_check, user_version. */
static int check_copy(sqlite3 *dst, storage_backup_info_t *info, err_t *err)
{
    char mode[32], version[32];
    int ret = first_text(dst, "PRAGMA journal_mode=DELETE", mode, sizeof mode, err);
    if (!ret)
        ret =
            first_text(dst, "PRAGMA integrity_check", info->integrity, sizeof info->integrity, err);
    if (!ret && strcmp(info->integrity, "ok") != 0)
        ret = err_set(err, -EIO, "backup: the copy fails its integrity check: %s", info->integrity);
    if (!ret) ret = first_text(dst, "PRAGMA user_version", version, sizeof version, err);
    if (!ret) info->schema_version = atoi(version);
    return ret;
}

int storage_backup(storage_t *st, const char *dest, int pages_per_step, storage_backup_step_fn step,
                   void *ctx, storage_backup_info_t *info, err_t *err)
{
    char part[PATH_MAX];
    struct stat sb;
    sqlite3 *src = sqldb_sqlite_handle(st->db);
    if (!src)
        return err_set(err, -ENOTSUP, "backup: this copies an SQLite database; a PostgreSQL "
                                      "database is backed up with pg_dump (docs/operations.md)");
    if (snprintf(part, sizeof part, "%s.part", dest) >= (int)sizeof part)
        return err_set(err, -EINVAL, "backup: path too long: %s", dest);
    if (stat(dest, &sb) == 0) return err_set(err, -EEXIST, "backup: %s exists already", dest);
    int fd = open(part, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
    if (fd < 0) {
        int e = errno;
        return err_set(err, -e, "backup: cannot create %s: %s", part, strerror(e));
    }
    close(fd);
    storage_backup_info_t got = {0};
    sqlite3 *dst = NULL;
    int ret = 0, rc = sqlite3_open_v2(part, &dst, SQLITE_OPEN_READWRITE, NULL);
    if (rc != SQLITE_OK)
        ret = err_set(err, -EIO, "backup: opening %s: %s", part,
                      dst ? sqlite3_errmsg(dst) : sqlite3_errstr(rc));
    /* the snapshot: a read transaction held over every step (see the top of the file) */
    int in_txn = 0;
    char version[32];
    if (!ret && !(ret = stg_begin_read(st, err))) {
        in_txn = 1; /* BEGIN is deferred: the first read starts the transaction */
        ret = first_text(src, "PRAGMA user_version", version, sizeof version, err);
    }
    if (!ret)
        ret = copy_pages(st, dst, pages_per_step > 0 ? pages_per_step : BACKUP_PAGES_PER_STEP, step,
                         ctx, &got.pages, err);
    if (in_txn) stg_rollback(st); /* only read: ends the snapshot */
    if (!ret) ret = check_copy(dst, &got, err);
    if (dst && sqlite3_close(dst) != SQLITE_OK && !ret)
        ret = err_set(err, -EIO, "backup: closing %s", part);
    if (!ret) ret = sync_path(part, 0, err);
    /* link, not rename: never replaces a file that appeared meanwhile; rename where the file
     * system has no hard links */
    if (!ret && link(part, dest) != 0 &&
        !((errno == EPERM || errno == ENOTSUP) && stat(dest, &sb) != 0 &&
          rename(part, dest) == 0)) {
        int e = errno;
        ret = err_set(err, -e, "backup: cannot make %s: %s", dest, strerror(e));
    }
    unlink(part);
    /* a copy that failed (a full disk) leaves the destination's journal: a rollback journal, or
     * the log and index of WAL, the journal mode the copied header names until check_copy
     * switches it to DELETE */
    static const char *const journals[] = {"-journal", "-wal", "-shm"};
    for (int i = 0; i < 3; i++) {
        char j[PATH_MAX + 16];
        snprintf(j, sizeof j, "%s%s", part, journals[i]);
        unlink(j);
    }
    if (!ret && stat(dest, &sb) != 0) ret = err_set(err, -errno, "backup: %s vanished", dest);
    if (!ret) {
        char dir[PATH_MAX];
        snprintf(dir, sizeof dir, "%s", dest);
        char *slash = strrchr(dir, '/');
        if (slash == dir)
            slash[1] = 0;
        else if (slash)
            *slash = 0;
        else
            snprintf(dir, sizeof dir, ".");
        ret = sync_path(dir, 1, err);
    }
    if (!ret) {
        got.bytes = (int64_t)sb.st_size;
        if (info) *info = got;
    }
    return ret;
}
