/* test_storage_ptc.c: the ptc table (storage_ptc_*): photon-transfer measurements stored with
 * history (newest first, every one kept), the sensor's foreign key and the checks on the gain,
 * read noise and JSON, in a real SQLite file in a temporary directory; the ptc job (schema 5):
 * its result stored with the job's end in one transaction, claimed with the scan jobs in queue
 * order, and the migration of a schema-4 file (the jobs table rebuilt) keeping every row. */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <sqlite3.h>

#include "check.h"
#include "storage/storage.h"
#include "storage_int.h" /* stg_migrations: to make a schema-4 database by hand */

static int64_t now_ms = 1700000000000;
static int64_t clock_fn(void *ctx)
{
    return *(int64_t *)ctx;
}

static int raw_exec(const char *path, const char *sql)
{
    sqlite3 *db = NULL;
    int rc = sqlite3_open(path, &db);
    if (rc == SQLITE_OK) rc = sqlite3_exec(db, sql, NULL, NULL, NULL);
    sqlite3_close(db);
    return rc;
}

/* A ptc job: claimed with the scan jobs in the order queued; its result and its end stored
 * together; a cancelled job stores nothing. */
static void test_job(storage_t *st, int64_t sensor)
{
    int64_t scan_job, ptc_job, id = 0;
    storage_job_t j;
    err_t err;
    const unsigned instrument =
        STORAGE_JOB_BIT(STORAGE_JOB_SCAN) | STORAGE_JOB_BIT(STORAGE_JOB_PTC);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_PTC, "{\"sensor_id\": 1}", 0, &ptc_job, &err) == 0);
    CHECK(storage_job_enqueue(st, STORAGE_JOB_SCAN, "{}", 0, &scan_job, &err) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_FIT, &j, &err) == 0 && j.id == 0); /* not a fit */
    CHECK(storage_job_claim_kinds(st, instrument, &j, &err) == 0 && j.id == ptc_job &&
          j.kind == STORAGE_JOB_PTC && j.state == STORAGE_RUNNING);
    storage_job_free(&j);
    CHECK(storage_job_claim_kinds(st, instrument, &j, &err) == 0 && j.id == scan_job);
    storage_job_free(&j);
    CHECK(storage_job_claim_kinds(st, 0, &j, &err) == -EINVAL);
    CHECK(storage_job_claim_kinds(st, 1u << 7, &j, &err) == -EINVAL);

    storage_ptc_t p = {.sensor_id = sensor,
                       .gain_e_per_dn = 2.5,
                       .read_noise_e = 3,
                       .dark_dn = 100,
                       .saturation_dn = NAN,
                       .linearity_error_pct = NAN,
                       .result = "{\"K\": 0.4}",
                       .job_id = ptc_job};
    CHECK(storage_ptc_store_done(st, &p, &id, &err) == 0 && id > 0);
    CHECK(storage_job_get(st, ptc_job, &j, &err) == 0 && j.state == STORAGE_DONE &&
          j.progress == 1);
    storage_job_free(&j);
    storage_ptc_t got;
    CHECK(storage_ptc_get(st, id, &got, &err) == 0 && got.job_id == ptc_job &&
          got.gain_e_per_dn == 2.5 && got.read_noise_e == 3 && isnan(got.saturation_dn));
    storage_ptc_free(&got);
    CHECK(storage_ptc_get(st, id + 100, &got, &err) == -ENOENT);
    /* done already: a second store is refused and stores nothing */
    int64_t id2 = 0;
    CHECK(storage_ptc_store_done(st, &p, &id2, &err) == -ESTALE && id2 == 0);
    /* cancelled while running: nothing stored */
    int64_t cj, changed_id = 0;
    int changed = 0;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_PTC, "{}", 0, &cj, &err) == 0);
    CHECK(storage_job_claim(st, STORAGE_JOB_PTC, &j, &err) == 0 && j.id == cj);
    storage_job_free(&j);
    CHECK(storage_job_cancel(st, cj, &changed, &err) == 0 && changed == 1);
    p.job_id = cj;
    CHECK(storage_ptc_store_done(st, &p, &changed_id, &err) == -ECANCELED && changed_id == 0);
    storage_ptc_list_t l;
    CHECK(storage_ptc_history(st, sensor, 0, &l, &err) == 0 && l.n == 3);
    storage_ptc_list_free(&l);
}

/* A schema-4 file (migrations 1 to 4 run by hand) with a scan job, a fit job and a measurement
 * linked to a job migrates to schema 5 keeping every row and id; the old CHECK refused a ptc job,
 * the new one takes it. */
