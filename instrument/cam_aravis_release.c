/* cam_aravis_release.c: releasing a camera's Aravis objects on a thread of its own, waited for
 * before the camera is opened again and when the program ends (cam_aravis_release.h says why).
 * GLib's threads, mutex and condition (Aravis's own; its timed wait is on the monotonic clock). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cam_aravis_release.h"

struct release {
    struct release *next;
    GThread *thread;
    char id[128];
    ArvCamera *cam;
    ArvStream *stream;
    int stop, gate_fd;
    int done;   /* under mu: its thread ended its work */
    int waited; /* under mu: cam_aravis_release is waiting for it (no one else frees it) */
};

static GMutex mu; /* guards pending and each release's done (static storage: no init needed) */
static GCond ended;
static struct release *pending; /* releases whose threads are not joined yet */

static void release_objects(struct release *r)
{
    if (r->stop) arv_camera_stop_acquisition(r->cam, NULL);
    if (r->stream) g_object_unref(r->stream);
    if (r->cam) g_object_unref(r->cam);
}

static gpointer run(gpointer data)
{
    struct release *r = data;
    char c;
    if (r->gate_fd >= 0)
        while (read(r->gate_fd, &c, 1) < 0 && errno == EINTR)
            ;
    release_objects(r);
    g_mutex_lock(&mu);
    r->done = 1;
    g_cond_broadcast(&ended);
    g_mutex_unlock(&mu);
    return NULL;
}

/* Joins and frees the releases that ended (mu held: their threads no longer take it). */
static void reap(void)
{
    for (struct release **p = &pending; *p;) {
        struct release *r = *p;
        if (!r->done || r->waited) {
            p = &r->next;
            continue;
        }
        *p = r->next;
        g_thread_join(r->thread);
        free(r);
    }
}

int cam_aravis_release(const char *id, ArvCamera *cam, ArvStream *stream, int stop, double wait_s,
                       int gate_fd)
{
    struct release *r = calloc(1, sizeof *r);
    if (!r) { /* out of memory: released here, waiting as long as it takes */
        struct release here = {.cam = cam, .stream = stream, .stop = stop};
        release_objects(&here);
        return 1;
    }
    snprintf(r->id, sizeof r->id, "%s", id ? id : "");
    r->cam = cam;
    r->stream = stream;
    r->stop = stop;
    r->gate_fd = gate_fd;
    g_mutex_lock(&mu);
    reap();
    r->thread = g_thread_try_new("ipsd-arv-close", run, r, NULL);
    if (!r->thread) {
        g_mutex_unlock(&mu);
        r->gate_fd = -1;
        release_objects(r); /* no thread: here */
        free(r);
        return 1;
    }
    r->next = pending;
    pending = r;
    r->waited = 1;
    gint64 end_us = g_get_monotonic_time() + (gint64)(wait_s * 1e6);
    while (!r->done && wait_s > 0 && g_cond_wait_until(&ended, &mu, end_us))
        ;
    int done = r->done;
    r->waited = 0;
    reap(); /* r is freed here when done */
    g_mutex_unlock(&mu);
    return done;
}

void cam_aravis_release_wait(const char *id)
{
    g_mutex_lock(&mu);
    for (;;) {
        reap();
        int running = 0;
        for (struct release *r = pending; r && !running; r = r->next)
            running = !r->done && (!id || strcmp(r->id, id) == 0);
        if (!running) break;
        g_cond_wait(&ended, &mu);
    }
    g_mutex_unlock(&mu);
}

/* The module unloaded or the program ending: no release thread outlives it. */
__attribute__((destructor)) static void release_all(void)
{
    cam_aravis_release_wait(NULL);
}
