/* test_storage.c: storage/ against real SQLite files in a mkdtemp directory (removed at the end),
 * or, given `--pg URI` (a PostgreSQL server the suite started: tests/pg_server.sh), against
 * PostgreSQL, each database name of the tests then a schema of its own, made afresh.
 * Expected values come from the test's own inputs and from independent readers: the raw SQLite
 * API or libpq on a separate connection (schema version, journal mode, row counts, BLOB bytes
 * against hand-written little-endian hex) and the sqlite3 command-line shell. */
#define _GNU_SOURCE /* mkdtemp, strdup under -std=c11 */
#include <dirent.h>
#include <libpq-fe.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <sqlite3.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "check.h"
#include "storage/storage.h"
#include "storage_int.h" /* stg_migrations[0]: to make a schema-1 database by hand */

static char tmpdir[512];
static const char *pg_uri; /* --pg URI: PostgreSQL instead of SQLite files */
static int64_t fake_now = 1700000000000; /* the clock of the handles that install it */

static int64_t fake_clock(void *ctx) { return *(int64_t *)ctx; }

/* ---- PostgreSQL: a schema per database name, and the independent reader (libpq) --------- */

/* The schema standing for name: "t_" and its letters and digits ("calib.db": t_calibdb). */
static void pg_schema(const char *name, char *out, size_t n)
{
    size_t k = (size_t)snprintf(out, n, "t_");
    for (const char *c = name; *c && k + 1 < n; c++)
        if ((*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9')) out[k++] = *c;
    out[k] = '\0';
}

static PGconn *pg_connect(const char *name)
{
    PGconn *c = PQconnectdb(pg_uri);
    if (PQstatus(c) != CONNECTION_OK) {
        fprintf(stderr, "libpq: %s", PQerrorMessage(c));
        PQfinish(c);
        return NULL;
    }
    char schema[64], sql[128];
    pg_schema(name, schema, sizeof schema);
    snprintf(sql, sizeof sql, "SET search_path = %s; SET client_min_messages = warning", schema);
    PQclear(PQexec(c, sql));
    return c;
}

/* Makes name's schema afresh the first time a test uses the name, with the two SQLite functions
 * the tests' raw SQL uses (hex of a BLOB, zeroblob, a number's json_extract). */
static void pg_fresh(const char *name)
{
    static char seen[64][64];
    static int n_seen;
    for (int i = 0; i < n_seen; i++)
        if (!strcmp(seen[i], name)) return;
    if (n_seen < 64) snprintf(seen[n_seen++], sizeof seen[0], "%s", name);
    char schema[64], sql[1536];
    pg_schema(name, schema, sizeof schema);
    PGconn *c = pg_connect(name);
    if (!c) return;
    snprintf(sql, sizeof sql,
             "SET client_min_messages = warning; DROP SCHEMA IF EXISTS %s CASCADE; "
             "CREATE SCHEMA %s; SET search_path = %s; "
             "CREATE FUNCTION hex(bytea) RETURNS text LANGUAGE sql IMMUTABLE "
             "AS 'SELECT upper(encode($1, ''hex''))'; "
             "CREATE FUNCTION zeroblob(integer) RETURNS bytea LANGUAGE sql IMMUTABLE "
             "AS 'SELECT decode(repeat(''00'', $1), ''hex'')'; "
             "CREATE FUNCTION json_extract(text, text) RETURNS numeric LANGUAGE sql IMMUTABLE "
             "AS 'SELECT ($1::json #>> ARRAY[substr($2, 3)])::numeric'",
             schema, schema, schema);
    PGresult *r = PQexec(c, sql);
    if (PQresultStatus(r) != PGRES_COMMAND_OK) fprintf(stderr, "%s", PQresultErrorMessage(r));
    CHECK(PQresultStatus(r) == PGRES_COMMAND_OK);
    PQclear(r);
    PQfinish(c);
}

/* The first column of the first row of sql in name's schema, NULL when none (caller PQclears
 * *res). */
static const char *pg_first(const char *name, const char *sql, PGresult **res)
{
    *res = NULL;
    PGconn *c = pg_connect(name);
    if (!c) return NULL;
    *res = PQexec(c, sql);
    PQfinish(c);
    return PQresultStatus(*res) == PGRES_TUPLES_OK && PQntuples(*res) > 0 &&
                   !PQgetisnull(*res, 0, 0)
               ? PQgetvalue(*res, 0, 0)
               : NULL;
}

/* What storage_open is given for name: a file in tmpdir, or the URI with name's schema. */
static const char *db_path(const char *name)
{
    static char buf[8][1024];
    static int next;
    char *p = buf[next++ % 8];
    if (pg_uri) {
        char schema[64];
        pg_schema(name, schema, sizeof schema);
        pg_fresh(name);
        snprintf(p, sizeof buf[0], "%s%coptions=-csearch_path%%3D%s", pg_uri,
                 strchr(pg_uri, '?') ? '&' : '?', schema);
    } else {
        snprintf(p, sizeof buf[0], "%s/%s", tmpdir, name);
    }
    return p;
}

static storage_t *open_db(const char *name)
{
    storage_t *st = NULL;
    err_t err = {{0}};
    int ret = storage_open(db_path(name), &st, &err);
    if (ret) fprintf(stderr, "storage_open %s: %d %s\n", name, ret, err.msg);
    CHECK(ret == 0 && st);
    if (st) storage_set_clock(st, fake_clock, &fake_now);
    return st;
}

/* ---- independent reader: a raw SQLite connection -------------------------------------------- */

static int64_t raw_int(const char *name, const char *sql)
{
    if (pg_uri) {
        PGresult *r;
        const char *v = pg_first(name, sql, &r);
        /* a boolean reads as SQLite's 1 or 0 */
        int64_t x = !v ? -999 : !strcmp(v, "t") ? 1 : !strcmp(v, "f") ? 0 : strtoll(v, NULL, 10);
        PQclear(r);
        return x;
    }
    sqlite3 *db = NULL;
    sqlite3_stmt *s = NULL;
    int64_t v = -999;
    if (sqlite3_open(db_path(name), &db) == SQLITE_OK &&
        sqlite3_prepare_v2(db, sql, -1, &s, NULL) == SQLITE_OK && sqlite3_step(s) == SQLITE_ROW)
        v = sqlite3_column_int64(s, 0);
    sqlite3_finalize(s);
    sqlite3_close(db);
    return v;
}

static void raw_text(const char *name, const char *sql, char *out, size_t n)
{
    snprintf(out, n, "(none)");
    if (pg_uri) {
        PGresult *r;
        const char *v = pg_first(name, sql, &r);
        if (v) snprintf(out, n, "%s", v);
        PQclear(r);
        return;
    }
    sqlite3 *db = NULL;
    sqlite3_stmt *s = NULL;
    if (sqlite3_open(db_path(name), &db) == SQLITE_OK &&
        sqlite3_prepare_v2(db, sql, -1, &s, NULL) == SQLITE_OK && sqlite3_step(s) == SQLITE_ROW &&
        sqlite3_column_text(s, 0))
        snprintf(out, n, "%s", (const char *)sqlite3_column_text(s, 0));
    sqlite3_finalize(s);
    sqlite3_close(db);
}

static int raw_text_eq(const char *name, const char *sql, const char *want)
{
    char got[256];
    raw_text(name, sql, got, sizeof got);
    return strcmp(got, want) == 0;
}

/* SQLITE_OK, SQLITE_CONSTRAINT (PostgreSQL: SQLSTATE class 23) or another SQLite code. */
static int raw_exec(const char *name, const char *sql)
{
    if (pg_uri) {
        PGconn *c = pg_connect(name);
        if (!c) return SQLITE_CANTOPEN;
        PGresult *r = PQexec(c, sql);
        const char *state = PQresultErrorField(r, PG_DIAG_SQLSTATE);
        int rc = PQresultStatus(r) == PGRES_COMMAND_OK || PQresultStatus(r) == PGRES_TUPLES_OK
                     ? SQLITE_OK
                 : state && !strncmp(state, "23", 2) ? SQLITE_CONSTRAINT
                                                      : SQLITE_ERROR;
        PQclear(r);
        PQfinish(c);
        return rc;
    }
    sqlite3 *db = NULL;
    int rc = sqlite3_open(db_path(name), &db);
    if (rc == SQLITE_OK) {
        sqlite3_busy_timeout(db, 5000);
        rc = sqlite3_exec(db, sql, NULL, NULL, NULL);
    }
    sqlite3_close(db);
    return rc;
}

/* ---- fixtures ------------------------------------------------------------------------------- */

static int64_t make_sensor(storage_t *st, const char *model, const char *serial)
{
    storage_sensor_t s = {.model = (char *)model, .serial = (char *)serial, .n_cols = 640,
                          .n_rows = 480, .pitch_um = 6.0, .gain_e_per_dn = 1.5,
                          .read_noise_e = 3.25, .bias_dn = 100.0, .full_scale_dn = 16383.0};
    int64_t id = 0;
    CHECK(storage_sensor_create(st, &s, &id, NULL) == 0 && id > 0);
    return id;
}

static storage_scan_t scan_template(int64_t sensor_id)
{
    return (storage_scan_t){.sensor_id = sensor_id, .poi_col = 100, .poi_row = 200,
                            .wavelength_um = 0.55, .na = 0.25, .spot_radius_um = 1.342,
                            .area_px = 5, .step_um = 0.6, .sub_px = 3, .frames = 2,
                            .exposure_us = 1500.0, .points_total = 6};
}

static int64_t make_running_scan(storage_t *st, int64_t sensor_id)
{
    storage_scan_t sc = scan_template(sensor_id);
    int64_t id = 0;
    CHECK(storage_scan_create(st, &sc, &id, NULL) == 0 && id > 0);
    CHECK(storage_scan_set_state(st, id, STORAGE_RUNNING, NULL, NULL) == 0);
    return id;
}

/* A point of a 3 x 3, 2-frame scan whose mean at sub-frame pixel (i, j) is 1000 p + 10 j + i
 * + 0.25 and whose raw samples are 100 p + sample index. */
static int put_point(storage_t *st, int64_t scan, int p, err_t *err)
{
    uint16_t raw[18];
    double mean[9];
    for (int k = 0; k < 18; k++) raw[k] = (uint16_t)(100 * p + k);
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) mean[j * 3 + i] = 1000.0 * p + 10 * j + i + 0.25;
    storage_frame_t f = {.scan_id = scan, .point_index = p, .stage_x_um = 0.6 * (p % 3),
                         .stage_y_um = 0.6 * (p / 3), .stage_z_um = -12.5,
                         .exposure_us = 1000.0 + p, .frames = 2, .sub_px = 3, .raw = raw,
                         .mean = mean};
    return storage_frame_put(st, &f, err);
}

/* ---- tests ---------------------------------------------------------------------------------- */

static void test_open_migrate(void)
{
    storage_t *st = open_db("open.db");
    struct stat sb;
    char mode[32];
    CHECK(stat(db_path("open.db"), &sb) == 0);
    CHECK(storage_schema_version() == 12); /* docs/schema.md: "currently 12" (keep in step) */
    CHECK(raw_int("open.db", "PRAGMA user_version") == storage_schema_version());
    raw_text("open.db", "PRAGMA journal_mode", mode, sizeof mode);
    CHECK(strcmp(mode, "wal") == 0);
    CHECK(raw_int("open.db", "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN "
                             "('sensors','scans','frames','jobs','fits','calibrations')") == 6);
    int64_t sensor = make_sensor(st, "IMX-T", "0001");
    int64_t objects = raw_int("open.db", "SELECT count(*) FROM sqlite_master");
    storage_close(st);

    /* reopening an existing, current database is a no-op: same version, objects and rows */
    st = open_db("open.db");
    CHECK(raw_int("open.db", "PRAGMA user_version") == storage_schema_version());
    CHECK(raw_int("open.db", "SELECT count(*) FROM sqlite_master") == objects);
    storage_sensor_t s;
    CHECK(storage_sensor_get(st, sensor, &s, NULL) == 0 && strcmp(s.model, "IMX-T") == 0);
    storage_sensor_free(&s);
    storage_close(st);

    /* bad arguments, a missing directory, NULL close */
    err_t err = {{0}};
    storage_t *none = (storage_t *)&err;
    CHECK(storage_open(NULL, &none, &err) == -EINVAL && none == NULL);
    CHECK(storage_open(db_path("x.db"), NULL, &err) == -EINVAL);
    CHECK(storage_open(db_path("no/such/dir/x.db"), &none, &err) == -EIO && none == NULL);
    CHECK(strstr(err.msg, "no/such/dir/x.db") != NULL);
    storage_close(NULL);
}

static void test_refuse(void)
{
    /* a database from a newer ipsd: refused, and left exactly as it was (not even WAL) */
    char sql[128], mode[32];
    snprintf(sql, sizeof sql, "CREATE TABLE t (x); PRAGMA user_version = %d;",
             storage_schema_version() + 1);
    CHECK(raw_exec("new.db", sql) == SQLITE_OK);
    storage_t *st = NULL;
    err_t err = {{0}};
    CHECK(storage_open(db_path("new.db"), &st, &err) == -ENOTSUP && st == NULL);
    CHECK(strstr(err.msg, "newer") != NULL);
    CHECK(raw_int("new.db", "PRAGMA user_version") == storage_schema_version() + 1);
    raw_text("new.db", "PRAGMA journal_mode", mode, sizeof mode);
    CHECK(strcmp(mode, "delete") == 0);

    /* a file that is not a database */
    FILE *f = fopen(db_path("junk.db"), "w");
    CHECK(f != NULL);
    if (f) {
        for (int i = 0; i < 64; i++) fputs("this is not an SQLite database\n", f);
        fclose(f);
    }
    CHECK(storage_open(db_path("junk.db"), &st, &err) == -EIO && st == NULL);
    CHECK(strstr(err.msg, "junk.db") != NULL);
}

static void test_sensor_scan_roundtrip(void)
{
    storage_t *st = open_db("rt.db");
    err_t err = {{0}};
    int64_t sensor = make_sensor(st, "IMX-RT", "S/N 42");
    storage_sensor_t s, dup = {.model = "IMX-RT", .serial = "S/N 42", .n_cols = 1, .n_rows = 1,
                               .pitch_um = 1, .gain_e_per_dn = 1, .full_scale_dn = 1};
    int64_t id = 0;
    CHECK(storage_sensor_create(st, &dup, &id, &err) == -EEXIST && strstr(err.msg, "S/N 42"));
    CHECK(storage_sensor_find(st, "IMX-RT", "S/N 42", &s, NULL) == 0);
    CHECK(s.id == sensor && s.n_cols == 640 && s.n_rows == 480 && s.pitch_um == 6.0);
    CHECK(s.gain_e_per_dn == 1.5 && s.read_noise_e == 3.25 && s.bias_dn == 100.0);
    CHECK(s.full_scale_dn == 16383.0 && s.created_ms == fake_now);
    storage_sensor_free(&s);
    CHECK(storage_sensor_get(st, 999, &s, &err) == -ENOENT && strstr(err.msg, "999"));

    storage_scan_t in = scan_template(sensor), sc;
    CHECK(storage_scan_create(st, &in, &id, NULL) == 0);
    CHECK(storage_scan_get(st, id, &sc, NULL) == 0);
    CHECK(sc.sensor_id == sensor && sc.poi_col == 100 && sc.poi_row == 200);
    CHECK(sc.wavelength_um == 0.55 && sc.na == 0.25 && sc.spot_radius_um == 1.342);
    CHECK(sc.area_px == 5 && sc.step_um == 0.6 && sc.sub_px == 3 && sc.frames == 2);
    CHECK(sc.exposure_us == 1500.0 && sc.points_total == 6 && sc.points_done == 0);
    CHECK(sc.state == STORAGE_QUEUED && sc.error == NULL && sc.created_ms == fake_now);
    CHECK(sc.started_ms == 0 && sc.finished_ms == 0);
    storage_scan_free(&sc);
    int64_t t_start = fake_now += 1000;
    CHECK(storage_scan_set_state(st, id, STORAGE_RUNNING, NULL, NULL) == 0);
    fake_now += 1000;
    CHECK(storage_scan_set_state(st, id, STORAGE_FAILED, "stage lost", NULL) == 0);
    CHECK(storage_scan_get(st, id, &sc, NULL) == 0);
    CHECK(sc.state == STORAGE_FAILED && sc.error && strcmp(sc.error, "stage lost") == 0);
    CHECK(sc.started_ms == t_start && sc.finished_ms == fake_now);
    storage_scan_free(&sc);
    CHECK(storage_scan_set_state(st, 999, STORAGE_DONE, NULL, NULL) == -ENOENT);

    /* validation: even sub-frame, unknown sensor, sub-frame off the sensor */
    in.sub_px = 4;
    CHECK(storage_scan_create(st, &in, &id, &err) == -EINVAL && strstr(err.msg, "sub_px"));
    in = scan_template(999);
    CHECK(storage_scan_create(st, &in, &id, &err) == -ENOENT);
    in = scan_template(sensor);
    in.poi_col = 639;
    CHECK(storage_scan_create(st, &in, &id, &err) == -EINVAL);
    CHECK(raw_int("rt.db", "SELECT count(*) FROM scans") == 1);
    storage_close(st);
}

static void test_frame_roundtrip(void)
{
    storage_t *st = open_db("frame.db");
    int64_t scan = make_running_scan(st, make_sensor(st, "IMX-F", "1"));
    uint16_t raw[18] = {0x1234, 0xFFFF, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 65534, 42};
    double mean[9] = {1.0, -0.0, 1.0 / 3.0, 5e-324, 1.7976931348623157e308, -2.5, 1e-300,
                      3.141592653589793, 16383.0};
    storage_frame_t f = {.scan_id = scan, .point_index = 4, .stage_x_um = 1.25,
                         .stage_y_um = -3.5, .stage_z_um = 0.125, .exposure_us = 2000.0,
                         .frames = 2, .sub_px = 3, .raw = raw, .mean = mean}, g;
    CHECK(storage_frame_put(st, &f, NULL) == 0);
    CHECK(storage_frame_get(st, scan, 4, &g, NULL) == 0);
    CHECK(g.frames == 2 && g.sub_px == 3 && g.raw && g.mean);
    CHECK(g.raw && memcmp(g.raw, raw, sizeof raw) == 0);
    CHECK(g.mean && memcmp(g.mean, mean, sizeof mean) == 0); /* bit-exact, -0.0 and denormal too */
    CHECK(g.stage_x_um == 1.25 && g.stage_y_um == -3.5 && g.stage_z_um == 0.125);
    CHECK(g.exposure_us == 2000.0 && g.captured_ms == fake_now);
    storage_frame_free(&g);
    CHECK(storage_frame_get(st, scan, 3, &g, NULL) == -ENOENT);

    /* the documented layout: little-endian, uint16 raw, float64 mean (hex written by hand) */
    char hex[64];
    raw_text("frame.db", "SELECT hex(substr(raw, 1, 4)) FROM frames", hex, sizeof hex);
    CHECK(strcmp(hex, "3412FFFF") == 0);
    raw_text("frame.db", "SELECT hex(substr(mean, 1, 16)) FROM frames", hex, sizeof hex);
    CHECK(strcmp(hex, "000000000000F03F0000000000000080") == 0);
    CHECK(raw_int("frame.db", "SELECT length(raw) FROM frames") == 2 * 3 * 3 * 2);
    CHECK(raw_int("frame.db", "SELECT length(mean) FROM frames") == 3 * 3 * 8);

    /* wrong shape, index out of range */
    err_t err = {{0}};
    f.sub_px = 5;
    CHECK(storage_frame_put(st, &f, &err) == -EINVAL && strstr(err.msg, "shape"));
    f.sub_px = 3;
    f.point_index = 6;
    CHECK(storage_frame_put(st, &f, &err) == -EINVAL && strstr(err.msg, "point_index"));
    storage_close(st);
}

static void test_frames_unique(void)
{
    storage_t *st = open_db("uniq.db");
    int64_t scan = make_running_scan(st, make_sensor(st, "IMX-U", "1"));
    err_t err = {{0}};
    CHECK(put_point(st, scan, 0, NULL) == 0);
    /* the same index again, with other values: refused, the stored row unchanged */
    uint16_t raw[18] = {0};
    double mean[9] = {0};
    storage_frame_t dup = {.scan_id = scan, .point_index = 0, .exposure_us = 1, .frames = 2,
                           .sub_px = 3, .raw = raw, .mean = mean}, g;
    CHECK(storage_frame_put(st, &dup, &err) == -EEXIST && strstr(err.msg, "point 0"));
    CHECK(storage_frame_get(st, scan, 0, &g, NULL) == 0);
    CHECK(g.mean && g.mean[4] == 11.25 && g.raw && g.raw[17] == 17 && g.exposure_us == 1000.0);
    storage_frame_free(&g);
    CHECK(raw_int("uniq.db", "SELECT count(*) FROM frames") == 1);
    CHECK(raw_int("uniq.db", "SELECT points_done FROM scans") == 1);
    storage_close(st);
}

static void test_point_transaction(void)
{
    storage_t *st = open_db("txn.db");
    int64_t scan = make_running_scan(st, make_sensor(st, "IMX-X", "1"));
    CHECK(put_point(st, scan, 0, NULL) == 0 && put_point(st, scan, 1, NULL) == 0);
    /* another connection makes the progress update of the third point fail, after its frame
     * row was inserted in the same transaction */
    CHECK(raw_exec("txn.db", "CREATE TRIGGER inject BEFORE UPDATE OF points_done ON scans "
                             "WHEN NEW.points_done = 3 BEGIN SELECT RAISE(ABORT, 'injected'); END")
          == SQLITE_OK);
    err_t err = {{0}};
    CHECK(put_point(st, scan, 2, &err) < 0 && strstr(err.msg, "injected"));
    CHECK(raw_int("txn.db", "SELECT count(*) FROM frames WHERE point_index = 2") == 0);
    CHECK(raw_int("txn.db", "SELECT points_done FROM scans") == 2);
    int last = -9, count = -9;
    CHECK(storage_frame_last(st, scan, &last, &count, NULL) == 0 && last == 1 && count == 2);
    CHECK(raw_exec("txn.db", "DROP TRIGGER inject") == SQLITE_OK);
    CHECK(put_point(st, scan, 2, NULL) == 0); /* not a duplicate: nothing was left behind */
    CHECK(raw_int("txn.db", "SELECT points_done FROM scans") == 3);
    storage_close(st);

    /* a process that dies without closing: what returned 0 is in the file */
    pid_t pid = fork();
    if (pid == 0) {
        storage_t *c = NULL;
        int64_t job = 0;
        if (storage_open(db_path("txn.db"), &c, NULL) || put_point(c, scan, 3, NULL) ||
            storage_job_enqueue(c, STORAGE_JOB_FIT, "{\"r\": 7}", scan, &job, NULL))
            _exit(1);
        _exit(0); /* no storage_close, no commit of anything pending */
    }
    int status = -1;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) &&
          WEXITSTATUS(status) == 0);
    st = open_db("txn.db");
    CHECK(storage_frame_last(st, scan, &last, &count, NULL) == 0 && last == 3 && count == 4);
    CHECK(raw_int("txn.db", "SELECT count(*) FROM jobs WHERE state = 'queued' "
                            "AND json_extract(params, '$.r') = 7") == 1);
    storage_close(st);
}

