/* srv.c: the server core's life cycle and the operations the API asks for (see srv.h). The
 * workers live in srv_scanner.c and srv_fitter.c. */
#include "srv_int.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <time.h>
#include <unistd.h>

#include "base/clock.h"
#include "instrument/scan_limits.h"
#include "srv_bench.h"
#include "srv_failpoint.h"

#define EVENT_RING 4096 /* events kept for slow readers */
#define IDLE_POLL_MS 1000 /* workers also poll: jobs may be queued by another process */

/* On a shared database, one ipsd per bench name: two would both run that bench's scans. The lock
 * is the database's, held by a connection of its own for the life of the process (released by
 * the server when it dies, so a kill -9 leaves none). */
static int lock_bench_name(srv_t *srv, err_t *err)
{
    char name[128];
    snprintf(name, sizeof name, "bench %s", srv->cfg.bench_name);
    int ret = storage_open(srv->cfg.db_path, &srv->lock_st, err);
    if (ret == 0) ret = storage_lock_name(srv->lock_st, name, err);
    if (ret == 1) ret = 0; /* taken */
    if (ret == 0) atomic_store(&srv->bench_lock, SRV_BENCH_LOCK_HELD);
    if (ret == -EBUSY)
        return err_set(err, -EBUSY,
                       "bench %s is in use by another ipsd on database %s: give each ipsd its own "
                       "--bench-name",
                       srv->cfg.bench_name, srv->cfg.db_path);
    return ret;
}

/* The idle scan worker's look at the bench name's lock, about four times a lease: the advisory
 * lock ends with the connection that held it (a database server restart), and the handle's next
 * statement opens a new one, so the look takes it again, or finds that another ipsd of the same
 * name took it meanwhile: then the scan worker claims nothing (srv_worker_loop) until the other
 * lets it go. Changes are logged once each. */
static void keep_bench_lock(srv_worker_t *w)
{
    srv_t *srv = w->srv;
    if (!srv->lock_st) return;
    int64_t now_ms = clock_wall_ms();
    if (now_ms - w->bench_lock_ms < srv->cfg.lease_s * 250LL) return;
    w->bench_lock_ms = now_ms;
    if (srv_failpoint(w, "bench.lock", NULL)) return; /* test hook: held, then stopping */
    char name[128];
    snprintf(name, sizeof name, "bench %s", srv->cfg.bench_name);
    err_t err;
    int ret = storage_lock_name(srv->lock_st, name, &err);
    int now = ret == 0 || ret == 1 ? SRV_BENCH_LOCK_HELD
              : ret == -EBUSY      ? SRV_BENCH_LOCK_LOST
                                   : SRV_BENCH_LOCK_UNKNOWN;
    int before = atomic_exchange(&srv->bench_lock, now);
    if (ret == 1 && before == SRV_BENCH_LOCK_LOST)
        fprintf(stderr, "ipsd: bench %s: its lock is free again and held by this ipsd: it claims "
                        "scan jobs again\n", srv->cfg.bench_name);
    else if (ret == 1)
        fprintf(stderr, "ipsd: bench %s: its lock on the database taken again (the connection that "
                        "held it was lost)\n", srv->cfg.bench_name);
    else if (now == SRV_BENCH_LOCK_LOST && before != now)
        fprintf(stderr, "ipsd: bench %s: another ipsd of that name took its lock while this one's "
                        "connection was lost: this ipsd claims no scan jobs until the other stops\n",
                srv->cfg.bench_name);
    else if (now == SRV_BENCH_LOCK_UNKNOWN && before != now)
        fprintf(stderr, "ipsd: bench %s: its lock cannot be checked: %s\n", srv->cfg.bench_name,
                err.msg);
}

/* One ipsd per SQLite file: start-up requeues every job left running, which would take a second
 * instance's running jobs from it. An advisory lock on DB-ipsd.lock (released by the kernel when
 * the process dies, so a kill -9 leaves no stale lock) makes the second one refuse to start.
 * A PostgreSQL database is shared: each ipsd requeues only its own jobs (requeue_interrupted). */
