/* cam.c: the camera interface (cam.h) over a table of backends chosen by name at run time, as
 * SQLite picks a VFS: each entry is built in (the simulator's) or a module loaded with dlopen the
 * first time its backend is listed or opened (libcamera's: libipscam_libcamera.so; Aravis's:
 * libipscam_aravis.so), so that no program pays for libcamera and its ~30 libraries, or glib and
 * Aravis, unless it drives a real camera. How a backend plugs in, and the module ABI: cam_impl.h.
 *
 * Modules are looked for in the directories of $IPSD_CAM_MODULE_PATH (colon-separated) when it is
 * set, else in IPSD_CAM_MODULE_PATH_DEFAULT, compiled in by instrument/CMakeLists.txt: the build
 * tree's lib/ipsd, then the install location. A loaded module stays loaded (its cameras' threads
 * and libcamera's own state outlive any one handle); a failed load is tried again next time. */
#include "instrument/cam.h"

#include <dlfcn.h>
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cam_impl.h"

struct cam {
    const struct cam_ops *ops;
    void *impl;
    uint64_t sequence;
};

/* The backends: built in, or the file name of the module that provides it. */
static const struct slot {
    const char *name;
    const struct cam_backend *builtin;
    const char *module;
} slots[] = {
    {"sim", &cam_sim_backend, NULL},
    {"libcamera", NULL, "libipscam_libcamera.so"},
    {"aravis", NULL, "libipscam_aravis.so"},
};
#define N_SLOTS (sizeof slots / sizeof slots[0])

static pthread_mutex_t load_mu = PTHREAD_MUTEX_INITIALIZER;
static const struct cam_backend *loaded[N_SLOTS]; /* modules loaded so far, under load_mu */

static const char *module_path(void)
{
    const char *env = getenv("IPSD_CAM_MODULE_PATH");
    return env && *env ? env : IPSD_CAM_MODULE_PATH_DEFAULT;
}

/* Calls fn(dir/file, arg) for each directory of the module path until it returns non-zero;
 * returns that, or 0. */
static int each_candidate(const char *file, int (*fn)(const char *path, void *arg), void *arg)
{
    char path[4096];
    for (const char *p = module_path();; p++) {
        size_t len = strcspn(p, ":");
        int rc = 0;
        if (len > 0 && snprintf(path, sizeof path, "%.*s/%s", (int)len, p, file) < (int)sizeof path)
            rc = fn(path, arg);
        if (rc) return rc;
        p += len;
        if (!*p) return 0;
    }
}

static int exists(const char *path, void *arg)
{
    (void)arg;
    return access(path, R_OK) == 0;
}

/* One search for a module: what loaded, or why nothing did (the most telling reason: a file
 * that is there but does not load says more than one that is not there). */
struct attempt {
    const struct slot *slot;
    const struct cam_backend *table;
    char why[200];
    int why_present;
};

/* Checks what a module's entry point gave: its version, the layouts, its name, its functions. */
static const char *table_problem(const struct cam_backend *t, const char *name)
{
    if (!t) return "its entry point returned no table";
    if (t->abi != CAM_BACKEND_ABI) return "its backend ABI version differs from this program's";
    if (t->info_size != sizeof(cam_info_t) || t->frame_size != sizeof(cam_frame_t) ||
        t->err_size != sizeof(err_t))
        return "it was built against other cam.h / err.h layouts";
    if (!t->name || strcmp(t->name, name) != 0) return "it provides another backend";
    if (!t->list || !t->open || !t->ops || !t->ops->info || !t->ops->set_exposure ||
        !t->ops->set_gain || !t->ops->capture || !t->ops->set_timeout)
        return "its table lacks an operation";
    return NULL;
}

static int try_load(const char *path, void *arg)
{
    struct attempt *a = arg;
    int present = access(path, F_OK) == 0;
    const char *why;
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        why = dlerror();
    } else {
        cam_backend_entry_fn entry;
        /* POSIX's way from a dlsym result to a function pointer (dlsym(3)) */
        *(void **)&entry = dlsym(h, CAM_BACKEND_ENTRY);
        a->table = entry ? entry() : NULL;
        why = entry ? table_problem(a->table, a->slot->name) : "it has no " CAM_BACKEND_ENTRY "()";
        if (!why) return 1; /* loaded for good */
        a->table = NULL;
        dlclose(h);
    }
    if (!why) why = "unknown dlopen error";
    if (!a->why[0] || (present && !a->why_present)) {
        /* dlerror names the file when the file itself fails, not when a library it needs does */
        int named = strncmp(why, path, strlen(path)) == 0;
        snprintf(a->why, sizeof a->why, "%s%s%s", named ? "" : path, named ? "" : ": ", why);
        a->why_present = present;
    }
    return 0;
}

