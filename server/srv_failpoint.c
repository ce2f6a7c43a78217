/* srv_failpoint.c: the workers' test hooks (see srv_failpoint.h): the IPSD_FAILPOINTS parser, hit
 * counting, the hold and the crash. A hold polls (every HOLD_POLL_MS) for its release file and
 * the worker's stop flag: the flag is a plain atomic that a cancel or the shutdown sets without
 * a wake-up, and a hold is test-only, so a short poll is simpler than a second signalling path.
 * A crash raises SIGKILL: what kill -9 does, at a point a test names instead of a random one. */
#include "srv_failpoint.h"

#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "base/parse.h"
#include "instrument/sim.h"

#define MAX_TERMS 16
#define HOLD_POLL_MS 2

enum fp_action { FP_OFF, FP_HOLD, FP_ERROR, FP_CRASH }; /* by precedence: a crash wins */

/* One NAME=ACTION[@N] term and the hits of its point so far. */
struct fp_term {
    char name[32];
    enum fp_action action;
    long long at; /* the hit it fires on, 0: every hit */
    long long hits;
};

struct srv_failpoints {
    pthread_mutex_t mu; /* guards the hit counters */
    struct fp_term terms[MAX_TERMS];
    int n;
    char dir[PATH_MAX / 2]; /* "" : no held files */
};

/* The points the workers have (a misspelt name must not arm nothing silently). */
static const char *const POINTS[] = {
    "scan.setup",       "scan.point",      "scan.finish", "fit.step",     "fit.before_store",
    "fit.after_store",  "fit.poll",        "fit.poll.lm", "fit.poll.nnls", "fit.poll.wiener",
    "fit.poll.geometry", "camera.frame",   "fit.pixel",   "ptc.level",    "ptc.before_store",
    "ptc.after_store",  "bench.lock"};

static int parse_term(char *text, struct fp_term *t, err_t *err)
{
    char *eq = strchr(text, '=');
    if (!eq) return err_set(err, -EINVAL, "IPSD_FAILPOINTS: '%s' is not NAME=ACTION[@N]", text);
    *eq = '\0';
    char *action = eq + 1, *at = strchr(action, '@');
    if (at) *at++ = '\0';
    int known = 0;
    for (size_t i = 0; i < sizeof POINTS / sizeof *POINTS; i++) known |= !strcmp(text, POINTS[i]);
    if (!known)
        return err_set(err, -EINVAL,
                       "IPSD_FAILPOINTS: unknown point '%s' (scan.setup, scan.point, fit.step, "
                       "fit.before_store, fit.after_store, fit.poll, fit.poll.lm, "
                       "fit.poll.nnls, fit.poll.wiener, fit.poll.geometry, "
                       "camera.frame, fit.pixel, ptc.level, ptc.before_store, "
                       "ptc.after_store)",
                       text);
    snprintf(t->name, sizeof t->name, "%s", text);
    if (!strcmp(action, "hold")) t->action = FP_HOLD;
    else if (!strcmp(action, "error")) t->action = FP_ERROR;
    else if (!strcmp(action, "crash")) t->action = FP_CRASH;
    else if (!strcmp(action, "off")) t->action = FP_OFF;
    else
        return err_set(err, -EINVAL,
                       "IPSD_FAILPOINTS: %s: unknown action '%s' (hold, error, crash, off)", text,
                       action);
    if (at && (parse_ll(at, &t->at) || t->at < 1))
        return err_set(err, -EINVAL, "IPSD_FAILPOINTS: %s: '@%s' is not a hit number >= 1", text,
                       at);
    return 0;
}

int srv_failpoints_open(const char *spec, const char *dir, srv_failpoints_t **out, err_t *err)
{
    *out = NULL;
    if (!spec || !*spec) return 0;
    srv_failpoints_t *fp = calloc(1, sizeof *fp);
    char *copy = strdup(spec);
    if (!fp || !copy) {
        free(fp);
        free(copy);
        return err_set(err, -ENOMEM, "out of memory");
    }
    int ret = 0;
    if (dir && snprintf(fp->dir, sizeof fp->dir, "%s", dir) >= (int)sizeof fp->dir)
        ret = err_set(err, -EINVAL, "IPSD_FAILPOINT_DIR: path too long");
    char *save = NULL;
    for (char *t = strtok_r(copy, ";", &save); t && ret == 0; t = strtok_r(NULL, ";", &save)) {
        if (fp->n == MAX_TERMS)
            ret = err_set(err, -EINVAL, "IPSD_FAILPOINTS: more than %d terms", MAX_TERMS);
        else
            ret = parse_term(t, &fp->terms[fp->n++], err);
    }
    free(copy);
    if (ret) {
        free(fp);
        return ret;
    }
    pthread_mutex_init(&fp->mu, NULL);
    fprintf(stderr, "ipsd: test hooks armed: IPSD_FAILPOINTS=%s\n", spec);
    *out = fp;
    return 0;
}

void srv_failpoints_close(srv_failpoints_t *fp)
{
    if (!fp) return;
    pthread_mutex_destroy(&fp->mu);
    free(fp);
}

/* The held file's path for job at point name ("" when there is no directory). */
static void held_file_path(const srv_failpoints_t *fp, const char *name, long long job,
                           char *path, size_t size)
{
    path[0] = '\0';
    if (fp->dir[0]) snprintf(path, size, "%s/%s.%lld.held", fp->dir, name, job);
}