static void test_raster(void)
{
    storage_t *st = open_db("raster.db");
    int64_t scan = make_running_scan(st, make_sensor(st, "IMX-R", "1"));
    int order[6] = {3, 0, 5, 1, 4, 2};
    for (int k = 0; k < 6; k++) CHECK(put_point(st, scan, order[k], NULL) == 0);
    storage_raster_t r;
    /* (dcol, drow) = (1, -1) is sub-frame pixel (i, j) = (2, 0): mean 1000 p + 2.25 */
    CHECK(storage_frame_raster(st, scan, 1, -1, &r, NULL) == 0 && r.n == 6);
    for (size_t p = 0; p < r.n && r.n == 6; p++) {
        CHECK(r.point_index[p] == (int)p);
        CHECK(r.mean_dn[p] == 1000.0 * p + 2.25);
        CHECK(r.stage_x_um[p] == 0.6 * (p % 3) && r.stage_y_um[p] == 0.6 * (p / 3));
        CHECK(r.exposure_us[p] == 1000.0 + p);
    }
    storage_raster_free(&r);
    CHECK(storage_frame_raster(st, scan, 0, 0, &r, NULL) == 0 && r.n == 6);
    CHECK(r.n == 6 && r.mean_dn[5] == 5011.25 && r.mean_dn[0] == 11.25);
    storage_raster_free(&r);
    CHECK(storage_frame_raster(st, scan, -1, 1, &r, NULL) == 0 && r.n == 6);
    CHECK(r.n == 6 && r.mean_dn[3] == 3020.25);
    storage_raster_free(&r);
    err_t err = {{0}};
    CHECK(storage_frame_raster(st, scan, 2, 0, &r, &err) == -EINVAL && strstr(err.msg, "outside"));
    CHECK(storage_frame_raster(st, 999, 0, 0, &r, NULL) == -ENOENT);
    int last, count;
    CHECK(storage_frame_last(st, scan, &last, &count, NULL) == 0 && last == 5 && count == 6);
    storage_close(st);

    /* the database's own shell reads what the code wrote (Debian packages sqlite3 and
     * postgresql-client) */
    const char *shell = pg_uri ? "/usr/bin/psql -X -At" : "/usr/bin/sqlite3";
    if (access(pg_uri ? "/usr/bin/psql" : "/usr/bin/sqlite3", X_OK) == 0) {
        char cmd[1024], line[128] = "";
        snprintf(cmd, sizeof cmd, "%s '%s' -c 'select count(*) from frames'", shell,
                 db_path("raster.db"));
        if (!pg_uri) /* sqlite3 takes the SQL as its second argument */
            snprintf(cmd, sizeof cmd, "%s '%s' 'select count(*) from frames'", shell,
                     db_path("raster.db"));
        FILE *p = popen(cmd, "r");
        CHECK(p && fgets(line, sizeof line, p) && atoi(line) == 6);
        CHECK(p && pclose(p) == 0);
        /* point 1's mean at pixel (0, 0) is 1000.25 = 0x408F420000000000, little-endian */
        snprintf(cmd, sizeof cmd, "%s '%s' %s 'select hex(substr(mean, 1, 8)) from "
                 "frames where point_index = 1'", shell, db_path("raster.db"), pg_uri ? "-c" : "");
        p = popen(cmd, "r");
        CHECK(p && fgets(line, sizeof line, p) && strncmp(line, "0000000000428F40", 16) == 0);
        CHECK(p && pclose(p) == 0);
    } else {
        printf("note: the database's shell is not installed, shell check skipped\n");
    }
}

/* ---- jobs ----------------------------------------------------------------------------------- */

#define N_JOBS 400

static pthread_barrier_t claim_start;

typedef struct claimer {
    char path[1024]; /* set by the main thread (db_path is not thread-safe) */
    int64_t ids[N_JOBS];
    int n, failed;
} claimer_t;

static void *claim_loop(void *arg)
{
    claimer_t *c = arg;
    storage_t *st = NULL;
    if (storage_open(c->path, &st, NULL)) c->failed = 1;
    pthread_barrier_wait(&claim_start); /* both threads race from here */
    for (; st;) {
        storage_job_t j;
        if (storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL)) {
            c->failed = 1;
            break;
        }
        if (j.id == 0) break;
        if (c->n < N_JOBS) c->ids[c->n++] = j.id;
        if (j.attempts != 1 || j.state != STORAGE_RUNNING ||
            storage_job_finish(st, j.id, STORAGE_DONE, NULL, NULL))
            c->failed = 1;
        storage_job_free(&j);
        usleep(300); /* "work", so the other thread gets its turns */
    }
    storage_close(st);
    return NULL;
}

static void test_claim_concurrent(void)
{
    storage_t *st = open_db("claim.db");
    int64_t id, first = 0, scan_job;
    for (int k = 0; k < N_JOBS; k++) {
        CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &id, NULL) == 0);
        if (k == 0) first = id;
    }
    CHECK(storage_job_enqueue(st, STORAGE_JOB_SCAN, "{}", 0, &scan_job, NULL) == 0);
    storage_close(st);
    static claimer_t c[2];
    pthread_t t[2];
    CHECK(pthread_barrier_init(&claim_start, NULL, 2) == 0);
    for (int k = 0; k < 2; k++) snprintf(c[k].path, sizeof c[k].path, "%s", db_path("claim.db"));
    for (int k = 0; k < 2; k++) CHECK(pthread_create(&t[k], NULL, claim_loop, &c[k]) == 0);
    for (int k = 0; k < 2; k++) pthread_join(t[k], NULL);
    pthread_barrier_destroy(&claim_start);
    CHECK(!c[0].failed && !c[1].failed);
    CHECK(c[0].n + c[1].n == N_JOBS);
    /* every job exactly once, each thread in queue order */
    char seen[N_JOBS] = {0};
    int dup = 0, unordered = 0;
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < c[k].n; i++) {
            int64_t slot = c[k].ids[i] - first;
            if (slot < 0 || slot >= N_JOBS || seen[slot]++) dup++;
            if (i && c[k].ids[i] <= c[k].ids[i - 1]) unordered++;
        }
    CHECK(dup == 0 && unordered == 0);
    CHECK(raw_int("claim.db", "SELECT count(*) FROM jobs WHERE kind = 'fit' AND state = 'done' "
                              "AND attempts = 1 AND progress = 1") == N_JOBS);
    CHECK(raw_int("claim.db", "SELECT count(*) FROM jobs WHERE kind = 'scan' AND state = 'queued' "
                              "AND attempts = 0") == 1);
    printf("claims: thread 0 got %d, thread 1 got %d\n", c[0].n, c[1].n);
}

