/* test_storage_backup.c: storage_backup against real SQLite files in a mkdtemp directory: the
 * copy is the snapshot of the moment the backup began although another connection commits
 * between its steps (and is not restarted by that commit: the pages left only go down), it is a
 * self-contained, integrity-checked file read back by a raw SQLite connection, a stopped backup
 * leaves no file, and an existing destination is refused. */
#define _GNU_SOURCE /* mkdtemp under -std=c11 */
#include <errno.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "check.h"
#include "storage/storage.h"

#define N_SENSORS 400

static char tmpdir[512];

static const char *path_of(const char *name)
{
    static char buf[4][1024];
    static int next;
    char *p = buf[next++ % 4];
    snprintf(p, sizeof buf[0], "%s/%s", tmpdir, name);
    return p;
}

static int add_sensor(storage_t *st, int i)
{
    char model[256], serial[32];
    memset(model, 'M', 200); /* long rows: the database spans many pages */
    snprintf(model + 200, sizeof model - 200, "-%d", i);
    snprintf(serial, sizeof serial, "s%d", i);
    storage_sensor_t s = {.model = model,
                          .serial = serial,
                          .n_cols = 64,
                          .n_rows = 64,
                          .pitch_um = 3.0,
                          .gain_e_per_dn = 1.0,
                          .read_noise_e = 2.0,
                          .bias_dn = 100,
                          .full_scale_dn = 4095};
    int64_t id;
    return storage_sensor_create(st, &s, &id, NULL);
}

/* A raw connection's answer to a one-value query, as text. */
static void query(const char *db_path, const char *sql, char *out, size_t n)
{
    sqlite3 *db = NULL;
    sqlite3_stmt *s = NULL;
    out[0] = 0;
    if (sqlite3_open_v2(db_path, &db, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK &&
        sqlite3_prepare_v2(db, sql, -1, &s, NULL) == SQLITE_OK && sqlite3_step(s) == SQLITE_ROW)
        snprintf(out, n, "%s", (const char *)sqlite3_column_text(s, 0));
    sqlite3_finalize(s);
    sqlite3_close(db);
}

typedef struct {
    storage_t *writer; /* commits through another connection during the backup */
    int calls, restarted, last_remaining, stop_at;
} probe_t;

static int probe(void *ctx, int remaining, int total)
{
    probe_t *p = ctx;
    (void)total;
    if (p->calls > 0 && remaining >= p->last_remaining) p->restarted = 1;
    p->last_remaining = remaining;
    p->calls++;
    static int next = N_SENSORS; /* the ids after the first N_SENSORS */
    if (p->calls == 1 || p->calls == 5) CHECK(add_sensor(p->writer, next++) == 0); /* mid-backup */
    return p->stop_at && p->calls >= p->stop_at;
}

int main(void)
{
    const char *base = getenv("TMPDIR");
    snprintf(tmpdir, sizeof tmpdir, "%s/ipsd-test-backup-XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(tmpdir)) return 1;
    storage_t *st = NULL, *w = NULL;
    err_t err = {{0}};
    CHECK(storage_open(path_of("live.db"), &st, &err) == 0);
    CHECK(storage_open(path_of("live.db"), &w, &err) == 0);
    for (int i = 0; i < N_SENSORS; i++)
        CHECK(add_sensor(w, i) == 0);

    /* one page a step; two commits of the other connection in between */
    probe_t p = {.writer = w};
    storage_backup_info_t info;
    CHECK(storage_backup(st, path_of("copy.db"), 1, probe, &p, &info, &err) == 0);
    CHECK(info.pages > 20 && p.calls >= info.pages - 1 && !p.restarted);
    CHECK(strcmp(info.integrity, "ok") == 0 && info.schema_version == storage_schema_version());
    struct stat sb;
    CHECK(stat(path_of("copy.db"), &sb) == 0 && sb.st_size == info.bytes);
    CHECK(stat(path_of("copy.db.part"), &sb) != 0);
    char v[64];
    query(path_of("copy.db"), "SELECT count(*) FROM sensors", v, sizeof v);
    CHECK(atoi(v) == N_SENSORS); /* the snapshot: neither mid-backup commit */
    query(path_of("live.db"), "SELECT count(*) FROM sensors", v, sizeof v);
    CHECK(atoi(v) == N_SENSORS + 2);
    query(path_of("copy.db"), "PRAGMA integrity_check", v, sizeof v);
    CHECK(strcmp(v, "ok") == 0);
    query(path_of("copy.db"), "PRAGMA journal_mode", v, sizeof v);
    CHECK(strcmp(v, "delete") == 0);
    query(path_of("copy.db"), "SELECT serial FROM sensors ORDER BY id DESC LIMIT 1", v, sizeof v);
    char want[32];
    snprintf(want, sizeof want, "s%d", N_SENSORS - 1);
    CHECK(strcmp(v, want) == 0);

    /* the destination exists: refused, the file untouched */
    CHECK(storage_backup(st, path_of("copy.db"), 0, NULL, NULL, &info, &err) == -EEXIST);
    CHECK(stat(path_of("copy.db"), &sb) == 0 && sb.st_size > 0);

    /* stopped by the step function: no file left */
    probe_t stop = {.writer = w, .stop_at = 3};
    CHECK(storage_backup(st, path_of("stopped.db"), 1, probe, &stop, &info, &err) == -ECANCELED);
    CHECK(stat(path_of("stopped.db"), &sb) != 0 && stat(path_of("stopped.db.part"), &sb) != 0);

    /* the handle is usable afterwards (the snapshot ended) and sees the new rows */
    storage_sensor_list_t l = {0};
    CHECK(storage_sensor_list(st, 0, 0, &l, &err) == 0 && l.total == N_SENSORS + 3); /* 2 + 1 */
    storage_sensor_list_free(&l);

    storage_close(w);
    storage_close(st);
    const char *files[] = {"live.db", "live.db-wal", "live.db-shm", "copy.db"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++)
        unlink(path_of(files[i]));
    CHECK(rmdir(tmpdir) == 0);
    CHECK_DONE();
}
