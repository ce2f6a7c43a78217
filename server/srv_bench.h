/* srv_bench.h: the instrument a scan runs on: a camera (--bench: the simulated bench of
 * instrument/sim.h configured as the scan's sensor, optics, scene and seed, or a libcamera
 * camera) with a motion stage (--stage: the simulated stage, or a real controller by its stage
 * string, instrument/stage.h). Any camera works with any stage:
 *   sim camera + sim stage: the simulated bench as it is;
 *   sim camera + real stage: the real stage moves and reports; the simulated bench's own stage
 *     follows the position the real one reports after each move (stage_open_follow), so the
 *     simulated optics put the spot where the real stage says it is;
 *   libcamera or aravis + sim stage: real frames, commanded positions;
 *   libcamera or aravis + real stage: both real.
 * The bench string is "sim", or a camera backend ("libcamera", "aravis") with ":DEVICE-ID" when
 * it names one of its cameras (else the first one the backend finds). */
#ifndef IPSD_SERVER_SRV_BENCH_H
#define IPSD_SERVER_SRV_BENCH_H

#include "instrument/cam.h"
#include "base/err.h"
#include "instrument/sim.h"
#include "server/srv_params.h"
#include "instrument/stage.h"
#include "storage/storage.h"

typedef struct srv_bench {
    sim_t *sim;        /* the simulated bench (NULL for a real camera); owns cam and its stage */
    cam_t *cam;        /* borrowed from sim, or owned (libcamera, aravis) */
    stage_t *stage;    /* borrowed from sim (sim stage), or owned */
    stage_pos_t start; /* where the scan procedure starts: the POI's centre, focus guess */
} srv_bench_t;

/* Checks at start-up that the bench can run: for a real camera, that its backend is built in and
 * finds the camera (the first one, or the one the bench string names), which *camera then
 * describes (the sim bench: backend "sim"; an aravis camera is opened and closed again, so that
 * one without what a scan needs is refused naming the feature, and its size is known); and that the stage (a stage string) answers: a real
 * one is opened (connected, servo on, referenced if needed) and closed again. Returns 0,
 * -ENOTSUP, -ENODEV or the stage's error with a clear message. */
int srv_bench_check(const char *bench, const char *stage, cam_info_t *camera, err_t *err);

/* Splits a bench string into its backend (kind, of size kind_size) and the camera id after ':'
 * (a pointer into bench; NULL when none is named). */
const char *srv_bench_split(const char *bench, char *kind, size_t kind_size);

/* Opens the bench (bench string, stage string stage) for scan sc of sensor sn with the job's
 * parameters. *b is released with
 * srv_bench_close (also after an error). frame_fault (NULL: none) is the simulated camera's
 * fault switch (sim_config_t), with ctx. The camera waits at most timeout_s for a frame
 * (cam_set_timeout; 0: the camera's default). */
int srv_bench_open(const char *bench, const char *stage, const storage_sensor_t *sn,
                   const storage_scan_t *sc, const srv_scan_params_t *p,
                   int (*frame_fault)(void *, unsigned long long), void *ctx, double timeout_s,
                   srv_bench_t *b, err_t *err);

void srv_bench_close(srv_bench_t *b);

#endif