static int lock_db(srv_t *srv, err_t *err)
{
    if (srv->shared) return lock_bench_name(srv, err);
    char path[4096];
    if (snprintf(path, sizeof path, "%s-ipsd.lock", srv->cfg.db_path) >= (int)sizeof path)
        return err_set(err, -ENAMETOOLONG, "database path too long");
    srv->lock_fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (srv->lock_fd < 0)
        return err_set(err, -errno, "cannot create the lock file %s: %s", path, strerror(errno));
    if (flock(srv->lock_fd, LOCK_EX | LOCK_NB) != 0) {
        int e = errno;
        close(srv->lock_fd);
        srv->lock_fd = -1;
        if (e == EWOULDBLOCK)
            return err_set(err, -EBUSY, "database %s is in use by another ipsd (lock %s)",
                           srv->cfg.db_path, path);
        return err_set(err, -e, "cannot lock %s: %s", path, strerror(e));
    }
    return 0;
}

/* Start-up housekeeping on one handle: every job left running was interrupted by a crash (a
 * graceful stop gives jobs back), so it runs again unless it has used up its attempts. On a
 * shared database, only the jobs this ipsd left running: the others' are theirs until their
 * lease runs out (srv_lease_sweep). */
static int requeue_interrupted(srv_t *srv, err_t *err)
{
    storage_t *st = srv_db_get(srv, err);
    if (!st) return -EIO;
    int requeued = 0, failed = 0;
    int ret = storage_job_requeue_claimed(st, srv->shared ? srv->cfg.bench_name : NULL, 0,
                                          srv->cfg.max_attempts, &requeued, &failed, err);
    srv_db_put(srv, st);
    if (ret == 0 && (requeued || failed))
        fprintf(stderr,
                "ipsd: %d interrupted job(s) queued again, %d abandoned after %d "
                "attempts\n",
                requeued, failed, srv->cfg.max_attempts);
    return ret;
}

/* The storage test hooks (docs/server.md, "Test hooks"): IPSD_STORAGE_FAULT_FILE (while that file
 * exists, writes fail with the fault it names) and IPSD_MAX_DB_PAGES (PRAGMA max_page_count on
 * every handle: SQLite itself answers SQLITE_FULL). */
static int arm_storage_hooks(srv_t *srv, err_t *err)
{
    const char *file = getenv("IPSD_STORAGE_FAULT_FILE"), *pages = getenv("IPSD_MAX_DB_PAGES");
    long long n = 0;
    if (pages && *pages) {
        char *end;
        n = strtoll(pages, &end, 10);
        if (*end || n < 1)
            return err_set(err, -EINVAL, "IPSD_MAX_DB_PAGES: '%s' is not a page count >= 1",
                           pages);
    }
    if ((!file || !*file) && n == 0) return 0;
    if (storage_gate_set_test_faults(srv->gate, file, n))
        return err_set(err, -EINVAL, "IPSD_STORAGE_FAULT_FILE: path too long");
    fprintf(stderr, "ipsd: storage test hooks armed:%s%s%s%s\n", file && *file ? " fault file " : "",
            file && *file ? file : "", n ? " max pages " : "", n ? pages : "");
    return 0;
}

int srv_open(const srv_config_t *cfg, srv_t **out, err_t *err)
{
    srv_t *srv = calloc(1, sizeof *srv);
    *out = NULL;
    if (!srv) return err_set(err, -ENOMEM, "out of memory");
    srv->cfg = *cfg;
    srv->lock_fd = -1;
    srv->shared = storage_is_postgres(cfg->db_path);
    pthread_mutex_init(&srv->mu, NULL);
    pthread_cond_init(&srv->cv, NULL);
    int ret = 0;
    if ((ret = srv_failpoints_open(getenv("IPSD_FAILPOINTS"), getenv("IPSD_FAILPOINT_DIR"),
                                   &srv->failpoints, err)) ||
        (ret = srv_bench_check(cfg->bench, cfg->stage, &srv->camera, err)) ||
        (ret = lock_db(srv, err)) || (ret = storage_gate_new(&srv->gate)) ||
        (ret = arm_storage_hooks(srv, err)) ||
        (ret = storage_gate_listen(srv->gate, cfg->db_path, err)) ||
        (ret = srv_dbpool_open(cfg->db_path, srv->shared ? cfg->bench_name : NULL, srv->gate,
                               &srv->pool, err)) ||
        (ret = requeue_interrupted(srv, err)) ||
        (ret = srv_events_open(EVENT_RING, cfg->heartbeat_s * 1000, &srv->events, err))) {
        if (ret == -ENOMEM) err_set(err, ret, "out of memory");
        srv->stopped = 1;
        srv_close(srv);
        return ret;
    }
    *out = srv;
    return 0;
}

