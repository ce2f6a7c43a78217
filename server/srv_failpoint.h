/* srv_failpoint.h: test hooks of the workers ("failpoints", in the style of FreeBSD's fail(9) and
 * etcd's gofail): named points in the scan and fit workers where a test can hold a job, or make
 * it fail, so that it acts on a scan or a fit at a known point instead of racing the worker.
 * Armed only from the environment when ipsd starts (docs/server.md, "Test hooks"):
 *
 *   IPSD_FAILPOINTS="NAME=ACTION[@N];..."   e.g. "scan.point=hold@100;fit.step=hold"
 *   IPSD_FAILPOINT_DIR=DIR                  where held points show as files (optional)
 *
 * Points: scan.setup (after the scan's setup is taken or made, before its raster), scan.point
 * (after a raster point is stored and published), scan.finish (all points stored and the
 * instrument released, before the one transaction that makes the scan done, queues its
 * automatic fit and finishes its job), fit.step (after each step of a fit: each r,
 * the F-test, the Wiener baseline), fit.before_store (a fit computed, before the transaction that
 * stores it), fit.after_store (after that transaction committed, before the job's end is
 * published), fit.poll (inside a fit's long loops, where it polls its stop: each batch of
 * design-matrix rows, after each solve, each LM iteration), fit.poll.lm (the polls of fit.poll
 * inside the LM only: each iteration, Jacobian and residual; hit after fit.poll), fit.poll.nnls,
 * fit.poll.wiener, fit.poll.geometry (the same for the polls inside the non-negative solve's
 * active-set steps, the Wiener baseline's kernel, FFT and filter passes, and the geometry fit's
 * iterations, residuals and covariance columns: fit/stop.h's sites), camera.frame (the simulated camera,
 * before each frame it captures: hold makes the camera stop answering until its frame timeout,
 * error makes the capture fail; no held file), fit.pixel (a fit of every pixel a scan covers,
 * after each pixel's fit and the job's count are committed, before the next pixel), ptc.level
 * (a photon-transfer measurement, after each level of its series is measured and published),
 * ptc.before_store (its analysis done, before the transaction that stores it), ptc.after_store
 * (after that transaction committed), bench.lock (on a shared database, the idle scan worker
 * before it looks at its bench name's lock; job 0: the first look is hit 1, at start). ACTION: hold (block the worker there), error (the point fails: -EIO), crash (the
 * process kills itself with SIGKILL there: a kill -9 at a known point) or off. @N: only the N-th hit of that point since ipsd started, counted over all
 * jobs; without it, every hit. Several terms may name one point.
 *
 * A hold writes "ipsd: failpoint NAME: holding job ID at hit N" to stderr and creates
 * DIR/NAME.ID.held; it ends when the test removes that file (released: the worker goes on), or
 * when the job is cancelled or ipsd stops (the worker's stop flag: -ECANCELED). No database
 * transaction is open at any point. Not armed (no IPSD_FAILPOINTS), a point costs one branch. */
#ifndef IPSD_SERVER_SRV_FAILPOINT_H
#define IPSD_SERVER_SRV_FAILPOINT_H

#include "base/err.h"
#include "srv_int.h"

/* The armed failpoints of spec (IPSD_FAILPOINTS' syntax) with held files in dir (NULL or "":
 * none). *out is NULL when spec is NULL or empty (nothing armed). Returns 0 or -EINVAL (bad
 * spec, with err naming the term) / -ENOMEM. */
int srv_failpoints_open(const char *spec, const char *dir, srv_failpoints_t **out, err_t *err);

/* Frees the failpoints (accepts NULL). */
void srv_failpoints_close(srv_failpoints_t *fp);

/* The simulated camera's fault switch (sim_config_t.frame_fault; ctx: the srv_t): a hit of
 * camera.frame, answered SIM_FRAME_OK, SIM_FRAME_HANG (hold) or SIM_FRAME_FAIL (error). */
int srv_failpoint_frame(void *ctx, unsigned long long frame);

/* The slow path of srv_failpoint. */
int srv_failpoint_eval(srv_worker_t *w, const char *name, err_t *err);

/* A hit of point name by worker w (running a job). Returns 0 (go on: not armed, not this hit,
 * or released), -ECANCELED (a hold ended by the stop flag) or -EIO with err (an error action). */
static inline int srv_failpoint(srv_worker_t *w, const char *name, err_t *err)
{
    return w->srv->failpoints ? srv_failpoint_eval(w, name, err) : 0;
}

#endif