/* Creates the held file at path (written under a temporary name, then renamed: a reader never
 * sees it half-written). Returns 0 or -errno; path becomes "" when it cannot be created. */
static int make_held_file(const char *name, long long job, long long hit, char *path)
{
    if (!path[0]) return 0;
    char tmp[PATH_MAX];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    int written = f && fprintf(f, "job %lld hit %lld\n", job, hit) >= 0;
    if (f && fclose(f) != 0) written = 0;
    if (!written || rename(tmp, path) != 0) {
        int e = errno;
        fprintf(stderr, "ipsd: failpoint %s: cannot create %s: %s\n", name, path, strerror(e));
        path[0] = '\0';
        return -e;
    }
    return 0;
}

/* Blocks worker w until the held file is removed (0) or its stop flag is set (-ECANCELED). */
static int hold(srv_failpoints_t *fp, srv_worker_t *w, const char *name, long long hit)
{
    long long job = atomic_load(&w->job);
    char path[PATH_MAX];
    held_file_path(fp, name, job, path, sizeof path);
    /* the line first: a test that sees the held file finds it in the log (stderr is unbuffered) */
    fprintf(stderr, "ipsd: failpoint %s: holding job %lld at hit %lld%s%s\n", name, job, hit,
            path[0] ? " until removed: " : "", path);
    make_held_file(name, job, hit, path);
    struct timespec pause = {0, HOLD_POLL_MS * 1000000L};
    int ret;
    for (;;) {
        if (atomic_load(&w->stop) || atomic_load(&w->srv->stopping)) {
            ret = -ECANCELED;
            break;
        }
        if (path[0] && access(path, F_OK) != 0 && errno == ENOENT) {
            ret = 0;
            break;
        }
        nanosleep(&pause, NULL);
    }
    if (ret && path[0]) unlink(path);
    fprintf(stderr, "ipsd: failpoint %s: job %lld %s\n", name, job,
            ret ? "no longer held: cancelled or stopping" : "released");
    return ret;
}

/* Counts a hit of point name: the action that fires on it (FP_OFF: none), its hit number, and
 * whether a hold fires on it too (held_too; may be NULL). */
static enum fp_action fire_of(srv_failpoints_t *fp, const char *name, long long *hit_out,
                              int *held_too)
{
    enum fp_action fire = FP_OFF;
    long long hit = 0;
    int hold_fires = 0;
    pthread_mutex_lock(&fp->mu);
    for (int i = 0; i < fp->n; i++) {
        struct fp_term *t = &fp->terms[i];
        if (strcmp(t->name, name) != 0) continue;
        t->hits++;
        if (!(t->at == 0 || t->hits == t->at)) continue;
        hold_fires |= t->action == FP_HOLD;
        /* of the terms that fire on this hit, a crash wins over an error, an error over a hold */
        if (t->action > fire) {
            fire = t->action;
            hit = t->hits;
        }
    }
    pthread_mutex_unlock(&fp->mu);
    *hit_out = hit;
    if (held_too) *held_too = hold_fires;
    return fire;
}

int srv_failpoint_frame(void *ctx, unsigned long long frame)
{
    srv_t *srv = ctx;
    if (!srv->failpoints) return SIM_FRAME_OK;
    long long hit;
    enum fp_action fire = fire_of(srv->failpoints, "camera.frame", &hit, NULL);
    if (fire == FP_OFF) return SIM_FRAME_OK;
    fprintf(stderr, "ipsd: failpoint camera.frame: the camera %s at its frame %llu (hit %lld)\n",
            fire == FP_HOLD ? "stops answering" : "fails", frame + 1, hit);
    return fire == FP_HOLD ? SIM_FRAME_HANG : SIM_FRAME_FAIL;
}

int srv_failpoint_eval(srv_worker_t *w, const char *name, err_t *err)
{
    srv_failpoints_t *fp = w->srv->failpoints;
    long long hit = 0;
    int held_too = 0;
    enum fp_action fire = fire_of(fp, name, &hit, &held_too);
    /* a crash armed with a hold on the same hit holds first and crashes when released, so a test
     * can see the request that queued the job answered before ipsd dies (a crash at a fit's
     * first step can otherwise come before the HTTP thread has sent the 202); a cancel or the
     * shutdown ends such a hold without the crash */
    if (fire == FP_CRASH && held_too) {
        int ret = hold(fp, w, name, hit);
        if (ret) return ret;
    }
    if (fire == FP_CRASH) {
        /* a crash as kill -9 makes it: no cleanup, nothing flushed, no transaction ended (stderr
         * is unbuffered, so the line is out before) */
        fprintf(stderr, "ipsd: failpoint %s: crashing in job %lld at hit %lld (SIGKILL)\n", name,
                (long long)atomic_load(&w->job), hit);
        raise(SIGKILL);
        _exit(137); /* not reached */
    }
    if (fire == FP_HOLD) return hold(fp, w, name, hit);
    if (fire == FP_ERROR) {
        fprintf(stderr, "ipsd: failpoint %s: error in job %lld at hit %lld\n", name,
                (long long)atomic_load(&w->job), hit);
        return err_set(err, -EIO, "failpoint %s: injected error (hit %lld)", name, hit);
    }
    return 0;
}
