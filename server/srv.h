/* srv.h: the ipsd server core: the database, the job queue and its workers (one scan worker that
 * owns the instrument, a pool of fit workers), the event hub, and the operations the HTTP API
 * asks of them. The API (api/) calls in here; nothing here knows about HTTP.
 *
 * Life cycle: srv_open (database and migrations, requeue of the jobs a crashed run left running,
 * bench check, event hub) -> srv_start (worker threads) -> ... -> srv_stop (graceful: writes are
 * refused, the scan worker stores the point in flight and gives its job back to the queue so the
 * scan resumes at the next start, fit workers finish their fit, event streams end) -> srv_close.
 *
 * Threads: every worker has its own storage_t; request handlers borrow one from the pool
 * (srv_db_get / srv_db_put). All functions here are thread-safe. */
#ifndef IPSD_SERVER_SRV_H
#define IPSD_SERVER_SRV_H

#include <stdint.h>

#include "base/err.h"
#include "instrument/cam.h"
#include "server/srv_config.h"
#include "server/srv_events.h"
#include "server/srv_params.h"
#include "storage/storage.h"

typedef struct srv srv_t;

/* Opens the server on a copy of cfg. *out is the caller's
 * (srv_close). Returns 0 or a negative errno with err: the database cannot be opened or migrated,
 * or the bench cannot run (-ENODEV: no camera). */
int srv_open(const srv_config_t *cfg, srv_t **out, err_t *err);

/* Starts the scan worker and the fit workers. */
int srv_start(srv_t *srv, err_t *err);

/* Graceful stop (see above); blocks until the workers have stopped. Idempotent. */
void srv_stop(srv_t *srv);

/* Stops (if not yet) and frees everything. Accepts NULL. */
void srv_close(srv_t *srv);

const srv_config_t *srv_config(const srv_t *srv);
/* The bench's camera as ipsd found it at start (backend "sim" for the simulated bench). */
const cam_info_t *srv_camera(const srv_t *srv);
/* On a shared database, this ipsd's bench-name lock as the last look found it: "held", "lost"
 * (another ipsd of the name took it while this one's connection was lost) or "unknown" (the
 * database did not answer); NULL on an SQLite file. */
const char *srv_bench_lock(srv_t *srv);
/* Non-zero once srv_stop has begun: the API answers writes with 503. */
int srv_stopping(const srv_t *srv);
srv_events_t *srv_events(srv_t *srv);

/* The storage's health (storage.h: the last storage fault seen by any handle, cleared by a
 * write that commits). */
void srv_storage_health(srv_t *srv, storage_health_t *out);

/* A scan job whose failure the storage refuses to record yet (the scan worker retries it), 0
 * when none; msg (size bytes, may be NULL) gets its error. */
int64_t srv_scan_unrecorded(srv_t *srv, char *msg, size_t size);

/* A database handle for the calling thread's request, or NULL with err. Give it back. */
storage_t *srv_db_get(srv_t *srv, err_t *err);
void srv_db_put(srv_t *srv, storage_t *st);

/* Queues a scan: the scan row (points_total is computed here from the sensor's pitch; an adaptive
 * scan's is its max_points until it stops) and its
 * scan job in one transaction (storage_scan_submit), then wakes the scan worker and publishes
 * the queued job. -EINVAL (e.g. the raster rules of instrument/scan_limits.h: step not dividing
 * the area), -ENOENT (sensor), -ESHUTDOWN when stopping. */
int srv_scan_submit(srv_t *srv, storage_t *st, const storage_scan_t *sc, const srv_scan_params_t *p,
                    int64_t *scan_id, int64_t *job_id, err_t *err);

/* Resumes a failed scan (storage_scan_resume: its stored points kept, its job queued again) and
 * wakes the scan worker, which continues after the last stored point. -ENOENT, -ESTALE (not
 * failed), -ESHUTDOWN when stopping. */
int srv_scan_resume(srv_t *srv, storage_t *st, int64_t scan_id, int64_t *job_id, err_t *err);

/* Queues a fit job (linked to p->scan_id when it has one) and wakes the fit workers. */
int srv_fit_submit(srv_t *srv, storage_t *st, const srv_fit_params_t *p, int64_t *job_id,
                   err_t *err);

/* Cancels a queued or running job (a running scan stops after the point in flight; its scan is
 * cancelled with it). *changed = 0 when the job had already ended. -ENOENT unknown job. */
int srv_job_cancel(srv_t *srv, storage_t *st, int64_t job_id, int *changed, err_t *err);

/* An online backup of the database into --backup-dir (storage_backup, on st: the caller's
 * handle, not in a transaction): a new file ipsd-backup-YYYYMMDDTHHMMSSZ.db (-N before .db when
 * that name is taken), its base name into name (n bytes), what was written into info. Writers
 * go on meanwhile; the copy is the database as it was when the backup began. One backup at a
 * time: -EBUSY while another runs; -ENOTSUP without --backup-dir; -ESHUTDOWN when stopping
 * (a backup in progress stops too); -ENOSPC, -EIO. */
int srv_backup(srv_t *srv, storage_t *st, char *name, size_t n, storage_backup_info_t *info,
               err_t *err);

#endif