int srv_start(srv_t *srv, err_t *err)
{
    int n = 1 + srv->cfg.workers, ret = 0;
    srv->workers = calloc((size_t)n, sizeof *srv->workers);
    if (!srv->workers) return err_set(err, -ENOMEM, "out of memory");
    srv->n_workers = n;
    for (int i = 0; i < n && ret == 0; i++) {
        srv_worker_t *w = &srv->workers[i];
        w->srv = srv;
        if (i == 0 && !strcmp(srv->cfg.bench, "none")) continue; /* no instrument: no scanner */
        if ((ret = storage_open(srv->cfg.db_path, &w->st, err))) break;
        if (srv->shared && storage_set_claimant(w->st, srv->cfg.bench_name)) {
            ret = err_set(err, -ENOMEM, "out of memory");
            break;
        }
        storage_set_gate(w->st, srv->gate);
        int rc = pthread_create(&w->thread, NULL, i == 0 ? srv_scanner_main : srv_fitter_main, w);
        if (rc) ret = err_set(err, -rc, "cannot start a worker thread: %s", strerror(rc));
        w->running = rc == 0;
    }
    return ret;
}

void srv_stop(srv_t *srv)
{
    if (!srv || srv->stopped) return;
    srv->stopped = 1;
    atomic_store(&srv->stopping, 1);
    for (int i = 0; i < srv->n_workers; i++)
        atomic_store(&srv->workers[i].stop, 1);
    srv_notify_work(srv);
    for (int i = 0; i < srv->n_workers; i++) {
        if (srv->workers[i].running) pthread_join(srv->workers[i].thread, NULL);
        srv->workers[i].running = 0;
        storage_close(srv->workers[i].st);
        srv->workers[i].st = NULL;
    }
    srv_events_shutdown(srv->events);
}

void srv_close(srv_t *srv)
{
    if (!srv) return;
    srv_stop(srv);
    free(srv->workers);
    srv_events_close(srv->events);
    srv_dbpool_close(srv->pool);
    storage_gate_free(srv->gate);
    pthread_cond_destroy(&srv->cv);
    pthread_mutex_destroy(&srv->mu);
    srv_config_free(&srv->cfg);
    srv_failpoints_close(srv->failpoints);
    if (srv->lock_fd >= 0) close(srv->lock_fd); /* releases the flock */
    storage_close(srv->lock_st);                /* and a shared database's bench lock */
    free(srv);
}

const srv_config_t *srv_config(const srv_t *srv)
{
    return &srv->cfg;
}

const cam_info_t *srv_camera(const srv_t *srv)
{
    return &srv->camera;
}
int srv_stopping(const srv_t *srv)
{
    return atomic_load(&srv->stopping);
}
srv_events_t *srv_events(srv_t *srv)
{
    return srv->events;
}
void srv_storage_health(srv_t *srv, storage_health_t *out)
{
    storage_gate_health(srv->gate, out);
}
storage_t *srv_db_get(srv_t *srv, err_t *err)
{
    return srv_dbpool_get(srv->pool, err);
}
void srv_db_put(srv_t *srv, storage_t *st)
{
    srv_dbpool_put(srv->pool, st);
}

void srv_worker_begin(srv_worker_t *w, int64_t id)
{
    /* srv_stop sets stopping, then the stop flags: clearing the flag first and reading stopping
     * after cannot lose a stop that lands in between */
    atomic_store(&w->stop, 0);
    if (atomic_load(&w->srv->stopping)) atomic_store(&w->stop, 1);
    atomic_store(&w->job, id);
}

void srv_worker_end(srv_worker_t *w)
{
    atomic_store(&w->job, 0);
}

void srv_worker_loop(srv_worker_t *w, unsigned kinds, const char *name,
                     void (*run)(srv_worker_t *w, storage_job_t *job))
{
    err_t err;
    /* a bench's instrument jobs, claimed only while this ipsd holds the bench's name */
    const unsigned bench_kinds = STORAGE_JOB_BIT(STORAGE_JOB_SCAN) | STORAGE_JOB_BIT(STORAGE_JOB_PTC);
    while (!atomic_load(&w->srv->stopping)) {
        storage_job_t job;
        unsigned now_kinds = kinds;
        if (atomic_load(&w->srv->bench_lock) == SRV_BENCH_LOCK_LOST) now_kinds &= ~bench_kinds;
        if (!now_kinds)
            job.id = 0;
        else if (storage_job_claim_kinds(w->st, now_kinds, &job, &err)) {
            fprintf(stderr, "ipsd: %s: %s\n", name, err.msg);
            srv_wait_work(w->srv, IDLE_POLL_MS);
            continue;
        }
        if (job.id == 0) {
            if (kinds & bench_kinds) keep_bench_lock(w);
            srv_lease_sweep(w);
            srv_wait_work(w->srv, IDLE_POLL_MS);
            continue;
        }
        run(w, &job);
        storage_job_free(&job);
    }
}