/* Loads slot's module (under load_mu). 0 with *out, or -ENOTSUP with the reason. */
static int load_module(const struct slot *sl, const struct cam_backend **out, err_t *err)
{
    struct attempt a = {.slot = sl};
    if (each_candidate(sl->module, try_load, &a)) {
        *out = a.table;
        return 0;
    }
    return err_set(err, -ENOTSUP,
                   "camera backend '%s' is not built or not installed (%s; set "
                   "IPSD_CAM_MODULE_PATH to the directory of %s)",
                   sl->name, a.why[0] ? a.why : "IPSD_CAM_MODULE_PATH lists no directory",
                   sl->module);
}

/* The backend called name (NULL: "sim"), its module loaded if need be. 0 with *out, -EINVAL for
 * an unknown name, -ENOTSUP for a module that does not load. */
static int backend_of(const char *name, const struct cam_backend **out, err_t *err)
{
    if (!name) name = "sim";
    for (size_t i = 0; i < N_SLOTS; i++) {
        if (strcmp(slots[i].name, name) != 0) continue;
        if (slots[i].builtin) {
            *out = slots[i].builtin;
            return 0;
        }
        pthread_mutex_lock(&load_mu);
        int rc = loaded[i] ? 0 : load_module(&slots[i], &loaded[i], err);
        *out = loaded[i];
        pthread_mutex_unlock(&load_mu);
        return rc;
    }
    char names[128] = "";
    for (size_t i = 0; i < N_SLOTS; i++)
        snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s",
                 i == 0             ? ""
                 : i + 1 == N_SLOTS ? " or "
                                    : ", ",
                 slots[i].name);
    return err_set(err, -EINVAL, "unknown camera backend '%s' (%s)", name, names);
}

static const char *available[N_SLOTS + 1];
static pthread_once_t available_once = PTHREAD_ONCE_INIT;

static void find_available(void)
{
    size_t n = 0;
    for (size_t i = 0; i < N_SLOTS; i++)
        if (slots[i].builtin || each_candidate(slots[i].module, exists, NULL))
            available[n++] = slots[i].name;
    available[n] = NULL;
}

const char *const *cam_backends(void)
{
    pthread_once(&available_once, find_available);
    return available;
}

cam_t *cam_wrap(const struct cam_ops *ops, void *impl)
{
    cam_t *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->ops = ops;
    c->impl = impl;
    return c;
}

void *cam_impl_of(cam_t *cam, const struct cam_ops *ops)
{
    return cam && cam->ops == ops ? cam->impl : NULL;
}

int cam_list(const char *backend, cam_info_t **infos, size_t *n, err_t *err)
{
    const struct cam_backend *b;
    *infos = NULL;
    *n = 0;
    int rc = backend_of(backend, &b, err);
    return rc ? rc : b->list(infos, n, err);
}

int cam_open(const char *backend, const char *id, cam_t **out, err_t *err)
{
    const struct cam_backend *b;
    void *impl = NULL;
    *out = NULL;
    int rc = backend_of(backend, &b, err);
    if (rc || (rc = b->open(id, &impl, err)) != 0) return rc;
    if (!(*out = cam_wrap(b->ops, impl))) {
        if (b->ops->close) b->ops->close(impl);
        return err_set(err, -ENOMEM, "out of memory for the camera");
    }
    return 0;
}

void cam_close(cam_t *cam)
{
    if (!cam) return;
    if (cam->ops->close) cam->ops->close(cam->impl);
    free(cam);
}

int cam_get_info(cam_t *cam, cam_info_t *info, err_t *err)
{
    memset(info, 0, sizeof *info);
    return cam->ops->info(cam->impl, info, err);
}

int cam_set_exposure(cam_t *cam, double exposure_us, err_t *err)
{
    return cam->ops->set_exposure(cam->impl, exposure_us, err);
}

int cam_set_gain(cam_t *cam, double gain, err_t *err)
{
    return cam->ops->set_gain(cam->impl, gain, err);
}

int cam_set_timeout(cam_t *cam, double seconds, err_t *err)
{
    if (!(seconds >= 0 && seconds < 1e9))
        return err_set(err, -EINVAL, "camera timeout %g s: need 0 (default) or more", seconds);
    return cam->ops->set_timeout(cam->impl, seconds, err);
}

int cam_capture(cam_t *cam, const cam_roi_t *roi, cam_frame_t *frame, err_t *err)
{
    memset(frame, 0, sizeof *frame);
    int rc = cam->ops->capture(cam->impl, roi, frame, err);
    if (rc) {
        cam_frame_free(frame);
        return rc;
    }
    frame->sequence = cam->sequence++;
    return 0;
}

void cam_frame_free(cam_frame_t *frame)
{
    if (!frame) return;
    free(frame->dn);
    free(frame->expected_dn);
    memset(frame, 0, sizeof *frame);
}