static void test_requeue(void)
{
    storage_t *st = open_db("requeue.db");
    storage_job_t j;
    int64_t id, other;
    int rq = -1, fl = -1;
    err_t err = {{0}};
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{\"a\": [1, 2]}", 0, &id, NULL) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == id);
    CHECK(j.attempts == 1 && j.heartbeat_ms == fake_now && j.started_ms == fake_now);
    storage_job_free(&j);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &other, NULL) == 0);
    fake_now += 10000;
    CHECK(storage_job_heartbeat(st, id, 0.5, 40, NULL) == 0);
    fake_now += 30000; /* heartbeat 30 s old: fresh for a 60 s threshold */
    CHECK(storage_job_requeue_stale(st, 60000, 3, &rq, &fl, NULL) == 0 && rq == 0 && fl == 0);
    fake_now += 60000; /* now 90 s old */
    CHECK(storage_job_requeue_stale(st, 60000, 3, &rq, &fl, NULL) == 0 && rq == 1 && fl == 0);
    CHECK(storage_job_get(st, id, &j, NULL) == 0);
    CHECK(j.state == STORAGE_QUEUED && j.attempts == 1 && j.heartbeat_ms == 0);
    CHECK(j.progress == 0.5 && j.points_done == 40 && strcmp(j.params, "{\"a\": [1, 2]}") == 0);
    storage_job_free(&j);
    /* the old worker, if it still lives, learns it lost the job */
    CHECK(storage_job_heartbeat(st, id, 0.6, 41, &err) == -ESTALE && strstr(err.msg, "queued"));
    CHECK(storage_job_finish(st, id, STORAGE_DONE, NULL, NULL) == -ESTALE);
    /* claimed again (it is the oldest), then abandoned at max_attempts = 2 */
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == id && j.attempts == 2);
    storage_job_free(&j);
    CHECK(storage_job_requeue_stale(st, 0, 2, &rq, &fl, NULL) == 0 && rq == 0 && fl == 1);
    CHECK(storage_job_get(st, id, &j, NULL) == 0);
    CHECK(j.state == STORAGE_FAILED && j.error && strstr(j.error, "abandoned after 2"));
    CHECK(j.finished_ms == fake_now);
    storage_job_free(&j);
    CHECK(storage_job_get(st, other, &j, NULL) == 0 && j.state == STORAGE_QUEUED);
    storage_job_free(&j);
    storage_close(st);
}

static void test_cancel(void)
{
    storage_t *st = open_db("cancel.db");
    storage_job_t j;
    int64_t q_id, r_id, d_id;
    int changed = -1;
    err_t err = {{0}};
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &d_id, NULL) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == d_id);
    storage_job_free(&j);
    CHECK(storage_job_finish(st, d_id, STORAGE_DONE, NULL, NULL) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &r_id, NULL) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &q_id, NULL) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == r_id);
    storage_job_free(&j);
    /* queued -> cancelled, once */
    CHECK(storage_job_cancel(st, q_id, &changed, NULL) == 0 && changed == 1);
    CHECK(storage_job_cancel(st, q_id, &changed, NULL) == 0 && changed == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == 0);
    /* running -> cancelled; the worker hears it at its next heartbeat or finish */
    CHECK(storage_job_cancel(st, r_id, &changed, NULL) == 0 && changed == 1);
    CHECK(storage_job_heartbeat(st, r_id, 0.3, 3, &err) == -ECANCELED);
    CHECK(storage_job_finish(st, r_id, STORAGE_FAILED, "late", NULL) == -ECANCELED);
    CHECK(storage_job_get(st, r_id, &j, NULL) == 0 && j.state == STORAGE_CANCELLED && !j.error);
    CHECK(j.finished_ms == fake_now);
    storage_job_free(&j);
    /* done stays done; unknown ids */
    CHECK(storage_job_cancel(st, d_id, &changed, NULL) == 0 && changed == 0);
    CHECK(storage_job_get(st, d_id, &j, NULL) == 0 && j.state == STORAGE_DONE && j.progress == 1);
    storage_job_free(&j);
    CHECK(storage_job_cancel(st, 999, &changed, &err) == -ENOENT && strstr(err.msg, "999"));
    CHECK(storage_job_heartbeat(st, 999, 0, 0, NULL) == -ENOENT);

    /* a scan job: submit is atomic, cancel stops the scan writer */
    int64_t sensor = make_sensor(st, "IMX-C", "1"), scan = 0, job = 0;
    storage_scan_t sc = scan_template(sensor);
    CHECK(storage_scan_submit(st, &sc, "{not json", &scan, &job, &err) == -EINVAL);
    CHECK(strstr(err.msg, "JSON") != NULL);
    CHECK(raw_int("cancel.db", "SELECT count(*) FROM scans") == 0);
    sc.sub_px = 4; /* the scan is refused: no job either */
    CHECK(storage_scan_submit(st, &sc, "{\"n\": 5}", &scan, &job, &err) == -EINVAL);
    CHECK(strstr(err.msg, "sub_px") != NULL);
    CHECK(raw_int("cancel.db", "SELECT count(*) FROM jobs WHERE kind = 'scan'") == 0);
    sc.sub_px = 3;
    CHECK(storage_scan_submit(st, &sc, "{\"n\": 5}", &scan, &job, NULL) == 0);
    CHECK(raw_int("cancel.db", "SELECT count(*) FROM scans") == 1);
    CHECK(raw_int("cancel.db", "SELECT count(*) FROM jobs WHERE kind = 'scan' AND state = 'queued' "
                               "AND scan_id = (SELECT id FROM scans) "
                               "AND json_extract(params, '$.n') = 5") == 1);
    CHECK(storage_job_claim(st, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == job);
    CHECK(j.scan_id == scan);
    storage_job_free(&j);
    CHECK(storage_scan_set_state(st, scan, STORAGE_RUNNING, NULL, NULL) == 0);
    CHECK(put_point(st, scan, 0, NULL) == 0);
    CHECK(storage_job_cancel(st, job, &changed, NULL) == 0 && changed == 1);
    CHECK(put_point(st, scan, 1, &err) == -ECANCELED);
    CHECK(storage_scan_get(st, scan, &sc, NULL) == 0 && sc.state == STORAGE_CANCELLED);
    CHECK(sc.points_done == 1);
    storage_scan_free(&sc);
    storage_close(st);
}

static void test_busy(void)
{
    storage_t *st = open_db("busy.db");
    sqlite3 *other = NULL;
    int64_t id = 0;
    err_t err = {{0}};
    /* another connection holds the write lock: a write gives up after the busy timeout */
    CHECK(sqlite3_open(db_path("busy.db"), &other) == SQLITE_OK);
    CHECK(sqlite3_exec(other, "BEGIN IMMEDIATE", NULL, NULL, NULL) == SQLITE_OK);
    CHECK(storage_set_busy_timeout(st, 20, NULL) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &id, &err) == -EBUSY);
    CHECK(strstr(err.msg, "locked") != NULL);
    storage_job_list_t l; /* readers are not blocked (WAL) */
    CHECK(storage_job_list(st, STORAGE_ANY, STORAGE_ANY, 0, 0, 0, &l, NULL) == 0 && l.total == 0);
    storage_job_list_free(&l);
    CHECK(sqlite3_exec(other, "COMMIT", NULL, NULL, NULL) == SQLITE_OK);
    sqlite3_close(other);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &id, NULL) == 0 && id == 1);
    storage_close(st);
}

/* The write gate: a hot writer (a scan storing points back to back) and another writer, each on
 * its own handle with a 1 ms busy timeout, sharing a gate: every write of both succeeds (the gate
 * serves them in turn, so SQLite's lock is always free when a handle asks). */
struct gate_writer {
    storage_t *st;
    int n, failures;
};

static void *gate_write_loop(void *arg)
{
    struct gate_writer *g = arg;
    int64_t id;
    err_t err = {{0}};
    for (int i = 0; i < g->n; i++)
        if (storage_job_enqueue(g->st, STORAGE_JOB_FIT, "{}", 0, &id, &err) != 0) {
            if (!g->failures) fprintf(stderr, "gate writer: %s\n", err.msg);
            g->failures++;
        }
    return NULL;
}

static void test_gate(void)
{
    storage_t *a = open_db("gate.db"), *b = open_db("gate.db");
    storage_gate_t *gate = NULL;
    CHECK(storage_gate_new(&gate) == 0);
    storage_set_gate(a, gate);
    storage_set_gate(b, gate);
    CHECK(storage_set_busy_timeout(a, 1, NULL) == 0 && storage_set_busy_timeout(b, 1, NULL) == 0);
    struct gate_writer w[2] = {{a, 3000, 0}, {b, 300, 0}};
    pthread_t t[2];
    for (int k = 0; k < 2; k++) CHECK(pthread_create(&t[k], NULL, gate_write_loop, &w[k]) == 0);
    for (int k = 0; k < 2; k++) pthread_join(t[k], NULL);
    CHECK(w[0].failures == 0 && w[1].failures == 0);
    storage_job_list_t l;
    CHECK(storage_job_list(a, STORAGE_ANY, STORAGE_ANY, 0, 0, 0, &l, NULL) == 0 && l.total == 3300);
    storage_job_list_free(&l);
    storage_close(a);
    storage_close(b);
    storage_gate_free(gate);
}

/* ---- fits and calibrations ------------------------------------------------------------------ */

static int64_t put_calib(storage_t *st, int64_t sensor, int col, int row, double s0,
                         const char *status)
{
    double S[4] = {s0, 1.0 / 3.0, 1e-300, -2.5}, E[4] = {0.01, 0.02, 0.03, 0.04};
    storage_calib_t c = {.sensor_id = sensor, .pixel_col = col, .pixel_row = row, .r = 2,
                         .S = S, .S_err = E, .I0 = 1234.5, .chi2_red = 1.07,
                         .status = (char *)status, .noise_model = "shot+read",
                         .wavelength_um = 0.55, .na = 0.25, .spot_radius_um = 1.342};
    int64_t id = 0;
    CHECK(storage_calib_put(st, &c, &id, NULL) == 0 && id > 0);
    return id;
}

static void test_fits(void)
{
    storage_t *st = open_db("fits.db");
    int64_t sensor = make_sensor(st, "IMX-FT", "1"), scan = make_running_scan(st, sensor);
    int64_t job, fit_id = 0, calib_id = 0;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", scan, &job, NULL) == 0);
    storage_fit_t f = {.scan_id = scan, .dcol = 0, .drow = 1, .noise_model = "paper",
                       .best_r_aic = 7, .best_r_bic = 5, .f_value = 2.49, .p_value = 0.00711,
                       .result = "{\"best_r\": {\"aic\": 7, \"bic\": 5}, "
                                 "\"note\": \"\u00b5m\"}"}, g;
    double S[1] = {1.0}, E[1] = {0.5};
    storage_calib_t c = {.sensor_id = sensor, .pixel_col = 100, .pixel_row = 201, .r = 1, .S = S,
                         .S_err = E, .I0 = NAN, .chi2_red = NAN, .status = "ok",
                         .noise_model = "paper", .wavelength_um = NAN, .na = NAN,
                         .spot_radius_um = NAN}, got;
    CHECK(storage_fit_put(st, &f, &c, job, &fit_id, &calib_id, NULL) == 0 && fit_id && calib_id);
    CHECK(storage_fit_get(st, fit_id, &g, NULL) == 0);
    CHECK(g.scan_id == scan && g.dcol == 0 && g.drow == 1 && strcmp(g.noise_model, "paper") == 0);
    CHECK(g.best_r_aic == 7 && g.best_r_bic == 5 && g.f_value == 2.49 && g.p_value == 0.00711);
    CHECK(strcmp(g.result, f.result) == 0 && g.created_ms == fake_now);
    storage_fit_free(&g);
    CHECK(storage_calib_get(st, calib_id, &got, NULL) == 0);
    CHECK(got.fit_id == fit_id && got.scan_id == scan && isnan(got.I0) && isnan(got.na));
    CHECK(strcmp(got.software_version, IPSD_VERSION) == 0);
    storage_calib_free(&got);
    storage_job_t j;
    CHECK(storage_job_get(st, job, &j, NULL) == 0 && j.fit_id == fit_id);
    storage_job_free(&j);

    /* no F-test -> NaN; a failed link leaves nothing behind */
    f.f_value = f.p_value = NAN;
    f.best_r_aic = 0;
    err_t err = {{0}};
    CHECK(storage_fit_put(st, &f, &c, 999, NULL, NULL, &err) == -ENOENT && strstr(err.msg, "999"));
    CHECK(raw_int("fits.db", "SELECT count(*) FROM fits") == 1);
    CHECK(raw_int("fits.db", "SELECT count(*) FROM calibrations") == 1);
    /* a refused calibration (pixel off the 640 x 480 sensor) leaves no fit and no job link */
    c.pixel_col = 640;
    CHECK(storage_fit_put(st, &f, &c, job, NULL, NULL, &err) == -EINVAL);
    CHECK(strstr(err.msg, "outside") != NULL);
    c.pixel_col = 100;
    CHECK(raw_int("fits.db", "SELECT count(*) FROM fits") == 1);
    CHECK(raw_int("fits.db", "SELECT count(*) FROM calibrations") == 1);
    CHECK(raw_int("fits.db", "SELECT count(*) FROM jobs WHERE fit_id = 1") == 1);
    CHECK(storage_fit_put(st, &f, NULL, 0, &fit_id, NULL, NULL) == 0);
    CHECK(storage_fit_get(st, fit_id, &g, NULL) == 0);
    CHECK(isnan(g.f_value) && isnan(g.p_value) && g.best_r_aic == 0 && g.best_r_bic == 5);
    storage_fit_free(&g);
    f.result = "{broken";
    CHECK(storage_fit_put(st, &f, NULL, 0, NULL, NULL, &err) == -EINVAL && strstr(err.msg, "JSON"));
    f.result = "{}";
    f.dcol = 2;
    CHECK(storage_fit_put(st, &f, NULL, 0, NULL, NULL, &err) == -EINVAL);
    storage_fit_list_t fl;
    CHECK(storage_fit_list(st, scan, 1, 0, &fl, NULL) == 0 && fl.total == 2 && fl.n == 1);
    CHECK(fl.n == 1 && fl.items[0].id == fit_id);
    storage_fit_list_free(&fl);
    storage_close(st);
}

/* A fit of scan with a 1 x 1 map (S 1, S_err 0.5) of pixel (7, 8) of sensor: what the fit-store
 * tests store. S and E are the caller's one-element arrays. */
static void one_cell_fit(int64_t scan, int64_t sensor, double *S, double *E, storage_fit_t *f,
                         storage_calib_t *c)
{
    S[0] = 1.0;
    E[0] = 0.5;
    *f = (storage_fit_t){.scan_id = scan, .noise_model = "paper", .best_r_aic = 1,
                         .best_r_bic = 1, .f_value = NAN, .p_value = NAN, .result = "{}"};
    *c = (storage_calib_t){.sensor_id = sensor, .pixel_col = 7, .pixel_row = 8, .r = 1, .S = S,
                           .S_err = E, .I0 = NAN, .chi2_red = NAN, .status = "ok",
                           .noise_model = "paper", .wavelength_um = NAN, .na = NAN,
                           .spot_radius_um = NAN};
}

/* A fit job's result and its done in one transaction (storage_fit_store_done): a running job
 * ends done naming its fit; a cancelled job, a job not running and an unknown job store nothing. */