const char *srv_bench_lock(srv_t *srv)
{
    switch (atomic_load(&srv->bench_lock)) {
    case SRV_BENCH_LOCK_HELD: return "held";
    case SRV_BENCH_LOCK_LOST: return "lost";
    case SRV_BENCH_LOCK_UNKNOWN: return "unknown";
    default: return NULL;
    }
}

void srv_lease_sweep(srv_worker_t *w)
{
    srv_t *srv = w->srv;
    if (!srv->shared) return;
    /* one idle worker of this ipsd looks, about four times a lease */
    int64_t now = clock_wall_ms(), last = atomic_load(&srv->lease_swept_ms);
    if (now - last < srv->cfg.lease_s * 250LL ||
        !atomic_compare_exchange_strong(&srv->lease_swept_ms, &last, now))
        return;
    int requeued = 0, failed = 0;
    err_t err;
    if (storage_job_requeue_claimed(w->st, NULL, srv->cfg.lease_s * 1000LL, srv->cfg.max_attempts,
                                    &requeued, &failed, &err))
        fprintf(stderr, "ipsd: lease sweep: %s\n", err.msg);
    else if (requeued || failed)
        fprintf(stderr,
                "ipsd: %d job(s) whose ipsd stopped reporting for %d s queued again, %d "
                "abandoned after %d attempts\n",
                requeued, srv->cfg.lease_s, failed, srv->cfg.max_attempts);
    if (requeued) srv_notify_work(srv);
}

void srv_notify_work(srv_t *srv)
{
    pthread_mutex_lock(&srv->mu);
    srv->work_seq++;
    pthread_cond_broadcast(&srv->cv);
    pthread_mutex_unlock(&srv->mu);
}

void srv_wait_work(srv_t *srv, int ms)
{
    struct timespec until = clock_deadline(CLOCK_REALTIME, ms);
    pthread_mutex_lock(&srv->mu);
    unsigned long seen = srv->work_seq;
    int rc = 0;
    while (rc == 0 && seen == srv->work_seq && !atomic_load(&srv->stopping))
        rc = pthread_cond_timedwait(&srv->cv, &srv->mu, &until);
    pthread_mutex_unlock(&srv->mu);
}

/* The event of job j's state (phase NULL: its state's name). */
static srv_event_t job_event(const storage_job_t *j, const char *phase, int points_total,
                             double eta_s)
{
    srv_event_t ev = {.job_id = j->id,
                      .scan_id = j->scan_id,
                      .fit_id = j->fit_id,
                      .kind = j->kind,
                      .state = j->state,
                      .progress = j->progress,
                      .points_done = j->points_done,
                      .points_total = points_total,
                      .eta_s = eta_s};
    snprintf(ev.phase, sizeof ev.phase, "%s", phase ? phase : storage_state_name(j->state));
    if (j->error) snprintf(ev.error, sizeof ev.error, "%s", j->error);
    return ev;
}

void srv_publish_job(srv_t *srv, const storage_job_t *j, const char *phase, int points_total,
                     double eta_s)
{
    srv_event_t ev = job_event(j, phase, points_total, eta_s);
    srv_events_publish(srv->events, &ev);
}

void srv_publish_job_adaptive(srv_t *srv, const storage_job_t *j, const char *phase,
                              int points_total, double expected_err)
{
    srv_event_t ev = job_event(j, phase, points_total, NAN);
    ev.has_expected = isfinite(expected_err);
    ev.expected_err = expected_err;
    srv_events_publish(srv->events, &ev);
}

void srv_publish_job_pixel(srv_t *srv, const storage_job_t *j, const char *phase,
                           int points_total, double eta_s, int dcol, int drow, int col, int row)
{
    srv_event_t ev = job_event(j, phase, points_total, eta_s);
    ev.has_pixel = 1;
    ev.dcol = dcol;
    ev.drow = drow;
    ev.col = col;
    ev.row = row;
    srv_events_publish(srv->events, &ev);
}

