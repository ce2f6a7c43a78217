/* srv_bench.h: the instrument a scan runs on: a camera (--bench: the simulated bench of
 * instrument/sim.h configured as the scan's sensor, optics, scene and seed, or a libcamera
 * camera) with a motion stage (--stage: the simulated stage, or a real controller by its stage
 * string, instrument/stage.h). Any camera works with any stage:
 *   sim camera + sim stage: the simulated bench as it is;
 *   sim camera + real stage: the real stage moves and reports; the simulated bench's own stage
 *     follows the position the real one reports after each move (stage_open_follow), so the
 *     simulated optics put the spot where the real stage says it is;
 *   libcamera + sim stage: real frames, commanded positions;
 *   libcamera + real stage: both real. */
#ifndef IPSD_SERVER_SRV_BENCH_H
#define IPSD_SERVER_SRV_BENCH_H

#include "instrument/cam.h"
#include "base/err.h"
#include "instrument/sim.h"
#include "server/srv_params.h"
#include "instrument/stage.h"
#include "storage/storage.h"

typedef struct srv_bench {
    sim_t *sim;        /* the simulated bench (NULL for libcamera); owns cam and its own stage */
    cam_t *cam;        /* borrowed from sim, or owned (libcamera) */
    stage_t *stage;    /* borrowed from sim (sim stage), or owned */
    stage_pos_t start; /* where the scan procedure starts: the POI's centre, focus guess */
} srv_bench_t;

/* Checks at start-up that the bench kind ("sim" or "libcamera") can run: for libcamera, that the
 * backend is built in and finds a camera; and that the stage (a stage string) answers: a real
 * one is opened (connected, servo on, referenced if needed) and closed again. Returns 0,
 * -ENOTSUP, -ENODEV or the stage's error with a clear message. */
int srv_bench_check(const char *kind, const char *stage, err_t *err);

/* Opens the bench (camera kind, stage string stage) for scan sc of sensor sn with the job's
 * parameters. *b is released with
 * srv_bench_close (also after an error). frame_fault (NULL: none) is the simulated camera's
 * fault switch (sim_config_t), with ctx. The camera waits at most timeout_s for a frame
 * (cam_set_timeout; 0: the camera's default). */
int srv_bench_open(const char *kind, const char *stage, const storage_sensor_t *sn,
                   const storage_scan_t *sc, const srv_scan_params_t *p,
                   int (*frame_fault)(void *, unsigned long long), void *ctx, double timeout_s,
                   srv_bench_t *b, err_t *err);

void srv_bench_close(srv_bench_t *b);

#endif