static void test_fit_store_done(void)
{
    storage_t *st = open_db("fitdone.db");
    int64_t sensor = make_sensor(st, "IMX-FD", "1"), scan = make_running_scan(st, sensor);
    int64_t run, cancelled, queued, fit_id = 0, calib_id = 0;
    err_t err = {{0}};
    storage_job_t j;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", scan, &run, NULL) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", scan, &cancelled, NULL) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", scan, &queued, NULL) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == run);
    storage_job_free(&j);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == cancelled);
    storage_job_free(&j);
    int changed = 0;
    CHECK(storage_job_cancel(st, cancelled, &changed, NULL) == 0 && changed);
    storage_fit_t f;
    storage_calib_t c;
    double S[1], E[1];
    one_cell_fit(scan, sensor, S, E, &f, &c);
    CHECK(storage_fit_store_done(st, &f, &c, 1, cancelled, NULL, NULL, &err) == -ECANCELED);
    CHECK(storage_fit_store_done(st, &f, &c, 1, queued, NULL, NULL, &err) == -ESTALE);
    CHECK(storage_fit_store_done(st, &f, &c, 1, 999, NULL, NULL, &err) == -ENOENT);
    CHECK(storage_fit_store_done(st, &f, &c, 1, 0, NULL, NULL, &err) == -EINVAL);
    CHECK(raw_int("fitdone.db", "SELECT count(*) FROM fits") == 0);
    CHECK(raw_int("fitdone.db", "SELECT count(*) FROM fit_maps") == 0);
    CHECK(raw_int("fitdone.db", "SELECT count(*) FROM calibrations") == 0);
    CHECK(storage_fit_store_done(st, &f, &c, 1, run, &fit_id, &calib_id, NULL) == 0);
    CHECK(fit_id > 0 && calib_id > 0);
    CHECK(storage_job_get(st, run, &j, NULL) == 0);
    CHECK(j.state == STORAGE_DONE && j.fit_id == fit_id && j.progress == 1);
    storage_job_free(&j);
    /* done: a second store (a rerun) is refused and stores nothing */
    CHECK(storage_fit_store_done(st, &f, &c, 1, run, NULL, NULL, &err) == -ESTALE);
    CHECK(raw_int("fitdone.db", "SELECT count(*) FROM fits") == 1);
    CHECK(raw_int("fitdone.db", "SELECT count(*) FROM calibrations") == 1);
    storage_close(st);
}

/* One pixel of a fit of every pixel (storage_fit_store_unit): the job's count moves by one from
 * the value given, so a unit is never stored twice; the last unit ends the job; a release (the
 * shutdown) keeps the count; a cancelled job stores nothing. */
static void test_fit_store_unit(void)
{
    storage_t *st = open_db("fitunit.db");
    int64_t sensor = make_sensor(st, "IMX-FU", "1"), scan = make_running_scan(st, sensor);
    int64_t a, b;
    err_t err = {{0}};
    storage_job_t j;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", scan, &a, NULL) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{\"pixels\": \"all\"}", scan, &b, NULL) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == a);
    storage_job_free(&j);
    storage_fit_t f;
    storage_calib_t c;
    double S[1], E[1];
    one_cell_fit(scan, sensor, S, E, &f, &c);
    CHECK(storage_fit_store_unit(st, &f, &c, 1, a, 0, 3, NULL, NULL, NULL) == 0);
    CHECK(storage_job_get(st, a, &j, NULL) == 0);
    CHECK(j.state == STORAGE_RUNNING && j.points_done == 1 && fabs(j.progress - 1.0 / 3) < 1e-12);
    storage_job_free(&j);
    /* unit 0 again (a rerun that did not know): refused, nothing stored */
    CHECK(storage_fit_store_unit(st, &f, &c, 1, a, 0, 3, NULL, NULL, &err) == -ESTALE);
    CHECK(raw_int("fitunit.db", "SELECT count(*) FROM fits") == 1);
    CHECK(raw_int("fitunit.db", "SELECT count(*) FROM calibrations") == 1);
    CHECK(storage_fit_store_unit(st, &f, &c, 0, a, 3, 3, NULL, NULL, &err) == -EINVAL);
    /* the shutdown gives the job back with its count; claimed again, it goes on */
    CHECK(storage_job_release(st, a, NULL) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == a);
    CHECK(j.points_done == 1);
    storage_job_free(&j);
    f.dcol = 1; /* not promoted: a map, no calibration */
    CHECK(storage_fit_store_unit(st, &f, &c, 0, a, 1, 3, NULL, NULL, NULL) == 0);
    CHECK(raw_int("fitunit.db", "SELECT count(*) FROM fit_maps") == 2);
    CHECK(raw_int("fitunit.db", "SELECT count(*) FROM calibrations") == 1);
    int changed = 0;
    CHECK(storage_job_cancel(st, a, &changed, NULL) == 0 && changed);
    CHECK(storage_fit_store_unit(st, &f, &c, 1, a, 2, 3, NULL, NULL, &err) == -ECANCELED);
    CHECK(raw_int("fitunit.db", "SELECT count(*) FROM fits") == 2);
    CHECK(raw_int("fitunit.db", "SELECT points_done FROM jobs WHERE id = 1") == 2);
    /* the last unit ends the job as done, in its transaction */
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == b);
    storage_job_free(&j);
    int64_t u0 = 0, u1 = 0;
    CHECK(storage_fit_store_unit(st, &f, NULL, 0, b, 0, 2, &u0, NULL, NULL) == 0);
    CHECK(storage_fit_store_unit(st, &f, NULL, 0, b, 1, 2, &u1, NULL, NULL) == 0);
    CHECK(storage_job_get(st, b, &j, NULL) == 0);
    /* linked to its fits: fit_id the newest, fit_ids every one in the order stored (each fit
     * records its job: schema 6), the params the request as it was */
    CHECK(j.state == STORAGE_DONE && j.points_done == 2 && j.progress == 1 && j.fit_id == u1);
    char want[64];
    snprintf(want, sizeof want, "[%lld,%lld]", (long long)u0, (long long)u1);
    CHECK(u0 > 0 && u1 > u0 && j.fit_ids && strcmp(j.fit_ids, want) == 0);
    CHECK(j.params && strcmp(j.params, "{\"pixels\": \"all\"}") == 0);
    storage_job_free(&j);
    CHECK(storage_job_get(st, a, &j, NULL) == 0 && j.fit_ids == NULL); /* not every pixel */
    storage_job_free(&j);
    CHECK(storage_fit_store_unit(st, &f, NULL, 0, b, 2, 3, NULL, NULL, &err) == -ESTALE);
    CHECK(raw_int("fitunit.db", "SELECT count(*) FROM fits") == 4);
    storage_close(st);
}

static void check_calib_search(storage_t *st, int64_t a, const int64_t *ids, int64_t t2);

/* The calibration generation (storage.h) is a sequence lock: even between writes, moved by 2 by
 * each transaction that stored a calibration (odd inside it), not moved by one that failed before
 * storing; without a gate there is none. On PostgreSQL a gate answers only while its listener
 * listens, which this test does not start. */
static void test_calib_generation(void)
{
    storage_t *st = open_db("calibgen.db");
    int64_t sensor = make_sensor(st, "IMX-G", "1");
    uint64_t g0, g1, g2;
    CHECK(storage_calib_generation(st, &g0) == -ENOTSUP);
    storage_gate_t *gate = NULL;
    CHECK(storage_gate_new(&gate) == 0);
    storage_set_gate(st, gate);
    if (pg_uri) {
        CHECK(storage_calib_generation(st, &g0) == -ENOTSUP);
    } else {
        CHECK(storage_calib_generation(st, &g0) == 0 && g0 % 2 == 0);
        put_calib(st, sensor, 3, 4, 1.0, "ok");
        CHECK(storage_calib_generation(st, &g1) == 0 && g1 == g0 + 2);
        double S[4] = {1, 1, 1, 1}, E[4] = {0.1, 0.1, 0.1, 0.1};
        storage_calib_t bad = {.sensor_id = sensor + 1000, .pixel_col = 3, .pixel_row = 4, .r = 2,
                               .S = S, .S_err = E, .status = "ok", .noise_model = "paper"};
        int64_t id = 0;
        CHECK(storage_calib_put(st, &bad, &id, NULL) != 0); /* no such sensor */
        CHECK(storage_calib_generation(st, &g2) == 0 && g2 == g1);
    }
    storage_close(st);
    storage_gate_free(gate);
}

static void test_calibrations(void)
{
    storage_t *st = open_db("calib.db");
    int64_t a = make_sensor(st, "IMX-A", "1"), b = make_sensor(st, "CMV-B", "7");
    int64_t t1 = fake_now += 1000, c1 = put_calib(st, a, 10, 20, 0.9, "ok");
    int64_t t2 = fake_now += 1000, c2 = put_calib(st, a, 10, 20, 0.95, "ok");
    int64_t t3 = fake_now += 1000, c3 = put_calib(st, a, 10, 20, 1.05, "unconstrained");
    int64_t d = put_calib(st, a, 11, 20, 1.0, "ok");
    fake_now += 1000;
    int64_t e = put_calib(st, b, 10, 20, 1.0, "ok");
    storage_calib_t c;
    CHECK(storage_calib_current(st, a, 10, 20, &c, NULL) == 0 && c.id == c3);
    CHECK(c.superseded_by == 0 && c.created_ms == t3 && c.r == 2);
    CHECK(strcmp(c.status, "unconstrained") == 0);
    double want[4] = {1.05, 1.0 / 3.0, 1e-300, -2.5}, want_err[4] = {0.01, 0.02, 0.03, 0.04};
    CHECK(c.S && memcmp(c.S, want, sizeof want) == 0);
    CHECK(c.S_err && memcmp(c.S_err, want_err, sizeof want_err) == 0);
    CHECK(c.I0 == 1234.5 && c.chi2_red == 1.07 && strcmp(c.noise_model, "shot+read") == 0);
    CHECK(c.wavelength_um == 0.55 && c.na == 0.25 && c.spot_radius_um == 1.342);
    storage_calib_free(&c);
    CHECK(storage_calib_get(st, c1, &c, NULL) == 0 && c.superseded_by == c2 && c.created_ms == t1);
    CHECK(c.S && c.S[0] == 0.9);
    storage_calib_free(&c);
    CHECK(storage_calib_get(st, c2, &c, NULL) == 0 && c.superseded_by == c3 && c.created_ms == t2);
    storage_calib_free(&c);
    CHECK(storage_calib_current(st, a, 11, 20, &c, NULL) == 0 && c.id == d);
    storage_calib_free(&c);
    CHECK(storage_calib_current(st, b, 10, 20, &c, NULL) == 0 && c.id == e);
    storage_calib_free(&c);
    CHECK(storage_calib_current(st, a, 12, 20, &c, NULL) == -ENOENT);

    storage_calib_list_t l;
    CHECK(storage_calib_history(st, a, 10, 20, &l, NULL) == 0 && l.n == 3);
    CHECK(l.n == 3 && l.items[0].id == c3 && l.items[1].id == c2 && l.items[2].id == c1);
    storage_calib_list_free(&l);
    /* the database itself allows one current map per pixel */
    CHECK(raw_int("calib.db", "SELECT count(*) FROM calibrations WHERE superseded_by IS NULL "
                              "AND pixel_col = 10 AND pixel_row = 20") == 2); /* a and b */
    CHECK(raw_exec("calib.db", "INSERT INTO calibrations (sensor_id, pixel_col, pixel_row, r, s, "
                               "s_err, status, noise_model, software_version, created_ms) VALUES "
                               "(1, 10, 20, 1, zeroblob(8), zeroblob(8), 'ok', 'paper', 'x', 0)")
          == SQLITE_CONSTRAINT);
    /* the map BLOB is little-endian float64: S[0] = 1.05 = 0x3FF0CCCCCCCCCCCD */
    char hex[40], sql[128];
    snprintf(sql, sizeof sql, "SELECT hex(substr(s, 1, 8)) FROM calibrations WHERE id = %lld",
             (long long)c3);
    raw_text("calib.db", sql, hex, sizeof hex);
    CHECK(strcmp(hex, "CDCCCCCCCCCCF03F") == 0);

    /* validation */
    err_t err = {{0}};
    double S[1] = {1};
    storage_calib_t bad = {.sensor_id = a, .pixel_col = 640, .pixel_row = 0, .r = 1, .S = S,
                           .S_err = S, .status = "ok", .noise_model = "paper"};
    int64_t id;
    CHECK(storage_calib_put(st, &bad, &id, &err) == -EINVAL && strstr(err.msg, "outside"));
    bad.pixel_col = 0;
    bad.sensor_id = 999;
    CHECK(storage_calib_put(st, &bad, &id, &err) == -ENOENT);
    bad.sensor_id = a;
    bad.scan_id = 999;
    CHECK(storage_calib_put(st, &bad, &id, &err) == -ENOENT);
    CHECK(raw_int("calib.db", "SELECT count(*) FROM calibrations") == 5);
    int64_t ids[5] = {c1, c2, c3, d, e};
    check_calib_search(st, a, ids, t2);
    storage_close(st);
}

/* Search over the calibrations of test_calibrations: ids c1, c2, c3 (sensor a, pixel (10, 20),
 * c3 "unconstrained"), d (a, (11, 20)), e (the other sensor, model CMV-B), c2 created at t2. */
static void check_calib_search(storage_t *st, int64_t a, const int64_t *ids, int64_t t2)
{
    int64_t c3 = ids[2], d = ids[3], e = ids[4];
    storage_calib_list_t l;
    storage_calib_filter_t f = storage_calib_filter_default();
    CHECK(storage_calib_search(st, &f, 2, 1, &l, NULL) == 0 && l.total == 5 && l.n == 2);
    CHECK(l.n == 2 && l.items[0].id == d && l.items[1].id == c3); /* newest first: e, d, c3 */
    storage_calib_list_free(&l);
    f.model = "CMV-B";
    CHECK(storage_calib_search(st, &f, 0, 0, &l, NULL) == 0 && l.total == 1 && l.items[0].id == e);
    storage_calib_list_free(&l);
    f = storage_calib_filter_default();
    f.sensor_id = a;
    f.current_only = 1;
    CHECK(storage_calib_search(st, &f, 0, 0, &l, NULL) == 0 && l.total == 2 && l.n == 2);
    storage_calib_list_free(&l);
    f.current_only = 0;
    f.col_min = f.col_max = 11;
    CHECK(storage_calib_search(st, &f, 0, 0, &l, NULL) == 0 && l.total == 1 && l.items[0].id == d);
    storage_calib_list_free(&l);
    f = storage_calib_filter_default();
    f.since_ms = t2;
    CHECK(storage_calib_search(st, &f, 0, 0, &l, NULL) == 0 && l.total == 4);
    storage_calib_list_free(&l);
    f.status = "unconstrained";
    CHECK(storage_calib_search(st, &f, 0, 0, &l, NULL) == 0 && l.total == 1 && l.items[0].id == c3);
    storage_calib_list_free(&l);
}