static void test_migrate_v4(const char *dir)
{
    char path[256];
    snprintf(path, sizeof path, "%s/v4.db", dir);
    for (int i = 0; i < 4; i++)
        CHECK(raw_exec(path, stg_migrations[i]) == SQLITE_OK);
    CHECK(raw_exec(path,
                   "INSERT INTO sensors (id, model, serial, n_cols, n_rows, pitch_um, "
                   "gain_e_per_dn, read_noise_e, bias_dn, full_scale_dn, created_ms) VALUES "
                   "(1, 'm', 's', 8, 8, 6, 3.153, 5.67, 100, 16383, 1);"
                   "INSERT INTO jobs (id, kind, params, state, progress, points_done, error, "
                   "attempts, created_ms, finished_ms) VALUES "
                   "(7, 'scan', '{\"seed\": 3}', 'failed', 0.5, 12, 'disk full', 2, 10, 20),"
                   "(9, 'fit', '{\"r_max\": 4}', 'queued', 0, 0, NULL, 0, 30, NULL);"
                   "INSERT INTO ptc (id, sensor_id, gain_e_per_dn, read_noise_e, result, job_id, "
                   "created_ms) VALUES (4, 1, 3.2, 5.5, '{}', 7, 40);") == SQLITE_OK);
    CHECK(raw_exec(path, "INSERT INTO jobs (kind, params, created_ms) VALUES ('ptc', '{}', 1)") ==
          SQLITE_CONSTRAINT); /* schema 4 has no ptc jobs */
    storage_t *st = NULL;
    err_t err;
    CHECK(storage_open(path, &st, &err) == 0);
    if (!st) return;
    storage_job_t j;
    CHECK(storage_job_get(st, 7, &j, &err) == 0 && j.kind == STORAGE_JOB_SCAN &&
          j.state == STORAGE_FAILED && j.progress == 0.5 && j.points_done == 12 &&
          j.attempts == 2 && j.created_ms == 10 && j.finished_ms == 20 &&
          strcmp(j.params, "{\"seed\": 3}") == 0 && j.error && strcmp(j.error, "disk full") == 0);
    storage_job_free(&j);
    CHECK(storage_job_get(st, 9, &j, &err) == 0 && j.kind == STORAGE_JOB_FIT &&
          j.state == STORAGE_QUEUED && strcmp(j.params, "{\"r_max\": 4}") == 0);
    storage_job_free(&j);
    storage_ptc_t p;
    CHECK(storage_ptc_get(st, 4, &p, &err) == 0 && p.job_id == 7 && p.gain_e_per_dn == 3.2);
    storage_ptc_free(&p);
    int64_t id = 0;
    CHECK(storage_job_enqueue(st, STORAGE_JOB_PTC, "{}", 0, &id, &err) == 0 && id == 10);
    storage_close(st);
}

int main(void)
{
    char dir[] = "/tmp/ipsd-ptc-XXXXXX", path[256];
    if (!mkdtemp(dir)) return 1;
    snprintf(path, sizeof path, "%s/ptc.db", dir);
    storage_t *st = NULL;
    err_t err;
    CHECK(storage_open(path, &st, &err) == 0);
    if (!st) return 1;
    storage_set_clock(st, clock_fn, &now_ms);
    storage_sensor_t sn = {.model = "IMX-sim",
                           .serial = "ptc-1",
                           .n_cols = 256,
                           .n_rows = 256,
                           .pitch_um = 6,
                           .gain_e_per_dn = 3.153,
                           .read_noise_e = 5.67,
                           .bias_dn = 100,
                           .full_scale_dn = 16383};
    int64_t sensor = 0, id1 = 0, id2 = 0, id;
    CHECK(storage_sensor_create(st, &sn, &sensor, &err) == 0);

    storage_ptc_list_t l;
    CHECK(storage_ptc_history(st, sensor, 0, &l, &err) == 0 && l.n == 0); /* none yet */

    storage_ptc_t p = {.sensor_id = sensor,
                       .gain_e_per_dn = 3.1563,
                       .read_noise_e = 5.6803,
                       .dark_dn = 100.0001,
                       .saturation_dn = 15774,
                       .linearity_error_pct = 0.007,
                       .result = "{\"K\": 0.3168}"};
    CHECK(storage_ptc_put(st, &p, &id1, &err) == 0 && id1 > 0);
    now_ms += 1000;
    p.gain_e_per_dn = 3.15, p.read_noise_e = 5.7, p.saturation_dn = NAN;
    CHECK(storage_ptc_put(st, &p, &id2, &err) == 0 && id2 > id1);

    CHECK(storage_ptc_history(st, sensor, 0, &l, &err) == 0 && l.n == 2);
    if (l.n == 2) {
        CHECK(l.items[0].id == id2 && l.items[1].id == id1); /* newest first */
        CHECK(l.items[0].gain_e_per_dn == 3.15 && l.items[0].read_noise_e == 5.7);
        CHECK(isnan(l.items[0].saturation_dn)); /* NaN is stored as NULL and read back */
        CHECK(l.items[1].gain_e_per_dn == 3.1563 && l.items[1].read_noise_e == 5.6803);
        CHECK(l.items[1].dark_dn == 100.0001 && l.items[1].saturation_dn == 15774);
        CHECK(l.items[1].created_ms == 1700000000000 && l.items[0].created_ms == 1700000001000);
        CHECK(strcmp(l.items[1].result, "{\"K\": 0.3168}") == 0);
        CHECK(l.items[0].job_id == 0 && l.items[0].sensor_id == sensor);
    }
    storage_ptc_list_free(&l);
    CHECK(storage_ptc_history(st, sensor, 1, &l, &err) == 0 && l.n == 1 && l.items[0].id == id2);
    storage_ptc_list_free(&l);
    CHECK(storage_ptc_history(st, sensor + 1, 0, &l, &err) == 0 && l.n == 0);

    /* refusals */
    p.sensor_id = sensor + 1;
    CHECK(storage_ptc_put(st, &p, &id, &err) == -ENOENT);
    p.sensor_id = sensor, p.result = "{not json";
    CHECK(storage_ptc_put(st, &p, &id, &err) == -EINVAL);
    p.result = "{}", p.gain_e_per_dn = 0;
    CHECK(storage_ptc_put(st, &p, &id, &err) == -EINVAL);
    p.gain_e_per_dn = 3, p.read_noise_e = -1;
    CHECK(storage_ptc_put(st, &p, &id, &err) == -EINVAL);
    p.read_noise_e = 5, p.job_id = 999;
    CHECK(storage_ptc_put(st, &p, &id, &err) == -ENOENT);                 /* no such job */
    CHECK(storage_ptc_history(st, sensor, 0, &l, &err) == 0 && l.n == 2); /* nothing added */
    storage_ptc_list_free(&l);

    test_job(st, sensor);
    storage_close(st);
    test_migrate_v4(dir);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
    CHECK_DONE();
}
