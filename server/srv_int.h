/* srv_int.h: what the files of server/ share and the API does not see: the server struct, the
 * work queue's wake-up, the event function, and the worker thread entry points. */
#ifndef IPSD_SERVER_SRV_INT_H
#define IPSD_SERVER_SRV_INT_H

#include <pthread.h>
#include <stdatomic.h>

#include "instrument/cam.h"
#include "server/srv.h"
#include "srv_dbpool.h"

/* A worker thread and its own database handle. */
typedef struct srv_worker {
    srv_t *srv;
    storage_t *st;
    pthread_t thread;
    int running;
    atomic_llong job; /* the job it runs, 0 when idle */
    atomic_int stop;  /* stops that job at its next check (cancel or shutdown) */
    int64_t bench_lock_ms; /* the scan worker's last look at the bench name's lock (shared) */
} srv_worker_t;

typedef struct srv_failpoints srv_failpoints_t; /* test hooks, srv_failpoint.h */

struct srv {
    srv_config_t cfg; /* a copy (its token digests wiped by srv_close) */
    srv_dbpool_t *pool;
    storage_gate_t *gate; /* every handle's writes, first come first served (storage.h) */
    srv_events_t *events;
    pthread_mutex_t mu; /* guards work_seq; cv signals new work or stopping */
    pthread_cond_t cv;
    unsigned long work_seq; /* bumped by every submit */
    atomic_int stopping;
    srv_worker_t *workers; /* [0] the scan worker, then the fit workers */
    int n_workers, stopped;
    int lock_fd; /* flock on DB-ipsd.lock: one ipsd per SQLite file, -1 when not held */
    int shared;  /* the database is PostgreSQL's, shared with other ipsd (claims, leases) */
    storage_t *lock_st; /* shared: the connection holding this bench name's lock, else NULL */
    atomic_int bench_lock; /* shared: SRV_BENCH_LOCK_* as last seen (srv_lease_sweep) */
    _Atomic int64_t lease_swept_ms; /* the last look for other instances' expired leases */
    srv_failpoints_t *failpoints; /* armed test hooks (IPSD_FAILPOINTS), NULL: none */
    atomic_int backup_running;    /* a POST /api/backup is copying (srv_backup.c) */
    int64_t unrecorded_job;       /* under mu: a scan job failed whose failure the storage */
    char unrecorded_msg[256];     /* refuses to record yet (srv_scanner.c), and its error */
    cam_info_t camera;            /* the bench's camera as found at start (srv_bench_check) */
};

/* The bench name's lock on a shared database, as the last look found it: held, taken by another
 * ipsd while this one's connection was lost (its scan worker claims nothing until it holds it
 * again), or not known (the database did not answer). */
enum { SRV_BENCH_LOCK_NONE, SRV_BENCH_LOCK_HELD, SRV_BENCH_LOCK_LOST, SRV_BENCH_LOCK_UNKNOWN };

/* A worker's life: claims jobs of the kinds (a mask of STORAGE_JOB_BIT) in queue order and runs
 * each with run, waiting for new work (or polling every second, for jobs queued by another
 * process) when there is none, until the server stops. name is for log lines. */
void srv_worker_loop(srv_worker_t *w, unsigned kinds, const char *name,
                     void (*run)(srv_worker_t *w, storage_job_t *job));

/* On a shared database, now and then (about four times a lease, one idle worker of this ipsd):
 * the jobs whose claimant stopped reporting for --lease seconds are queued again, so a crashed
 * ipsd's fits go to another and its scans wait for its bench; and the bench name's lock is
 * confirmed, or taken again after a database restart cut the connection that held it. No-op on
 * an SQLite file. */
void srv_lease_sweep(srv_worker_t *w);

/* Wakes every worker waiting for work. */
void srv_notify_work(srv_t *srv);

/* Waits until new work is signalled, the server stops, or ms pass (workers also poll, so jobs
 * queued by another process are found). */
void srv_wait_work(srv_t *srv, int ms);

/* Publishes the state of job j (as stored) with the extra fields the stored row lacks. */
void srv_publish_job(srv_t *srv, const storage_job_t *j, const char *phase, int points_total,
                     double eta_s);
/* srv_publish_job of an adaptive scan's progress, with the expected rms error of the map of the
 * points so far (NaN: not planned yet in this run). */
void srv_publish_job_adaptive(srv_t *srv, const storage_job_t *j, const char *phase,
                              int points_total, double expected_err);
/* srv_publish_job with the pixel the event is about (a job of every pixel, srv_fitall.c). */
void srv_publish_job_pixel(srv_t *srv, const storage_job_t *j, const char *phase,
                           int points_total, double eta_s, int dcol, int drow, int col, int row);

/* srv_fit_submit without the shutdown check: the scan worker queues the automatic fit of a scan
 * it just finished even while stopping. */
int srv_enqueue_fit(srv_t *srv, storage_t *st, const srv_fit_params_t *p, int64_t *job_id,
                    err_t *err);

/* A worker takes job id: its stop flag is cleared (unless the server is stopping) and cancels of
 * that job reach it. srv_worker_end: idle again. */
void srv_worker_begin(srv_worker_t *w, int64_t id);
void srv_worker_end(srv_worker_t *w);

/* The scan worker's failure that cannot be written yet (job 0 / msg NULL: none any more). */
void srv_scan_unrecorded_set(srv_t *srv, int64_t job_id, const char *msg);

/* Worker threads (arg: their srv_worker_t). */
void *srv_scanner_main(void *arg);
void *srv_fitter_main(void *arg);

/* The scan worker's other job kind: one photon-transfer measurement (srv_ptc.c), run to its end
 * state. */
void srv_ptc_run_job(srv_worker_t *w, storage_job_t *job);


/* The one-shot modes of ipsd (srv_tools.c): --hash-token (reads stdin) and --backup OUT.
 * Each returns the process exit code: 0, 1 (failed), 2 (bad input). */
int srv_tool_hash_token(void);
/* --list-cameras: every backend's cameras on stdout (0, or 1 when stdout fails). */
int srv_tool_list_cameras(void);
int srv_tool_backup(const srv_config_t *cfg);
/* --db-copy FROM TO: copies database FROM into TO (storage_copy), prints what it copied; exit
 * status 0, 2 for bad input (FROM missing, the same database), 1 when the copy failed. */
int srv_tool_db_copy(const srv_config_t *cfg);

#endif
