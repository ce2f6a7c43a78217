/* parfor.h: a loop whose iterations run on a few threads, the caller's among them, for the fit
 * pipeline's sweep over r (pipeline.c): each r is a fit of its own, so `ips fit` on a machine
 * with cores to spare finishes the sweep in about the time of its longest r's share.
 * Internal to fit/ (not installed). */
#ifndef IPSD_FIT_PARFOR_H
#define IPSD_FIT_PARFOR_H

#define FIT_THREADS_MAX 64 /* most threads a loop runs on */

/* Runs body(i, thread, ctx) for every i in 0..n-1, in increasing i as threads become free, on up
 * to `threads` threads (the caller's, number 0, and threads - 1 started here; thread tells the
 * body which, so that it can keep per-thread state). Once a body returns nonzero no further i
 * starts. Returns 0 when every body returned 0, else the return of the failed body of smallest i
 * (the one a one-thread loop would have stopped at, when the bodies are deterministic).
 * A thread that cannot be started leaves its share to the others. */
int fit_parfor(int n, int threads, int (*body)(int i, int thread, void *ctx), void *ctx);

#endif