/* Publishes the stored state of job id (quietly nothing when it cannot be read). */
static void publish_stored(srv_t *srv, storage_t *st, int64_t id, int points_total)
{
    storage_job_t j;
    if (storage_job_get(st, id, &j, NULL)) return;
    srv_publish_job(srv, &j, NULL, points_total, NAN);
    storage_job_free(&j);
}

/* A scan asked of an ipsd without an instrument (--bench none). */
static int no_instrument(srv_t *srv, err_t *err)
{
    return err_set(err, -ENOTSUP,
                   "this ipsd (%s) has no instrument (--bench none): it only fits; submit the "
                   "scan to the ipsd of the bench that holds the sensor",
                   srv->cfg.bench_name);
}

int srv_scan_submit(srv_t *srv, storage_t *st, const storage_scan_t *sc, const srv_scan_params_t *p,
                    int64_t *scan_id, int64_t *job_id, err_t *err)
{
    storage_sensor_t sn;
    if (srv_stopping(srv)) return err_set(err, -ESHUTDOWN, "ipsd is shutting down");
    if (!strcmp(srv->cfg.bench, "none")) return no_instrument(srv, err);
    int ret = storage_sensor_get(st, sc->sensor_id, &sn, err);
    if (ret) return ret;
    int nx;
    ret = scan_check_raster(sn.pitch_um, sc->area_px, sc->step_um, "raster.step_um", &nx, err);
    storage_sensor_free(&sn);
    if (ret) return ret;
    storage_scan_t row = *sc;
    /* an adaptive scan's count is its budget until it stops (then the points taken) */
    row.points_total = p->strategy.adaptive ? p->strategy.max_points : nx * nx;
    char *params = srv_scan_params_dump(p);
    if (!params) return err_set(err, -ENOMEM, "out of memory");
    ret = storage_scan_submit(st, &row, params, scan_id, job_id, err);
    free(params);
    if (ret) return ret;
    publish_stored(srv, st, *job_id, row.points_total);
    srv_notify_work(srv);
    return 0;
}

int srv_scan_resume(srv_t *srv, storage_t *st, int64_t scan_id, int64_t *job_id, err_t *err)
{
    if (srv_stopping(srv)) return err_set(err, -ESHUTDOWN, "ipsd is shutting down");
    if (!strcmp(srv->cfg.bench, "none")) return no_instrument(srv, err);
    storage_scan_t sc;
    int ret = storage_scan_resume(st, scan_id, job_id, err);
    if (ret) return ret;
    int total = storage_scan_get(st, scan_id, &sc, NULL) == 0 ? sc.points_total : 0;
    if (total) storage_scan_free(&sc);
    fprintf(stderr, "ipsd: scan %lld resumed (job %lld queued again)\n", (long long)scan_id,
            (long long)*job_id);
    publish_stored(srv, st, *job_id, total);
    srv_notify_work(srv);
    return 0;
}

int srv_fit_submit(srv_t *srv, storage_t *st, const srv_fit_params_t *p, int64_t *job_id,
                   err_t *err)
{
    if (srv_stopping(srv)) return err_set(err, -ESHUTDOWN, "ipsd is shutting down");
    return srv_enqueue_fit(srv, st, p, job_id, err);
}

int srv_enqueue_fit(srv_t *srv, storage_t *st, const srv_fit_params_t *p, int64_t *job_id,
                    err_t *err)
{
    char *params = srv_fit_params_dump(p);
    if (!params) return err_set(err, -ENOMEM, "out of memory");
    int ret = storage_job_enqueue(st, STORAGE_JOB_FIT, params, p->scan_id, job_id, err);
    free(params);
    if (ret) return ret;
    publish_stored(srv, st, *job_id, 0);
    srv_notify_work(srv);
    return 0;
}

int srv_job_cancel(srv_t *srv, storage_t *st, int64_t job_id, int *changed, err_t *err)
{
    int ret = storage_job_cancel(st, job_id, changed, err);
    if (ret || !*changed) return ret;
    /* the worker running it stops at its next check: a raster before its next point (whose
     * frame_put would be refused anyway), a fit before its next r */
    for (int i = 0; i < srv->n_workers; i++)
        if (atomic_load(&srv->workers[i].job) == job_id) atomic_store(&srv->workers[i].stop, 1);
    publish_stored(srv, st, job_id, 0);
    return 0;
}
