/* test_storage_ptc.c: the ptc table (storage_ptc_*): photon-transfer measurements stored with
 * history (newest first, every one kept), the sensor's foreign key and the checks on the gain,
 * read noise and JSON, in a real SQLite file in a temporary directory. */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "storage/storage.h"

static int64_t now_ms = 1700000000000;
static int64_t clock_fn(void *ctx)
{
    return *(int64_t *)ctx;
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

    storage_close(st);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
    CHECK_DONE();
}