static void test_pagination(void)
{
    storage_t *st = open_db("page.db");
    int64_t a = make_sensor(st, "IMX-P", "1"), b = make_sensor(st, "IMX-P", "2"), ids[5], id;
    storage_scan_t sc = scan_template(a);
    for (int k = 0; k < 5; k++) CHECK(storage_scan_create(st, &sc, &ids[k], NULL) == 0);
    sc.sensor_id = b;
    for (int k = 0; k < 3; k++) CHECK(storage_scan_create(st, &sc, &id, NULL) == 0);
    CHECK(storage_scan_set_state(st, ids[1], STORAGE_RUNNING, NULL, NULL) == 0);
    CHECK(storage_scan_set_state(st, ids[3], STORAGE_RUNNING, NULL, NULL) == 0);
    CHECK(storage_scan_set_state(st, ids[4], STORAGE_DONE, NULL, NULL) == 0);
    storage_scan_list_t l;
    CHECK(storage_scan_list(st, a, STORAGE_ANY, 2, 0, &l, NULL) == 0 && l.total == 5 && l.n == 2);
    CHECK(l.n == 2 && l.items[0].id == ids[4] && l.items[1].id == ids[3]);
    storage_scan_list_free(&l);
    CHECK(storage_scan_list(st, a, STORAGE_ANY, 2, 4, &l, NULL) == 0 && l.total == 5 && l.n == 1);
    CHECK(l.n == 1 && l.items[0].id == ids[0]);
    storage_scan_list_free(&l);
    CHECK(storage_scan_list(st, a, STORAGE_ANY, 2, 5, &l, NULL) == 0 && l.total == 5 && l.n == 0);
    storage_scan_list_free(&l);
    CHECK(storage_scan_list(st, 0, STORAGE_RUNNING, 0, 0, &l, NULL) == 0 && l.total == 2);
    CHECK(l.n == 2 && l.items[0].id == ids[3] && l.items[1].id == ids[1]);
    storage_scan_list_free(&l);
    CHECK(storage_scan_list(st, 0, STORAGE_ANY, 0, 0, &l, NULL) == 0 && l.total == 8 && l.n == 8);
    storage_scan_list_free(&l);
    CHECK(storage_scan_list(st, b, STORAGE_DONE, 10, 0, &l, NULL) == 0 && l.total == 0);
    storage_scan_list_free(&l);
    CHECK(storage_scan_list(st, a, 17, 10, 0, &l, NULL) == -EINVAL);

    storage_sensor_list_t sl;
    CHECK(storage_sensor_list(st, 0, 0, &sl, NULL) == 0 && sl.n == 2 && sl.items[0].id == a);
    storage_sensor_list_free(&sl);
    /* a page: the second sensor alone, total still counting both */
    CHECK(storage_sensor_list(st, 1, 1, &sl, NULL) == 0 && sl.n == 1 && sl.total == 2 &&
          sl.items[0].id == b);
    storage_sensor_list_free(&sl);
    CHECK(storage_sensor_list(st, 5, -1, &sl, NULL) == -EINVAL);
    for (int k = 0; k < 4; k++)
        CHECK(storage_job_enqueue(st, k % 2 ? STORAGE_JOB_FIT : STORAGE_JOB_SCAN, "[]",
                                  k < 2 ? ids[0] : 0, &id, NULL) == 0);
    storage_job_list_t jl;
    CHECK(storage_job_list(st, STORAGE_JOB_FIT, STORAGE_QUEUED, 0, 1, 0, &jl, NULL) == 0);
    CHECK(jl.total == 2 && jl.n == 1 && jl.items[0].id == id);
    storage_job_list_free(&jl);
    CHECK(storage_job_list(st, STORAGE_ANY, STORAGE_ANY, ids[0], 0, 0, &jl, NULL) == 0);
    CHECK(jl.total == 2 && jl.n == 2);
    storage_job_list_free(&jl);
    /* each listed scan carries its newest scan job's params (not a fit job's), NULL without */
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{\"fit\": 1}", ids[0], &id, NULL) == 0);
    CHECK(storage_scan_list(st, a, STORAGE_ANY, 0, 0, &l, NULL) == 0 && l.n == 5);
    CHECK(l.items[4].id == ids[0] && l.items[4].job_params &&
          strcmp(l.items[4].job_params, "[]") == 0);
    CHECK(!l.items[0].job_params && !l.items[3].job_params);
    storage_scan_list_free(&l);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_SCAN, "{\"again\": 2}", ids[0], &id, NULL) == 0);
    CHECK(storage_scan_list(st, a, STORAGE_ANY, 1, 4, &l, NULL) == 0 && l.n == 1);
    CHECK(l.items[0].id == ids[0] && l.items[0].job_params &&
          strcmp(l.items[0].job_params, "{\"again\": 2}") == 0);
    storage_scan_list_free(&l);
    CHECK(storage_scan_get(st, ids[0], &sc, NULL) == 0 && !sc.job_params);
    storage_scan_free(&sc);
    storage_close(st);
}

/* ---- schema 3: the map each fit offers, promotion, provenance ------------------------------ */

/* Does the first column of the first row of sql (e.g. hex(s), read by a raw connection) equal
 * want? Says what it got when not. */
static int raw_hex_eq(const char *name, const char *sql, const char *want)
{
    char got[600];
    raw_text(name, sql, got, sizeof got);
    if (strcmp(got, want) != 0) fprintf(stderr, "%s: got %s, want %s\n", sql, got, want);
    return strcmp(got, want) == 0;
}

/* A fit stored without promote keeps its map (fit_maps) and leaves the pixel's current
 * calibration alone; promoting it supersedes that one with its map and the provenance given;
 * promoting it again, a fit without a map or an unknown fit are refused and write nothing. */
static void test_promote(void)
{
    storage_t *st = open_db("promote.db");
    int64_t sensor = make_sensor(st, "IMX-PR", "1"), scan = make_running_scan(st, sensor);
    int64_t auto_fit, auto_cal, refit, refit_cal = -1, cal, bare;
    storage_fit_t f = {.scan_id = scan, .noise_model = "paper", .result = "{}"}, g;
    /* S[0] = 1.25 = 0x3FF4000000000000 and 0.75 = 0x3FE8000000000000, little-endian in the BLOB */
    double S1[1] = {1.25}, S2[1] = {0.75}, E[1] = {0.5};
    storage_calib_t c = {.sensor_id = sensor, .pixel_col = 7, .pixel_row = 8, .r = 1, .S = S1,
                         .S_err = E, .I0 = 10, .chi2_red = 1, .status = "ok",
                         .noise_model = "paper", .wavelength_um = 0.55, .na = 0.25,
                         .spot_radius_um = 1.342, .by = "ipsd",
                         .reason = "automatic fit of scan 1"};
    fake_now += 1000;
    CHECK(storage_fit_store(st, &f, &c, 1, 0, &auto_fit, &auto_cal, NULL) == 0 && auto_cal > 0);
    c.S = S2;
    c.by = NULL; /* storage's defaults */
    c.reason = NULL;
    fake_now += 1000;
    CHECK(storage_fit_store(st, &f, &c, 0, 0, &refit, &refit_cal, NULL) == 0 && refit_cal == 0);
    /* the re-fit changed nothing of the calibrations (a raw reader) but kept its map */
    CHECK(raw_int("promote.db", "SELECT count(*) FROM calibrations") == 1);
    CHECK(raw_int("promote.db", "SELECT fit_id FROM calibrations WHERE superseded_by IS NULL") ==
          auto_fit);
    CHECK(raw_hex_eq("promote.db", "SELECT hex(s) FROM fit_maps WHERE fit_id = 2",
                     "000000000000E83F"));
    CHECK(storage_fit_get(st, refit, &g, NULL) == 0);
    CHECK(g.map_sensor_id == sensor && g.map_col == 7 && g.map_row == 8 && g.map_r == 1);
    CHECK(g.pixel_calib_id == auto_cal && g.pixel_calib_fit_id == auto_fit);
    storage_fit_free(&g);
    CHECK(storage_fit_get(st, auto_fit, &g, NULL) == 0 && g.pixel_calib_fit_id == auto_fit);
    storage_fit_free(&g);

    /* promoted: a new row with the re-fit's map, superseding the automatic one */
    fake_now += 1000;
    err_t err = {{0}};
    CHECK(storage_calib_promote(st, refit, "alice", "r 1..4 is enough", &cal, &err) == 0);
    storage_calib_t got;
    CHECK(storage_calib_current(st, sensor, 7, 8, &got, NULL) == 0 && got.id == cal);
    CHECK(got.fit_id == refit && got.scan_id == scan && got.supersedes == auto_cal);
    CHECK(got.S && got.S[0] == 0.75 && got.I0 == 10 && got.spot_radius_um == 1.342);
    CHECK(got.by && strcmp(got.by, "alice") == 0 && strcmp(got.reason, "r 1..4 is enough") == 0);
    CHECK(got.created_ms == fake_now && strcmp(got.noise_model, "paper") == 0);
    storage_calib_free(&got);
    CHECK(storage_calib_get(st, auto_cal, &got, NULL) == 0 && got.superseded_by == cal);
    CHECK(got.supersedes == 0 && strcmp(got.by, "ipsd") == 0);
    CHECK(strcmp(got.reason, "automatic fit of scan 1") == 0);
    storage_calib_free(&got);
    CHECK(raw_hex_eq("promote.db", "SELECT hex(s) FROM calibrations WHERE superseded_by IS NULL",
                     "000000000000E83F"));

    /* refused, writing nothing: already current, no map, unknown fit, empty by */
    int64_t id = -1;
    CHECK(storage_calib_promote(st, refit, NULL, NULL, &id, &err) == -EALREADY && id == cal);
    CHECK(strstr(err.msg, "already") != NULL);
    CHECK(storage_fit_put(st, &f, NULL, 0, &bare, NULL, NULL) == 0);
    CHECK(storage_calib_promote(st, bare, NULL, NULL, &id, &err) == -ENODATA && id == 0);
    CHECK(storage_calib_promote(st, 999, NULL, NULL, &id, &err) == -ENOENT);
    CHECK(strstr(err.msg, "999") != NULL);
    CHECK(storage_calib_promote(st, auto_fit, "", NULL, &id, &err) == -EINVAL);
    CHECK(raw_int("promote.db", "SELECT count(*) FROM calibrations") == 2);

    /* back to the automatic fit's map: promoted again, with storage's default by and reason */
    fake_now += 1000;
    CHECK(storage_calib_promote(st, auto_fit, NULL, NULL, &id, &err) == 0 && id > cal);
    CHECK(storage_calib_get(st, id, &got, NULL) == 0 && got.supersedes == cal);
    CHECK(got.S[0] == 1.25 && strcmp(got.by, "ipsd") == 0);
    CHECK(strcmp(got.reason, "no reason given") == 0);
    storage_calib_free(&got);
    storage_calib_list_t l;
    CHECK(storage_calib_history(st, sensor, 7, 8, &l, NULL) == 0 && l.n == 3);
    CHECK(l.n == 3 && l.items[0].fit_id == auto_fit && l.items[1].fit_id == refit &&
          l.items[2].fit_id == auto_fit && l.items[0].supersedes == l.items[1].id &&
          l.items[1].supersedes == l.items[2].id && l.items[2].supersedes == 0);
    storage_calib_list_free(&l);
    /* a refused map (pixel outside the sensor) stores neither the fit nor its map */
    c.pixel_col = 640;
    CHECK(storage_fit_store(st, &f, &c, 0, 0, NULL, NULL, &err) == -EINVAL);
    CHECK(raw_int("promote.db", "SELECT count(*) FROM fits") == 3);
    CHECK(raw_int("promote.db", "SELECT count(*) FROM fit_maps") == 2);
    storage_close(st);
}

/* A schema-2 database (migrations 1 and 2 run by hand) with a pixel's history of two maps from
 * two fits and a map without a fit migrates to schema 3 keeping every row: the superseded link
 * read backwards as supersedes, "ipsd" and a reason for every earlier row, and each fit's map
 * kept in fit_maps, so the older fit can be promoted again. */
static void test_migrate_v2(void)
{
    CHECK(raw_exec("v2m.db", stg_migrations[0]) == SQLITE_OK);
    CHECK(raw_exec("v2m.db", "PRAGMA foreign_keys = OFF;") == SQLITE_OK);
    CHECK(raw_exec("v2m.db", stg_migrations[1]) == SQLITE_OK);
    CHECK(raw_int("v2m.db", "PRAGMA user_version") == 2);
    CHECK(raw_exec("v2m.db",
                   "INSERT INTO sensors VALUES (1, 'M', 'S', 10, 10, 6, 3, 5, 100, 16383, 1);"
                   "INSERT INTO scans (id, sensor_id, poi_col, poi_row, wavelength_um, na, "
                   "spot_radius_um, area_px, step_um, sub_px, frames, exposure_us, points_total, "
                   "created_ms) VALUES (1, 1, 5, 5, 0.55, 0.25, 1.342, 5, 0.6, 3, 2, 10, 9, 1);"
                   "INSERT INTO fits (id, scan_id, dcol, drow, noise_model, result, created_ms) "
                   "VALUES (7, 1, 0, 0, 'paper', '{}', 2), (8, 1, 0, 0, 'shot+read', '{}', 3);"
                   "INSERT INTO calibrations (id, sensor_id, pixel_col, pixel_row, r, s, s_err, "
                   "status, scan_id, fit_id, noise_model, software_version, created_ms, "
                   "superseded_by) VALUES "
                   "(4, 1, 5, 5, 1, x'000000000000F43F', zeroblob(8), 'ok', 1, 7, 'paper', "
                   "'0.1', 3, 5), "
                   "(5, 1, 5, 5, 1, x'000000000000E83F', zeroblob(8), 'ok', 1, 8, 'shot+read', "
                   "'0.1', 4, NULL), "
                   "(6, 1, 6, 5, 1, zeroblob(8), zeroblob(8), 'ok', NULL, NULL, 'paper', "
                   "'0.1', 5, NULL);") == SQLITE_OK);
    storage_t *st = open_db("v2m.db");
    CHECK(raw_int("v2m.db", "PRAGMA user_version") == storage_schema_version()); /* and on */
    CHECK(raw_int("v2m.db", "SELECT count(*) FROM calibrations") == 3);
    CHECK(raw_int("v2m.db", "SELECT count(*) FROM fits") == 2);
    CHECK(raw_int("v2m.db", "SELECT supersedes FROM calibrations WHERE id = 5") == 4);
    CHECK(raw_int("v2m.db", "SELECT count(*) FROM calibrations WHERE supersedes IS NULL") == 2);
    CHECK(raw_int("v2m.db", "SELECT superseded_by FROM calibrations WHERE id = 4") == 5);
    CHECK(raw_int("v2m.db", "SELECT count(*) FROM calibrations WHERE changed_by = 'ipsd' AND "
                            "reason LIKE 'stored when its fit finished%'") == 3);
    CHECK(raw_int("v2m.db", "SELECT count(*) FROM fit_maps") == 2);
    CHECK(raw_hex_eq("v2m.db", "SELECT hex(s) FROM fit_maps WHERE fit_id = 7",
                     "000000000000F43F"));
    CHECK(raw_int("v2m.db", "SELECT count(*) FROM pragma_foreign_key_check") == 0);
    storage_calib_t c;
    CHECK(st && storage_calib_get(st, 5, &c, NULL) == 0 && c.supersedes == 4);
    CHECK(c.by && strcmp(c.by, "ipsd") == 0 && c.S && c.S[0] == 0.75);
    storage_calib_free(&c);
    storage_fit_t f;
    CHECK(storage_fit_get(st, 7, &f, NULL) == 0 && f.map_sensor_id == 1 && f.map_col == 5);
    CHECK(f.pixel_calib_id == 5 && f.pixel_calib_fit_id == 8);
    storage_fit_free(&f);
    /* the older fit promoted again: its map (1.25) from the migrated fit_maps */
    int64_t id = 0;
    CHECK(storage_calib_promote(st, 7, "bob", "the paper noise model", &id, NULL) == 0);
    CHECK(storage_calib_current(st, 1, 5, 5, &c, NULL) == 0 && c.id == id && c.S[0] == 1.25);
    CHECK(c.supersedes == 5 && strcmp(c.noise_model, "paper") == 0);
    CHECK(strcmp(c.software_version, "0.1") == 0); /* the version that made the map */
    storage_calib_free(&c);
    storage_close(st);
}

/* Sensor 1 (a 10 x 10 sensor) and its done scan 1 of POI (5, 5): the rows the migration tests
 * from schema 5 on hang their fits and maps on. */
