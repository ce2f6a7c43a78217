/* srv_bench.h: the instrument a scan runs on: the simulated bench (instrument/sim.h) configured as
 * the scan's sensor, optics, scene and seed, or a libcamera camera. ipsd has no driver for a real
 * motion stage yet, so a libcamera bench moves a simulated stage (stage.h): the frames are real,
 * the positions are the commanded ones. */
#ifndef IPSD_SERVER_SRV_BENCH_H
#define IPSD_SERVER_SRV_BENCH_H

#include "instrument/cam.h"
#include "base/err.h"
#include "instrument/sim.h"
#include "server/srv_params.h"
#include "instrument/stage.h"
#include "storage/storage.h"

typedef struct srv_bench {
    sim_t *sim; /* the simulated bench (NULL for libcamera); owns cam and stage */
    cam_t *cam; /* borrowed from sim, or owned (libcamera) */
    stage_t *stage;
    stage_pos_t start; /* where the scan procedure starts: the POI's centre, focus guess */
} srv_bench_t;

/* Checks at start-up that the bench kind ("sim" or "libcamera") can run: for libcamera, that the
 * backend is built in and finds a camera. Returns 0, -ENOTSUP or -ENODEV with a clear message. */
int srv_bench_check(const char *kind, err_t *err);

/* Opens the bench for scan sc of sensor sn with the job's parameters. *b is released with
 * srv_bench_close (also after an error). frame_fault (NULL: none) is the simulated camera's
 * fault switch (sim_config_t), with ctx. The camera waits at most timeout_s for a frame
 * (cam_set_timeout; 0: the camera's default). */
int srv_bench_open(const char *kind, const storage_sensor_t *sn, const storage_scan_t *sc,
                   const srv_scan_params_t *p, int (*frame_fault)(void *, unsigned long long),
                   void *ctx, double timeout_s, srv_bench_t *b, err_t *err);

void srv_bench_close(srv_bench_t *b);

#endif
