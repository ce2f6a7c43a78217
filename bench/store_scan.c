/* store_scan.c: how long storing a full paper-sized scan takes: 51 x 51 raster points, each with
 * 12 raw 9 x 9 sub-frames (uint16) and their mean (float64), stored the way ipsd's scan worker
 * does it (storage_frame_put: one transaction per point, synchronous = FULL), into a fresh
 * database. Prints figures (never pass/fail): total time, points per second, ms per point, the
 * database size, and the time to read one pixel's raster back (what a fit job reads).
 * Usage: ipsd-bench-store [DIR] (the database goes to a temporary directory inside DIR, default
 * $TMPDIR or /tmp, removed at the end), or ipsd-bench-store postgresql://... (a PostgreSQL
 * database, best a fresh schema by the URI's options=-csearch_path%3DNAME; its rows are left
 * there): the same points with the driver's round trips to the server. */
#define _GNU_SOURCE /* mkdtemp */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "base/clock.h"
#include "storage/storage.h"

#define NX 51 /* points per axis: 5 pixels of 6 um in 0.6 um steps, plus one */
#define M 9   /* sub-frame side */
#define K 12  /* frames per point */

static int64_t make_scan(storage_t *st)
{
    storage_sensor_t sn = {.model = "BENCH",
                           .serial = "1",
                           .n_cols = 256,
                           .n_rows = 256,
                           .pitch_um = 6,
                           .gain_e_per_dn = 3.153,
                           .read_noise_e = 5.67,
                           .bias_dn = 100,
                           .full_scale_dn = 16383};
    int64_t sensor = 0, scan = 0;
    err_t err = {{0}};
    storage_scan_t sc = {.poi_col = 128,
                         .poi_row = 128,
                         .wavelength_um = 0.55,
                         .na = 0.25,
                         .spot_radius_um = 1.342,
                         .area_px = 5,
                         .step_um = 0.6,
                         .sub_px = M,
                         .frames = K,
                         .exposure_us = 10000,
                         .points_total = NX * NX};
    if (storage_sensor_create(st, &sn, &sensor, &err) ||
        (sc.sensor_id = sensor, storage_scan_create(st, &sc, &scan, &err)) ||
        storage_scan_set_state(st, scan, STORAGE_RUNNING, NULL, &err)) {
        fprintf(stderr, "ipsd-bench-store: %s\n", err.msg);
        return 0;
    }
    return scan;
}

int main(int argc, char **argv)
{
    const char *base = argc > 1 ? argv[1] : getenv("TMPDIR");
    char dir[512] = "", path[600], wal[610];
    int pg = base && storage_is_postgres(base);
    if (pg) {
        snprintf(path, sizeof path, "%s", base);
    } else {
        snprintf(dir, sizeof dir, "%s/ipsd-bench-XXXXXX", base && *base ? base : "/tmp");
        if (!mkdtemp(dir)) return perror("mkdtemp"), 1;
        snprintf(path, sizeof path, "%s/bench.db", dir);
    }
    storage_t *st = NULL;
    err_t err = {{0}};
    if (storage_open(path, &st, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
    int64_t scan = make_scan(st);
    static uint16_t raw[K * M * M];
    static double mean[M * M];
    unsigned seed = 1;
    double t0 = clock_mono_s(), worst = 0;
    for (int i = 0; scan && i < NX * NX; i++) {
        for (int k = 0; k < K * M * M; k++)
            raw[k] = (uint16_t)(100 + rand_r(&seed) % 16000);
        for (int q = 0; q < M * M; q++)
            mean[q] = raw[q] + 0.5;
        storage_frame_t f = {.scan_id = scan,
                             .point_index = i,
                             .stage_x_um = 0.6 * (i % NX),
                             .stage_y_um = 0.6 * (i / NX),
                             .exposure_us = 10000,
                             .frames = K,
                             .sub_px = M,
                             .raw = raw,
                             .mean = mean};
        double t = clock_mono_s();
        if (storage_frame_put(st, &f, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
        double dt = clock_mono_s() - t;
        if (dt > worst) worst = dt;
    }
    double total = clock_mono_s() - t0;
    storage_raster_t r;
    double t1 = clock_mono_s();
    if (storage_frame_raster(st, scan, 0, 0, &r, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
    double raster_ms = (clock_mono_s() - t1) * 1e3;
    size_t n = r.n;
    storage_raster_free(&r);
    storage_close(st);
    struct stat sb = {0};
    if (!pg) stat(path, &sb);
    printf("%s: ", pg ? "PostgreSQL" : "SQLite");
    printf(
        "store a %d x %d scan (%d points, %d raw %dx%d frames each, one transaction per point):\n",
        NX, NX, NX * NX, K, M, M);
    printf("  total %.2f s, %.0f points/s, %.2f ms/point (worst %.2f ms)", total, NX * NX / total,
           total * 1e3 / (NX * NX), worst * 1e3);
    if (!pg) printf(", database %.1f MB", sb.st_size / 1e6);
    printf("\n");
    printf("  read one pixel's raster back (%zu points): %.2f ms\n", n, raster_ms);
    if (pg) return 0;
    unlink(path);
    snprintf(wal, sizeof wal, "%s-wal", path);
    unlink(wal);
    snprintf(wal, sizeof wal, "%s-shm", path);
    unlink(wal);
    rmdir(dir);
    return 0;
}