#define SENSOR_AND_DONE_SCAN                                                                      \
    "INSERT INTO sensors VALUES (1, 'M', 'S', 10, 10, 6, 3, 5, 100, 16383, 1);"                   \
    "INSERT INTO scans (id, sensor_id, poi_col, poi_row, wavelength_um, na, spot_radius_um, "     \
    "area_px, step_um, sub_px, frames, exposure_us, points_total, state, points_done, "           \
    "created_ms) VALUES (1, 1, 5, 5, 0.55, 0.25, 1.342, 5, 0.6, 3, 2, 10, 9, 'done', 9, 1);"

/* Runs migrations 1 to v on the new database name by hand (an older ipsd's file). */
static void migrate_by_hand(const char *name, int v)
{
    for (int i = 0; i < v; i++)
        CHECK(raw_exec(name, stg_migrations[i]) == SQLITE_OK);
    CHECK(raw_int(name, "PRAGMA user_version") == v);
}

/* A schema-6 database (migrations 1 to 6 run by hand) migrates to schema 7 with each fit's map
 * and each calibration named: `shrunk` for the fit whose job asked for "map": "shrunk" and whose
 * document has a shrunk_map (and for both calibrations of that fit), `recommended` for a job
 * that asked but whose fit had no shrunk map (it stored the recommended one), for a fit without
 * a job and for a calibration without a fit; no row's resolution error (s_res) is known. Promoting
 * the shrunk fit again keeps the word, and a fit stored now with shrunk = 1 and its S_res reads
 * back so (fit_maps, then its promoted calibration). */
static void test_migrate_v6(void)
{
    migrate_by_hand("v6m.db", 6);
    CHECK(raw_exec("v6m.db",
                   SENSOR_AND_DONE_SCAN
                   "INSERT INTO jobs (id, kind, params, state, progress, points_done, created_ms, "
                   "scan_id, fit_id) VALUES "
                   "(1, 'fit', '{\"scan_id\": 1, \"map\": \"shrunk\"}', 'done', 1, 0, 2, 1, 21),"
                   "(2, 'fit', '{\"scan_id\": 1, \"map\": \"shrunk\"}', 'done', 1, 0, 3, 1, 22),"
                   "(3, 'fit', '{\"scan_id\": 1}', 'done', 1, 0, 4, 1, 23);"
                   "INSERT INTO fits (id, scan_id, dcol, drow, noise_model, result, created_ms, "
                   "job_id) VALUES "
                   "(21, 1, 0, 0, 'paper', '{\"shrunk_map\": {\"r\": 1}}', 2, 1), "
                   "(22, 1, 0, 0, 'paper', '{\"shrunk_map\": null}', 3, 2), "
                   "(23, 1, 0, 0, 'paper', '{}', 4, 3), "
                   "(24, 1, 0, 0, 'paper', '{}', 5, NULL);"
                   "INSERT INTO fit_maps (fit_id, sensor_id, pixel_col, pixel_row, r, s, s_err, "
                   "status, software_version) VALUES "
                   "(21, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', '0.1'), "
                   "(22, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', '0.1'), "
                   "(23, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', '0.1'), "
                   "(24, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', '0.1');"
                   "INSERT INTO calibrations (id, sensor_id, pixel_col, pixel_row, r, s, s_err, "
                   "status, scan_id, fit_id, noise_model, software_version, created_ms, "
                   "superseded_by, supersedes) VALUES "
                   "(1, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', 1, 21, 'paper', "
                   "'0.1', 2, 2, NULL), "
                   "(2, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', 1, 22, 'paper', "
                   "'0.1', 3, 3, 1), "
                   "(3, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', 1, 21, 'paper', "
                   "'0.1', 4, 4, 2), "
                   "(4, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), 'ok', NULL, NULL, 'paper', "
                   "'0.1', 5, NULL, 3);") == SQLITE_OK);
    storage_t *st = open_db("v6m.db");
    if (!st) return;
    CHECK(raw_int("v6m.db", "PRAGMA user_version") == storage_schema_version()); /* and on */
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM pragma_foreign_key_check") == 0);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM fit_maps") == 4);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM calibrations") == 4);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM fit_maps WHERE map = 'shrunk'") == 1);
    CHECK(raw_int("v6m.db", "SELECT fit_id FROM fit_maps WHERE map = 'shrunk'") == 21);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM fit_maps WHERE map = 'recommended'") == 3);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM calibrations WHERE map = 'shrunk' "
                            "AND id IN (1, 3)") == 2);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM calibrations WHERE map = 'recommended' "
                            "AND id IN (2, 4)") == 2);
    storage_calib_t c;
    CHECK(storage_calib_get(st, 3, &c, NULL) == 0 && c.map == STORAGE_MAP_SHRUNK);
    CHECK(c.S_res == NULL);
    storage_calib_free(&c);
    CHECK(storage_calib_get(st, 4, &c, NULL) == 0 && c.map == STORAGE_MAP_RECOMMENDED);
    storage_calib_free(&c);
    int64_t id = 0;
    CHECK(storage_calib_promote(st, 21, "bob", "the shrunk map again", &id, NULL) == 0);
    CHECK(storage_calib_current(st, 1, 5, 5, &c, NULL) == 0 && c.id == id);
    CHECK(c.map == STORAGE_MAP_SHRUNK);
    storage_calib_free(&c);
    CHECK(storage_calib_promote(st, 23, "bob", "back to r's own map", &id, NULL) == 0);
    CHECK(storage_calib_current(st, 1, 5, 5, &c, NULL) == 0 && c.id == id);
    CHECK(c.map == STORAGE_MAP_RECOMMENDED);
    storage_calib_free(&c);
    /* stored now: the fit's map is shrunk, kept in fit_maps, promoted later */
    double S = 1, E = 0.01, Res = 0.02;
    storage_fit_t f = {.scan_id = 1, .noise_model = "paper", .result = "{}"};
    storage_calib_t m = {.sensor_id = 1, .pixel_col = 5, .pixel_row = 5, .r = 1, .S = &S,
                         .S_err = &E, .status = "ok", .scan_id = 1, .noise_model = "paper",
                         .wavelength_um = NAN, .na = NAN, .spot_radius_um = NAN, .I0 = NAN,
                         .chi2_red = NAN, .map = STORAGE_MAP_SHRUNK, .S_res = &Res};
    int64_t fid = 0;
    CHECK(storage_fit_store(st, &f, &m, 0, 0, &fid, NULL, NULL) == 0 && fid > 0);
    CHECK(raw_int("v6m.db", "SELECT count(*) FROM fit_maps WHERE map = 'shrunk'") == 2);
    CHECK(raw_hex_eq("v6m.db", "SELECT hex(s_res) FROM fit_maps WHERE map = 'shrunk' AND "
                               "s_res IS NOT NULL", "7B14AE47E17A943F")); /* 0.02 */
    CHECK(storage_calib_promote(st, fid, NULL, NULL, &id, NULL) == 0);
    CHECK(storage_calib_current(st, 1, 5, 5, &c, NULL) == 0 && c.id == id);
    CHECK(c.map == STORAGE_MAP_SHRUNK);
    CHECK(c.S_res && c.S_res[0] == 0.02);
    storage_calib_free(&c);
    /* a BLOB of the wrong size is refused by the table */
    CHECK(raw_exec("v6m.db", "UPDATE calibrations SET s_res = zeroblob(16) WHERE id = 1") !=
          SQLITE_OK);
    storage_close(st);
}

/* Every row of fit_maps and calibrations as text, in id order (the same text before and after a
 * migration is every value kept). */
#define FIT_MAPS_DUMP                                                                             \
    "SELECT group_concat(fit_id || '|' || sensor_id || '|' || pixel_col || '|' || pixel_row || " \
    "'|' || r || '|' || hex(s) || '|' || hex(s_err) || '|' || quote(i0) || '|' || "             \
    "quote(chi2_red) || '|' || status || '|' || quote(wavelength_um) || '|' || quote(na) || "    \
    "'|' || quote(spot_radius_um) || '|' || software_version || '|' || map || '|' || "           \
    "quote(s_res), ';') FROM (SELECT * FROM fit_maps ORDER BY fit_id)"
#define CALIBRATIONS_DUMP                                                                         \
    "SELECT group_concat(id || '|' || sensor_id || '|' || pixel_col || '|' || pixel_row || '|' " \
    "|| r || '|' || hex(s) || '|' || hex(s_err) || '|' || quote(i0) || '|' || quote(chi2_red) " \
    "|| '|' || status || '|' || quote(scan_id) || '|' || quote(fit_id) || '|' || noise_model " \
    "|| '|' || quote(wavelength_um) || '|' || quote(na) || '|' || quote(spot_radius_um) || '|' " \
    "|| software_version || '|' || created_ms || '|' || quote(superseded_by) || '|' || "         \
    "quote(supersedes) || '|' || changed_by || '|' || reason || '|' || map || '|' || "           \
    "quote(s_res), ';') FROM (SELECT * FROM calibrations ORDER BY id)"

/* A schema-7 database (migrations 1 to 7 run by hand) migrates to schema 8, which lets in the
 * kriged map: fit_maps and calibrations are rebuilt with every row's every value kept (the dump
 * of each table is the same text before and after), the foreign keys hold, the indexes are back
 * (a second current calibration of a pixel is refused), a word the CHECK does not know is still
 * refused, and a kriged map on its fine grid (r = 28) is stored as a fit's map and promoted to
 * the calibration that says so. */
static void test_migrate_v7(void)
{
    migrate_by_hand("v7m.db", 7);
    CHECK(raw_exec("v7m.db",
                   SENSOR_AND_DONE_SCAN
                   "INSERT INTO fits (id, scan_id, dcol, drow, noise_model, result, created_ms) "
                   "VALUES (31, 1, 0, 0, 'paper', '{}', 2), (32, 1, 0, 0, 'paper', '{}', 3), "
                   "(33, 1, 0, 0, 'paper', '{}', 4);"
                   "INSERT INTO fit_maps (fit_id, sensor_id, pixel_col, pixel_row, r, s, s_err, "
                   "i0, chi2_red, status, wavelength_um, na, spot_radius_um, software_version, "
                   "map, s_res) VALUES "
                   "(31, 1, 5, 5, 1, x'000000000000F03F', x'7B14AE47E17A843F', 2.5e5, 1.1, 'ok', "
                   "0.55, 0.25, 1.342, '0.7', 'recommended', NULL), "
                   "(32, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), NULL, NULL, 'poor_fit', "
                   "NULL, NULL, NULL, '0.8', 'shrunk', x'7B14AE47E17A943F');"
                   "INSERT INTO calibrations (id, sensor_id, pixel_col, pixel_row, r, s, s_err, "
                   "i0, chi2_red, status, scan_id, fit_id, noise_model, wavelength_um, na, "
                   "spot_radius_um, software_version, created_ms, superseded_by, supersedes, "
                   "changed_by, reason, map, s_res) VALUES "
                   "(1, 1, 5, 5, 1, x'000000000000F03F', x'7B14AE47E17A843F', 2.5e5, 1.1, 'ok', "
                   "1, 31, 'paper', 0.55, 0.25, 1.342, '0.7', 5, 2, NULL, 'ipsd', 'automatic', "
                   "'recommended', NULL), "
                   "(2, 1, 5, 5, 1, x'000000000000F03F', zeroblob(8), NULL, NULL, 'poor_fit', "
                   "1, 32, 'paper', NULL, NULL, NULL, '0.8', 6, NULL, 1, 'alice', 'shrunk', "
                   "'shrunk', x'7B14AE47E17A943F'), "
                   "(3, 1, 6, 5, 1, x'000000000000F03F', zeroblob(8), NULL, NULL, 'ok', "
                   "NULL, NULL, 'shot+read', NULL, NULL, NULL, '0.8', 7, NULL, NULL, 'bob', "
                   "'upload', 'recommended', NULL);") == SQLITE_OK);
    char maps7[2048], calibs7[4096], maps8[2048], calibs8[4096];
    raw_text("v7m.db", FIT_MAPS_DUMP, maps7, sizeof maps7);
    raw_text("v7m.db", CALIBRATIONS_DUMP, calibs7, sizeof calibs7);
    CHECK(strstr(maps7, "shrunk") && strstr(calibs7, "alice")); /* the dumps hold the rows */
    storage_t *st = open_db("v7m.db");
    if (!st) return;
    CHECK(raw_int("v7m.db", "PRAGMA user_version") == storage_schema_version());
    /* migration 9: map_note, NULL on every older row */
    CHECK(raw_int("v7m.db", "SELECT count(*) FROM calibrations WHERE map_note IS NULL") == 3);
    CHECK(raw_int("v7m.db", "SELECT count(*) FROM fit_maps WHERE map_note IS NULL") == 2);
    raw_text("v7m.db", FIT_MAPS_DUMP, maps8, sizeof maps8);
    raw_text("v7m.db", CALIBRATIONS_DUMP, calibs8, sizeof calibs8);
    CHECK(strcmp(maps7, maps8) == 0);
    CHECK(strcmp(calibs7, calibs8) == 0);
    CHECK(raw_int("v7m.db", "SELECT count(*) FROM pragma_foreign_key_check") == 0);
    CHECK(raw_int("v7m.db", "SELECT count(*) FROM sqlite_master WHERE type = 'index' AND name IN "
                            "('calibrations_current', 'calibrations_pixel', "
                            "'calibrations_created', 'calibrations_fit')") == 4);
    CHECK(raw_int("v7m.db", "SELECT count(*) FROM sqlite_master WHERE name LIKE '%_v8'") == 0);
    /* the partial unique index: one current calibration per pixel */
    CHECK(raw_exec("v7m.db", "UPDATE calibrations SET superseded_by = NULL WHERE id = 1") !=
          SQLITE_OK);
    CHECK(raw_exec("v7m.db", "UPDATE calibrations SET map = 'bogus' WHERE id = 1") != SQLITE_OK);
    storage_calib_t c;
    CHECK(storage_calib_get(st, 2, &c, NULL) == 0 && c.map == STORAGE_MAP_SHRUNK);
    CHECK(c.supersedes == 1 && c.S_res && c.S_res[0] == 0.02 && strcmp(c.by, "alice") == 0);
    storage_calib_free(&c);
    /* a kriged map: F = 28 for r = 7 (fit/krige.h), stored as the fit's map, promoted */
    enum { F = 28 };
    double S[F * F], E[F * F];
    for (int i = 0; i < F * F; i++) S[i] = 1, E[i] = 0.01;
    storage_fit_t f = {.scan_id = 1, .noise_model = "paper", .result = "{}"};
    storage_calib_t m = {.sensor_id = 1, .pixel_col = 5, .pixel_row = 5, .r = F, .S = S,
                         .S_err = E, .status = "ok", .scan_id = 1, .noise_model = "paper",
                         .wavelength_um = NAN, .na = NAN, .spot_radius_um = NAN, .I0 = NAN,
                         .chi2_red = NAN, .map = STORAGE_MAP_KRIGED};
    int64_t fid = 0, id = 0;
    CHECK(storage_fit_store(st, &f, &m, 0, 0, &fid, NULL, NULL) == 0 && fid > 0);
    CHECK(raw_int("v7m.db", "SELECT r FROM fit_maps WHERE map = 'kriged'") == F);
    CHECK(storage_calib_promote(st, fid, "carol", "the kriged map", &id, NULL) == 0);
    CHECK(storage_calib_current(st, 1, 5, 5, &c, NULL) == 0 && c.id == id);
    CHECK(c.map == STORAGE_MAP_KRIGED && c.r == F && c.supersedes == 2 && c.S_res == NULL);
    CHECK(c.S_err && c.S_err[F * F - 1] == 0.01);
    storage_calib_free(&c);
    CHECK(raw_int("v7m.db", "SELECT superseded_by FROM calibrations WHERE id = 2") == id);
    storage_close(st);
}

