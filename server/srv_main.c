/* srv_main.c: ipsd's main program (see srv_main.h). Signals are blocked in every thread and taken
 * by sigwait in the main thread, so no handler runs inside a worker or a library. */
#include "server/srv_main.h"

#include <errno.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "base/thread_sched.h"
#include "srv_int.h"

/* Writes the bound port to cfg->port_file (written to FILE.tmp, then renamed: a reader never
 * sees a half-written number). */
static int write_port_file(const srv_config_t *cfg, int port, err_t *err)
{
    if (!cfg->port_file[0]) return 0;
    char tmp[SRV_PATH_MAX + 8];
    snprintf(tmp, sizeof tmp, "%s.tmp", cfg->port_file);
    FILE *f = fopen(tmp, "w");
    if (!f || fprintf(f, "%d\n", port) < 0 || fclose(f) != 0 || rename(tmp, cfg->port_file)) {
        int e = errno;
        return err_set(err, -e, "--port-file %s: %s", cfg->port_file, strerror(e));
    }
    return 0;
}

/* glibc keeps what threads free in per-thread arenas and rarely gives it back: under hours of
 * mixed load RSS climbed to 211 MB and stayed there idle (malloc_trim brought it to
 * 35 MB, so no leak). ipsd caps the arenas at start and trims them every MEM_TRIM_S seconds
 * from the main thread, which only waits for signals. bench/soak.py prints RSS over a run. */
#define MEM_TRIM_S 10
#define MEM_ARENAS 4
/* With --fit-sched idle, one arena per thread instead: a thread's first malloc takes a new arena
 * while there are fewer than the cap, so no HTTP thread shares an arena (and its lock) with a
 * SCHED_IDLE fit worker, which, preempted while holding it, would get the CPU back only when
 * nothing else wants it (docs/server.md, "Threads"). The threads: main, the scan worker, the
 * fit workers, the event ticker, the connection reaper, the HTTP pool; two spare. */
#define MEM_OTHER_THREADS 6

static void mem_setup(const srv_config_t *cfg)
{
#ifdef __GLIBC__
    int arenas = MEM_ARENAS;
    if (cfg->fit_sched == THREAD_SCHED_IDLE)
        arenas = MEM_OTHER_THREADS + cfg->workers + cfg->http_threads;
    mallopt(M_ARENA_MAX, arenas);
#else
    (void)cfg;
#endif
    storage_process_setup();
}

static void mem_trim(void)
{
#ifdef __GLIBC__
    malloc_trim(0);
#endif
}

/* Waits for SIGINT / SIGTERM / SIGHUP, trimming the allocator meanwhile; returns the signal. */
static int wait_signal(const sigset_t *sigs)
{
    for (;;) {
        struct timespec every = {MEM_TRIM_S, 0};
        int sig = sigtimedwait(sigs, NULL, &every);
        if (sig > 0) return sig;
        if (errno == EAGAIN) mem_trim();
    }
}

/* Serves until SIGINT / SIGTERM; returns the exit code. */
static int serve(srv_t *srv, const srv_frontend_t *fe, const sigset_t *sigs)
{
    const srv_config_t *cfg = srv_config(srv);
    void *front = NULL;
    int port = 0, sig = 0;
    err_t err = {{0}};
    if (srv_start(srv, &err) || fe->start(srv, &front, &port, &err) ||
        write_port_file(cfg, port, &err)) {
        fprintf(stderr, "ipsd: %s\n", err.msg);
        if (front) fe->quiesce(front);
        srv_stop(srv);
        if (front) fe->stop(front);
        return 1;
    }
    fprintf(stderr,
            "ipsd: listening on http://%s%s%s:%d/ (database %s, bench %s, %d fit "
            "worker%s)\n",
            strchr(cfg->host, ':') ? "[" : "", cfg->host, strchr(cfg->host, ':') ? "]" : "", port,
            cfg->db_path, cfg->bench, cfg->workers, cfg->workers == 1 ? "" : "s");
    /* SIGHUP: logrotate renamed the log; reopen it by name and go on serving */
    while ((sig = wait_signal(sigs)) == SIGHUP)
        if (fe->reopen_logs) fe->reopen_logs(front);
    fprintf(stderr, "ipsd: %s: stopping (running scans resume at the next start)\n",
            sig == SIGINT ? "SIGINT" : "SIGTERM");
    fe->quiesce(front);
    srv_stop(srv);
    fe->stop(front);
    fprintf(stderr, "ipsd: stopped\n");
    return 0;
}

int srv_main(int argc, char **argv, const srv_frontend_t *fe)
{
    srv_config_t cfg = srv_config_default();
    err_t err = {{0}};
    int rc = srv_config_parse(argc, argv, &cfg, &err);
    if (rc) {
        srv_config_free(&cfg);
        if (rc > 0) return 0;
        fprintf(stderr, "ipsd: %s\n", err.msg);
        return 2;
    }
    if (cfg.hash_token || cfg.backup_out[0] || cfg.list_cameras || cfg.copy_from[0]) {
        /* one-shot modes, no server */
        rc = cfg.hash_token     ? srv_tool_hash_token()
             : cfg.list_cameras ? srv_tool_list_cameras()
             : cfg.copy_from[0] ? srv_tool_db_copy(&cfg)
                                : srv_tool_backup(&cfg);
        srv_config_free(&cfg);
        return rc;
    }
    /* before any thread exists: every thread inherits the mask. The default disposition first:
     * a shell starts background jobs with SIGINT ignored, and an ignored signal is discarded
     * before sigwait could take it. */
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    signal(SIGHUP, SIG_DFL);
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGTERM);
    sigaddset(&sigs, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);
    signal(SIGPIPE, SIG_IGN);
    mem_setup(&cfg);
    srv_t *srv = NULL;
    if ((rc = srv_open(&cfg, &srv, &err))) {
        fprintf(stderr, "ipsd: %s\n", err.msg);
        /* a shared database the command line got wrong (a malformed URI, refused credentials, a
         * schema newer than this ipsd) is bad input; an SQLite file keeps exit status 1 */
        int bad = storage_is_postgres(cfg.db_path) &&
                  (rc == -EINVAL || rc == -EACCES || rc == -ENOTSUP);
        srv_config_free(&cfg);
        return bad ? 2 : 1;
    }
    srv_config_free(&cfg);
    rc = serve(srv, fe, &sigs);
    srv_close(srv);
    return rc;
}