/* A schema-5 database (migrations 1 to 5 run by hand), where a job of every pixel kept its fits
 * in its params' "fit_ids", migrates to schema 6 with each fit's job recorded: the jobs answer
 * the same fit_ids in the same order (from SQL now) and their params lose only "fit_ids"; an
 * ordinary fit job's fit records it from the job's fit_id, a fit without a job records none,
 * other params stay byte for byte. The half-done job of every pixel then resumes: its next
 * pixel joins its fit_ids, a pixel stored already is refused (a rerun stores none twice). */
static void test_migrate_v5(void)
{
    migrate_by_hand("v5m.db", 5);
    CHECK(raw_exec("v5m.db",
                   SENSOR_AND_DONE_SCAN
                   "INSERT INTO fits (id, scan_id, dcol, drow, noise_model, result, created_ms) "
                   "VALUES (11, 1, -1, -1, 'paper', '{}', 2), (12, 1, 0, -1, 'paper', '{}', 3), "
                   "(13, 1, 1, -1, 'paper', '{}', 4), (14, 1, 0, 0, 'paper', '{}', 5), "
                   "(15, 1, 0, 0, 'paper', '{}', 6), (16, 1, -1, -1, 'paper', '{}', 7), "
                   "(17, 1, 0, -1, 'paper', '{}', 8);"
                   "INSERT INTO jobs (id, kind, params, state, progress, points_done, created_ms, "
                   "scan_id, fit_id) VALUES "
                   "(5, 'fit', '{\"scan_id\":1,\"pixels\":\"all\",\"r_max\":4,"
                   "\"fit_ids\":[11,12,13]}', 'done', 1, 3, 2, 1, 13),"
                   "(6, 'fit', '{\"scan_id\": 1, \"r_max\": 4}', 'done', 1, 0, 5, 1, 14),"
                   "(7, 'scan', '{\"seed\": 3}', 'done', 1, 9, 1, 1, NULL),"
                   "(8, 'fit', '{\"scan_id\":1,\"pixels\":\"all\",\"fit_ids\":[16,17]}', "
                   "'running', 0.67, 2, 7, 1, 17),"
                   "(9, 'fit', '{\"scan_id\": 1, \"pixels\": \"all\"}', 'queued', 0, 0, 9, "
                   "1, NULL);") == SQLITE_OK);
    storage_t *st = open_db("v5m.db");
    if (!st) return;
    CHECK(raw_int("v5m.db", "PRAGMA user_version") == storage_schema_version()); /* and on */
    CHECK(raw_int("v5m.db", "SELECT count(*) FROM pragma_foreign_key_check") == 0);
    CHECK(raw_int("v5m.db", "SELECT count(*) FROM pragma_index_list('fits') "
                            "WHERE name = 'fits_job'") == 1);
    CHECK(raw_int("v5m.db", "SELECT count(*) FROM fits WHERE job_id = 5 AND id IN (11, 12, 13)") ==
          3);
    CHECK(raw_int("v5m.db", "SELECT job_id FROM fits WHERE id = 14") == 6);
    CHECK(raw_int("v5m.db", "SELECT count(*) FROM fits WHERE job_id IS NULL") == 1); /* 15 */
    CHECK(raw_int("v5m.db", "SELECT count(*) FROM jobs WHERE params LIKE '%fit_ids%'") == 0);
    storage_job_t j;
    CHECK(storage_job_get(st, 5, &j, NULL) == 0 && j.fit_id == 13 && j.points_done == 3);
    CHECK(j.fit_ids && strcmp(j.fit_ids, "[11,12,13]") == 0);
    CHECK(j.params && strcmp(j.params, "{\"scan_id\":1,\"pixels\":\"all\",\"r_max\":4}") == 0);
    storage_job_free(&j);
    CHECK(storage_job_get(st, 6, &j, NULL) == 0 && j.fit_id == 14 && j.fit_ids == NULL);
    CHECK(j.params && strcmp(j.params, "{\"scan_id\": 1, \"r_max\": 4}") == 0);
    storage_job_free(&j);
    CHECK(storage_job_get(st, 7, &j, NULL) == 0 && strcmp(j.params, "{\"seed\": 3}") == 0);
    storage_job_free(&j);
    CHECK(storage_job_get(st, 9, &j, NULL) == 0 && j.fit_ids && strcmp(j.fit_ids, "[]") == 0);
    storage_job_free(&j);
    /* the list answers the same fit_ids (newest first: 9, 8, 7, 6, 5) */
    storage_job_list_t l;
    CHECK(storage_job_list(st, STORAGE_ANY, STORAGE_ANY, 0, 10, 0, &l, NULL) == 0 && l.n == 5);
    if (l.n == 5) {
        CHECK(l.items[1].id == 8 && l.items[1].fit_ids &&
              strcmp(l.items[1].fit_ids, "[16,17]") == 0);
        CHECK(l.items[3].id == 6 && l.items[3].fit_ids == NULL);
        CHECK(l.items[4].id == 5 && l.items[4].fit_ids &&
              strcmp(l.items[4].fit_ids, "[11,12,13]") == 0);
    }
    storage_job_list_free(&l);
    /* job 8, running at 2 of 3 pixels when the old ipsd stopped: requeued and claimed again */
    int requeued = 0;
    CHECK(storage_job_requeue_stale(st, 0, 0, &requeued, NULL, NULL) == 0 && requeued == 1);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == 8);
    CHECK(j.points_done == 2 && j.fit_ids && strcmp(j.fit_ids, "[16,17]") == 0);
    storage_job_free(&j);
    storage_fit_t f = {.scan_id = 1, .dcol = 0, .drow = -1, .noise_model = "paper", .result = "{}"};
    err_t err = {{0}};
    CHECK(storage_fit_store_unit(st, &f, NULL, 0, 8, 1, 3, NULL, NULL, &err) == -ESTALE);
    f.dcol = 1;
    int64_t u = 0;
    CHECK(storage_fit_store_unit(st, &f, NULL, 0, 8, 2, 3, &u, NULL, &err) == 0 && u == 18);
    CHECK(storage_job_get(st, 8, &j, NULL) == 0 && j.state == STORAGE_DONE && j.fit_id == 18);
    CHECK(j.fit_ids && strcmp(j.fit_ids, "[16,17,18]") == 0);
    storage_job_free(&j);
    CHECK(raw_int("v5m.db", "SELECT count(*) FROM fits") == 8);
    storage_close(st);
}

/* ---- driver --------------------------------------------------------------------------------- */

/* ---- schema 2 (ipsd server): scan setup, job release, fits of uploaded scans --------------- */

/* A schema-1 database as ipsd 0.1 made it (migration 1 run by hand on a raw connection), with a
 * fit referenced by a job and a calibration, migrates to the current schema keeping its rows,
 * ids and references, and foreign keys are on afterwards. */
static void test_migrate_v1(void)
{
    CHECK(raw_exec("v1.db", stg_migrations[0]) == SQLITE_OK);
    CHECK(raw_exec("v1.db",
                   "INSERT INTO sensors VALUES (1, 'M', 'S', 10, 10, 6, 3, 5, 100, 16383, 1);"
                   "INSERT INTO scans (id, sensor_id, poi_col, poi_row, wavelength_um, na, "
                   "spot_radius_um, area_px, step_um, sub_px, frames, exposure_us, points_total, "
                   "created_ms) VALUES (1, 1, 5, 5, 0.55, 0.25, 1.342, 5, 0.6, 3, 2, 10, 9, 1);"
                   "INSERT INTO fits (id, scan_id, dcol, drow, noise_model, result, created_ms) "
                   "VALUES (7, 1, 0, 0, 'paper', '{\"k\": 1}', 2);"
                   "INSERT INTO jobs (id, kind, params, created_ms, scan_id, fit_id) "
                   "VALUES (3, 'fit', '{}', 2, 1, 7);"
                   "INSERT INTO calibrations (id, sensor_id, pixel_col, pixel_row, r, s, s_err, "
                   "status, scan_id, fit_id, noise_model, software_version, created_ms) VALUES "
                   "(4, 1, 5, 5, 1, zeroblob(8), zeroblob(8), 'ok', 1, 7, 'paper', '0.1', 3);") ==
          SQLITE_OK);
    CHECK(raw_int("v1.db", "PRAGMA user_version") == 1);
    storage_t *st = open_db("v1.db");
    CHECK(raw_int("v1.db", "PRAGMA user_version") == storage_schema_version());
    storage_fit_t f;
    CHECK(st && storage_fit_get(st, 7, &f, NULL) == 0 && f.scan_id == 1);
    CHECK(f.result && strcmp(f.result, "{\"k\": 1}") == 0);
    storage_fit_free(&f);
    CHECK(raw_int("v1.db", "SELECT fit_id FROM jobs WHERE id = 3") == 7);
    CHECK(raw_int("v1.db", "SELECT count(*) FROM pragma_foreign_key_check") == 0);
    CHECK(raw_int("v1.db", "SELECT count(*) FROM pragma_index_list('fits') "
                           "WHERE name = 'fits_scan_pixel'") == 1);
    /* foreign keys are enforced on the handle: a fit of a scan that does not exist is refused */
    err_t err = {{0}};
    storage_fit_t bad = {.scan_id = 99, .noise_model = "paper", .result = "{}"};
    CHECK(storage_fit_put(st, &bad, NULL, 0, NULL, NULL, &err) == -ENOENT);
    storage_close(st);
}

static void test_setup_release_upload(void)
{
    storage_t *st = open_db("v2.db");
    int64_t sensor = make_sensor(st, "IMX-V2", "1"), scan = make_running_scan(st, sensor);
    char *json = (char *)"x";
    err_t err = {{0}};
    CHECK(storage_scan_get_setup(st, scan, &json, NULL) == 0 && json == NULL);
    CHECK(storage_scan_set_setup(st, scan, "{\"centre\": [1.5, -2]}", NULL) == 0);
    CHECK(storage_scan_get_setup(st, scan, &json, NULL) == 0 && json);
    CHECK(json && strcmp(json, "{\"centre\": [1.5, -2]}") == 0);
    free(json);
    CHECK(storage_scan_set_setup(st, scan, "{nope", &err) == -EINVAL && strstr(err.msg, "JSON"));
    CHECK(storage_scan_set_setup(st, 999, "{}", &err) == -ENOENT && strstr(err.msg, "999"));
    CHECK(storage_scan_get_setup(st, 999, &json, &err) == -ENOENT);

    /* an adaptive scan's count once it stopped: at least the points stored, then no more */
    CHECK(put_point(st, scan, 0, NULL) == 0 && put_point(st, scan, 1, NULL) == 0);
    CHECK(storage_scan_set_points_total(st, scan, 2, NULL) == 0);
    CHECK(raw_int("v2.db", "SELECT points_total FROM scans WHERE id = 1") == 2);
    CHECK(put_point(st, scan, 2, &err) == -EINVAL && strstr(err.msg, "point_index"));
    CHECK(storage_scan_set_points_total(st, scan, 1, &err) == -EINVAL &&
          strstr(err.msg, "below its 2 points"));
    CHECK(storage_scan_set_points_total(st, scan, 0, &err) == -EINVAL);
    CHECK(storage_scan_set_points_total(st, 999, 5, &err) == -ENOENT && strstr(err.msg, "999"));
    CHECK(raw_int("v2.db", "SELECT points_total FROM scans WHERE id = 1") == 2);

    /* release: a claimed job goes back, its claim not counted; only running jobs */
    int64_t job;
    storage_job_t j;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_SCAN, "{}", scan, &job, NULL) == 0);
    CHECK(storage_job_release(st, job, &err) == -ESTALE && strstr(err.msg, "queued"));
    CHECK(storage_job_claim(st, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == job);
    storage_job_free(&j);
    CHECK(storage_job_release(st, job, NULL) == 0);
    CHECK(raw_int("v2.db", "SELECT attempts FROM jobs WHERE id = 1") == 0);
    CHECK(raw_text_eq("v2.db", "SELECT state FROM jobs WHERE id = 1", "queued"));
    CHECK(raw_int("v2.db", "SELECT heartbeat_ms IS NULL FROM jobs WHERE id = 1") == 1);
    CHECK(storage_job_claim(st, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == job);
    CHECK(j.attempts == 1);
    storage_job_free(&j);
    int changed = 0;
    CHECK(storage_job_cancel(st, job, &changed, NULL) == 0 && changed == 1);
    CHECK(storage_job_release(st, job, &err) == -ECANCELED);
    CHECK(storage_job_release(st, 999, &err) == -ENOENT);

    /* a fit of an uploaded scan file: no scan, pixel (0, 0), with a calibration */
    double S[1] = {1.0}, E[1] = {0.25};
    storage_fit_t f = {.scan_id = 0, .noise_model = "paper", .result = "{}"}, g;
    storage_calib_t c = {.sensor_id = sensor, .pixel_col = 3, .pixel_row = 4, .r = 1, .S = S,
                         .S_err = E, .I0 = 2.0, .chi2_red = 1.0, .status = "ok",
                         .noise_model = "paper", .wavelength_um = NAN, .na = NAN,
                         .spot_radius_um = 1.342}, got;
    int64_t fit_id = 0, calib_id = 0;
    CHECK(storage_fit_put(st, &f, &c, 0, &fit_id, &calib_id, NULL) == 0 && fit_id && calib_id);
    CHECK(storage_fit_get(st, fit_id, &g, NULL) == 0 && g.scan_id == 0);
    storage_fit_free(&g);
    CHECK(raw_int("v2.db", "SELECT scan_id IS NULL FROM fits") == 1);
    CHECK(storage_calib_get(st, calib_id, &got, NULL) == 0 && got.scan_id == 0);
    CHECK(got.fit_id == fit_id && got.S_err[0] == 0.25);
    storage_calib_free(&got);
    f.dcol = 1; /* an upload has one pixel */
    CHECK(storage_fit_put(st, &f, NULL, 0, NULL, NULL, &err) == -EINVAL);
    storage_close(st);
}

/* Several ipsd on one database: a scan job belongs to the bench that queued it, a fit job to
 * anyone; a claimant's heartbeats are its lease: once it runs out another ipsd queues the job
 * again and the late claimant can neither report on it nor end it; at start-up an ipsd requeues
 * only what it left running itself. */
static void test_claimants(void)
{
    storage_t *a = open_db("claimants.db"), *b = open_db("claimants.db"),
              *f = open_db("claimants.db");
    CHECK(storage_set_claimant(a, "bench-a") == 0 && storage_set_claimant(b, "bench-b") == 0 &&
          storage_set_claimant(f, "fitter") == 0);
    CHECK(storage_set_claimant(a, "") == -EINVAL);
    int64_t scan = make_running_scan(a, make_sensor(a, "IMX-C", "1")), sj = 0, fj = 0, bj = 0;
    err_t err = {{0}};
    CHECK(storage_job_enqueue(a, STORAGE_JOB_SCAN, "{}", scan, &sj, NULL) == 0);
    CHECK(storage_job_enqueue(a, STORAGE_JOB_FIT, "{}", scan, &fj, NULL) == 0);
    CHECK(storage_job_enqueue(b, STORAGE_JOB_SCAN, "{}", scan, &bj, NULL) == 0);
    storage_job_t j;
    CHECK(storage_job_get(a, sj, &j, NULL) == 0 && j.bench && !strcmp(j.bench, "bench-a") &&
          !j.claimed_by);
    storage_job_free(&j);
    CHECK(storage_job_get(a, fj, &j, NULL) == 0 && !j.bench);
    storage_job_free(&j);
    /* b's instrument takes only b's scan job; the fit goes to whoever asks */
    CHECK(storage_job_claim(b, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == bj);
    storage_job_free(&j);
    CHECK(storage_job_claim(b, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == 0);
    CHECK(storage_job_claim(b, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == fj &&
          j.claimed_by && !strcmp(j.claimed_by, "bench-b"));
    storage_job_free(&j);
    CHECK(storage_job_claim(a, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == sj);
    storage_job_free(&j);
    /* only the claimant reports on a running job */
    CHECK(storage_job_heartbeat(a, fj, 0.5, 0, &err) == -ESTALE && strstr(err.msg, "bench-b"));
    CHECK(storage_job_heartbeat(b, fj, 0.5, 0, NULL) == 0);

    /* b goes silent for a minute: its lease (30 s here) runs out, a's does not */
    fake_now += 60000;
    CHECK(storage_job_heartbeat(a, sj, 0.5, 1, NULL) == 0 &&
          storage_job_heartbeat(b, bj, 0.1, 0, NULL) == 0);
    int requeued = -1, failed = -1;
    CHECK(storage_job_requeue_claimed(f, NULL, 30000, 5, &requeued, &failed, NULL) == 0);
    CHECK(requeued == 1 && failed == 0); /* the fit */
    CHECK(storage_job_claim(f, STORAGE_JOB_FIT, &j, NULL) == 0 && j.id == fj && j.attempts == 2);
    storage_job_free(&j);
    CHECK(storage_job_finish(b, fj, STORAGE_DONE, NULL, &err) == -ESTALE &&
          strstr(err.msg, "taken over by fitter"));
    CHECK(storage_job_heartbeat(b, fj, 0.9, 0, NULL) == -ESTALE);
    CHECK(storage_job_release(b, fj, NULL) == -ESTALE);
    CHECK(storage_job_finish(f, fj, STORAGE_DONE, NULL, NULL) == 0);
    CHECK(raw_int("claimants.db", "SELECT count(*) FROM jobs WHERE state = 'done'") == 1);

    /* b restarts: it requeues its own scan job, not a's */
    CHECK(storage_job_requeue_claimed(b, "bench-b", 0, 5, &requeued, &failed, NULL) == 0 &&
          requeued == 1);
    CHECK(storage_job_get(a, sj, &j, NULL) == 0 && j.state == STORAGE_RUNNING);
    storage_job_free(&j);
    CHECK(storage_job_get(a, bj, &j, NULL) == 0 && j.state == STORAGE_QUEUED);
    storage_job_free(&j);
    CHECK(storage_job_claim(a, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == 0); /* b's, not a's */
    CHECK(storage_job_claim(b, STORAGE_JOB_SCAN, &j, NULL) == 0 && j.id == bj);
    storage_job_free(&j);
    storage_close(a);
    storage_close(b);
    storage_close(f);
}

/* Until the count of sql reads 0: a closed or terminated backend lets its locks go after the
 * server has answered, so the test waits for that (a condition, at most 60 s), never a time. */
static int lock_gone(const char *name, const char *sql)
{
    for (int i = 0; i < 6000; i++) {
        if (raw_int(name, sql) == 0) return 1;
        nanosleep(&(struct timespec){0, 10000000L}, NULL);
    }
    return 0;
}

/* A bench name's lock: held by one connection at a time (PostgreSQL's advisory lock), confirmed
 * by its holder without taking it twice, taken again when the holder's connection was cut (the
 * handle opens a new one), free when the holder closes; SQLite has none (-ENOTSUP). */
static void test_lock_name(void)
{
    storage_t *a = open_db("lockname.db"), *b = open_db("lockname.db");
    err_t err = {{0}};
    if (!pg_uri) {
        CHECK(storage_lock_name(a, "bench x", &err) == -ENOTSUP);
        storage_close(a);
        storage_close(b);
        return;
    }
    const char *held = "SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' AND granted "
                       "AND objsubid = 2 AND classid = 1768977252 AND objid = "
                       "hashtext(current_schema() || ' bench x')::oid";
    CHECK(storage_lock_name(a, "bench x", &err) == 1); /* taken */
    CHECK(storage_lock_name(a, "bench x", &err) == 0); /* confirmed */
    CHECK(raw_int("lockname.db", held) == 1);
    CHECK(storage_lock_name(b, "bench x", &err) == -EBUSY);
    CHECK(strstr(err.msg, "bench x is held by another connection") != NULL);
    CHECK(storage_lock_name(b, "bench y", &err) == 1); /* another name is another lock */
    /* the holder's connection cut: its next look opens a new one and takes the lock again */
    CHECK(raw_exec("lockname.db", "SELECT pg_terminate_backend(pid) FROM pg_locks WHERE "
                                  "locktype = 'advisory' AND objsubid = 2 AND classid = "
                                  "1768977252 AND objid = hashtext(current_schema() || "
                                  "' bench x')::oid") == SQLITE_OK);
    CHECK(lock_gone("lockname.db", held)); /* the server ends the backend after it answered */
    CHECK(storage_lock_name(a, "bench x", &err) == 1);
    CHECK(raw_int("lockname.db", held) == 1);
    CHECK(storage_lock_name(b, "bench x", &err) == -EBUSY);
    storage_close(a);
    CHECK(lock_gone("lockname.db", held));
    CHECK(storage_lock_name(b, "bench x", &err) == 1); /* free once its holder closed */
    storage_close(b);
}

/* PostgreSQL over TLS (tests/pg_server.sh's certificate, in the directory of the URI file):
 * sslmode=verify-full against the server's own certificate connects, and the server (read by
 * another connection, pg_stat_ssl) says every connection of the handle is encrypted; against a
 * certificate the server's does not chain to, the open is refused (-EACCES), naming the
 * certificate. */
static void test_pg_tls(const char *uri_file)
{
    char dir[512], root[600], other[600], uri[1800];
    snprintf(dir, sizeof dir, "%s", uri_file);
    char *slash = strrchr(dir, '/');
    if (slash) *slash = '\0'; else snprintf(dir, sizeof dir, ".");
    snprintf(root, sizeof root, "%s/root.crt", dir);
    snprintf(other, sizeof other, "%s/other-root.crt", dir);
    if (access(root, R_OK) != 0 || access(other, R_OK) != 0) {
        printf("the test server has no TLS certificate (%s): TLS not checked\n", root);
        return;
    }
    const char *base = db_path("pgtls");
    snprintf(uri, sizeof uri, "%s&sslmode=verify-full&sslrootcert=%s&application_name=ipsd_tls",
             base, root);
    storage_t *st = NULL;
    err_t err = {{0}};
    CHECK(storage_open(uri, &st, &err) == 0 && st);
    if (st) {
        CHECK(make_sensor(st, "IMX-TLS", "0001") > 0);
        const char *by_app = "FROM pg_stat_ssl s JOIN pg_stat_activity a USING (pid) WHERE "
                             "a.application_name = 'ipsd_tls'";
        char sql[256];
        snprintf(sql, sizeof sql, "SELECT count(*) %s AND s.ssl AND s.version LIKE 'TLS%%'",
                 by_app);
        CHECK(raw_int("pgtls", sql) >= 1);
        snprintf(sql, sizeof sql, "SELECT count(*) %s AND NOT s.ssl", by_app);
        CHECK(raw_int("pgtls", sql) == 0);
        storage_close(st);
    }
    CHECK(raw_int("pgtls", "SELECT count(*) FROM sensors WHERE model = 'IMX-TLS'") == 1);
    snprintf(uri, sizeof uri, "%s&sslmode=verify-full&sslrootcert=%s", base, other);
    st = NULL;
    CHECK(storage_open(uri, &st, &err) == -EACCES && st == NULL);
    CHECK(strstr(err.msg, "certificate") != NULL);
    printf("an untrusted server certificate: %s\n", err.msg);
}

/* PostgreSQL: the version table, a reopen that changes nothing, a newer schema refused with
 * nothing written, a URI that is not one, a wrong password (not in the message), and a writer
 * that waits past the busy timeout for another instance's write transaction. */
/* A gate's listener hears the calibrations of other instances, not its own (storage_listen.c):
 * on a connection that LISTENs, a notification whose payload is the ignored token (the gate's own)
 * is taken but not counted, one with another payload (another instance's gate) is counted. A
 * channel of its own, so that the other tests' instances sharing the server do not count here. */
static void test_pg_notify_own(void)
{
    sqldb_t *db = NULL;
    err_t err = {{0}};
    CHECK(sqldb_pg_open(db_path("pgnotify"), &db, &err) == 0);
    CHECK(db && sqldb_exec(db, "LISTEN ipsd_test_notify") == SQLDB_OK);
    CHECK(raw_exec("pgnotify", "NOTIFY ipsd_test_notify, 'own-7'") == SQLITE_OK);
    CHECK(raw_exec("pgnotify", "NOTIFY ipsd_test_notify, 'other-9'") == SQLITE_OK);
    int counted = 0, ignored = 0, ig, n = 0;
    /* both committed: each wait takes what has arrived, until both are in (or 30 s pass) */
    for (int k = 0; k < 300 && counted + ignored < 2 && n >= 0; k++) {
        n = sqldb_pg_wait_notify(db, 100, "own-7", &ig);
        if (n >= 0) counted += n, ignored += ig;
    }
    CHECK(n >= 0 && counted == 1 && ignored == 1);
    sqldb_close(db);
}

static void test_pg_open(void)
{
    const char *tables = "SELECT count(*) FROM information_schema.tables WHERE table_schema = "
                         "current_schema() AND table_name IN ('sensors', 'scans', 'frames', "
                         "'jobs', 'fits', 'calibrations', 'fit_maps', 'ptc', 'frame_times')";
    storage_t *st = open_db("pgopen");
    CHECK(raw_int("pgopen", "SELECT version FROM ipsd_schema") == storage_schema_version());
    CHECK(raw_int("pgopen", "SELECT count(*) FROM ipsd_schema") == 1);
    CHECK(raw_int("pgopen", tables) == 9);
    int64_t sensor = make_sensor(st, "IMX-PG", "0001");
    storage_close(st);
    st = open_db("pgopen");
    CHECK(raw_int("pgopen", "SELECT version FROM ipsd_schema") == storage_schema_version());
    storage_sensor_t s;
    CHECK(storage_sensor_get(st, sensor, &s, NULL) == 0 && strcmp(s.model, "IMX-PG") == 0);
    storage_sensor_free(&s);
    storage_close(st);

    char sql[160];
    snprintf(sql, sizeof sql, "CREATE TABLE ipsd_schema (version integer NOT NULL); "
                              "INSERT INTO ipsd_schema VALUES (%d)", storage_schema_version() + 1);
    const char *newer = db_path("pgnewer");
    CHECK(raw_exec("pgnewer", sql) == SQLITE_OK);
    err_t err = {{0}};
    CHECK(storage_open(newer, &st, &err) == -ENOTSUP && st == NULL && strstr(err.msg, "newer"));
    CHECK(raw_int("pgnewer", "SELECT version FROM ipsd_schema") == storage_schema_version() + 1);
    CHECK(raw_int("pgnewer", tables) == 0);

    CHECK(storage_open("postgresql://127.0.0.1/ipsd?no_such_parameter=1", &st, &err) == -EINVAL &&
          st == NULL);
    CHECK(strstr(err.msg, "cannot open database") && strstr(err.msg, "no_such_parameter") &&
          !strchr(err.msg, '\n'));
    printf("bad URI: %s\n", err.msg);
    char wrong[512];
    const char *at = strstr(pg_uri, "@"), *scheme = strstr(pg_uri, "://");
    CHECK(at && scheme);
    if (at && scheme) {
        snprintf(wrong, sizeof wrong, "%.*s:NotThePassword%s", (int)(at - pg_uri), pg_uri, at);
        CHECK(storage_open(wrong, &st, &err) == -EACCES && st == NULL);
        CHECK(strstr(err.msg, "password") && !strstr(err.msg, "NotThePassword"));
        printf("wrong password: %s\n", err.msg);
    }

    /* another instance in a write transaction: a write gives up after the busy timeout, a read
     * goes on */
    st = open_db("pgopen");
    PGconn *other = pg_connect("pgopen");
    PGresult *r = PQexec(other, "BEGIN; SELECT pg_advisory_xact_lock(1768977252, " /* "ipsd" */
                                "hashtext(current_schema()))");
    CHECK(PQresultStatus(r) == PGRES_TUPLES_OK);
    PQclear(r);
    CHECK(storage_set_busy_timeout(st, 20, NULL) == 0);
    int64_t id = 0;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &id, &err) == -EBUSY);
    storage_job_list_t l;
    CHECK(storage_job_list(st, STORAGE_ANY, STORAGE_ANY, 0, 0, 0, &l, NULL) == 0 && l.total == 0);
    storage_job_list_free(&l);
    PQclear(PQexec(other, "COMMIT"));
    PQfinish(other);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_FIT, "{}", 0, &id, NULL) == 0 && id == 1);
    storage_close(st);
}

static void remove_tmpdir(void)
{
    DIR *d = opendir(tmpdir);
    struct dirent *e;
    while (d && (e = readdir(d))) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        CHECK(unlink(db_path(e->d_name)) == 0);
    }
    if (d) closedir(d);
    CHECK(rmdir(tmpdir) == 0);
}

int main(int argc, char **argv)
{
    if (argc == 3 && !strcmp(argv[1], "--pg-uri-file")) {
        /* the URI the suite's server wrote (tests/pg_server.sh), its password in PGPASSFILE */
        static char uri[512];
        FILE *f = fopen(argv[2], "r");
        if (!f || !fgets(uri, sizeof uri, f)) {
            fprintf(stderr, "no PostgreSQL server for the tests (%s): skipped\n", argv[2]);
            return 77;
        }
        fclose(f);
        uri[strcspn(uri, "\r\n")] = '\0';
        pg_uri = uri;
        test_pg_open();
        test_pg_notify_own();
        test_pg_tls(argv[2]);
        test_sensor_scan_roundtrip();
        test_frame_roundtrip();
        test_frames_unique();
        test_raster();
        test_claim_concurrent();
        test_requeue();
        test_claimants();
        test_lock_name();
        test_cancel();
        test_gate();
        test_fits();
        test_fit_store_done();
        test_fit_store_unit();
        test_calibrations();
        test_calib_generation();
        test_pagination();
        test_promote();
        test_setup_release_upload();
        CHECK_DONE();
    }
    const char *base = getenv("TMPDIR");
    snprintf(tmpdir, sizeof tmpdir, "%s/ipsd-test-storage-XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_open_migrate();
    test_refuse();
    test_sensor_scan_roundtrip();
    test_frame_roundtrip();
    test_frames_unique();
    test_point_transaction();
    test_raster();
    test_claim_concurrent();
    test_requeue();
    test_claimants();
    test_lock_name();
    test_cancel();
    test_busy();
    test_gate();
    test_fits();
    test_fit_store_done();
    test_fit_store_unit();
    test_calibrations();
    test_calib_generation();
    test_pagination();
    test_migrate_v1();
    test_promote();
    test_migrate_v2();
    test_migrate_v5();
    test_migrate_v6();
    test_migrate_v7();
    test_setup_release_upload();
    remove_tmpdir();
    CHECK_DONE();
}
