/* cam_aravis.c: the "aravis" camera backend (cam.h): GenICam cameras (GigE Vision, USB3 Vision)
 * through Aravis 0.8, built as a module of its own (libipscam_aravis.so) that cam.c loads with
 * dlopen only when the backend is listed or opened, so that ips and ipsd link neither glib nor
 * Aravis. Its one exported symbol is ipsd_cam_backend_v3() (cam_impl.h); it needs nothing from
 * the program that loads it (err_set and cam_roi_check are compiled into it).
 *
 * Everything goes through Aravis's ArvCamera, which speaks the standard feature names (SFNC) and
 * the older ones a camera may have instead (ExposureTime or ExposureTimeAbs, Gain or GainRaw):
 *   - the deepest monochrome pixel format the camera offers (Mono16, Mono14, Mono12, Mono10 as
 *     16-bit values, Mono8); a camera with none is refused naming PixelFormat and what it offers;
 *   - ExposureAuto and GainAuto off where they exist; ExposureTime; the gain as a factor over the
 *     camera's base gain: a float Gain is taken in dB (SFNC's usual unit: 20 log10 of the factor
 *     above its minimum), an integer GainRaw only at its minimum (factor 1);
 *   - the region: the smallest one the camera can set (OffsetX/OffsetY/Width/Height on their
 *     increments) holding the region asked for, kept while later regions fit in it; the frame is
 *     cut out of it;
 *   - software trigger (TriggerSelector FrameStart, TriggerMode On, TriggerSource Software) with
 *     continuous acquisition: one trigger, one frame, exposed after the call that asked for it (a
 *     stage move before it is never in an older frame). A camera without a software trigger is
 *     started and stopped around each frame instead;
 *   - GigE Vision streams on a UDP socket of their own port, never Aravis's AF_PACKET ring (stray
 *     packets of other traffic read as frames), with a receive buffer that holds a frame's burst.
 * Faults are errors, never hangs: no frame within the timeout (cam_set_timeout; default the
 * exposure plus 5 s) is -ETIMEDOUT; a frame with missing packets, one that timed out in transfer,
 * or whose size, region or format differs from what was set is -EIO; a lost control channel
 * (Aravis's control-lost signal, a camera unplugged or switched off) fails every later call with
 * -EIO. After a faulty frame the acquisition and its stream are started anew, so that nothing
 * late of the old one is taken for a later frame; the old ones are stopped and released on a
 * thread of their own, waited for at most 1 s (5 s of Aravis's timeouts when the camera stopped
 * answering after its trigger). Messages carry Aravis's own words. Closing a
 * camera at fault sends it nothing itself and does not wait for Aravis, whose finalizers still
 * talk to the camera (10 s of timeouts against one that vanished): its objects are released on a
 * thread of their own (cam_aravis_release.c), waited for before the camera is opened again and
 * when the program ends. A handle is used by one thread at a time. */
#include <arpa/inet.h>
#include <arv.h>
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "cam_impl.h"
#include "cam_roi.h"
#include "cam_aravis_release.h"

#define N_BUFFERS 4
#define CLOSE_WAIT_S 1.0 /* a close waits this long at most for Aravis to release the camera */

/* Monochrome formats read, deepest first: name, bits per value, bytes per value. */
static const struct mono {
    const char *name;
    int bits, bytes;
} monos[] = {
    {"Mono16", 16, 2}, {"Mono14", 14, 2}, {"Mono12", 12, 2}, {"Mono10", 10, 2}, {"Mono8", 8, 1}};

typedef struct av {
    ArvCamera *cam;
    ArvStream *stream;
    gulong lost_handler;
    atomic_int *lost; /* Aravis said the control channel is lost (owned by the signal handler:
                         an emission in flight on Aravis's heartbeat thread may still set it) */
    int silent;       /* a command went unanswered: at fault (closing sends the camera nothing) */
    int releasing;    /* the old stream of a reset is still being released (reset) */
    cam_info_t info;
    const struct mono *fmt;
    ArvPixelFormat pixel_format; /* fmt's code, as frames carry it */
    cam_roi_t region;            /* the region the camera is set to (valid when has_region) */
    int has_region, acquiring, trigger;
    int gain_db; /* the gain feature is a float in dB (else GainRaw: factor 1) */
    double gain_feature_min;
    double exposure_us, gain, timeout_s;
} av_t;

/* Aravis's device list is global: one caller at a time. */
static pthread_mutex_t list_mu = PTHREAD_MUTEX_INITIALIZER;

/* Whether a GError says the camera did not answer (rather than refused or lacks something). */
static int transport_error(const GError *e)
{
    return e && e->domain == ARV_DEVICE_ERROR &&
           (e->code == ARV_DEVICE_ERROR_TIMEOUT || e->code == ARV_DEVICE_ERROR_NOT_CONNECTED ||
            e->code == ARV_DEVICE_ERROR_PROTOCOL_ERROR ||
            e->code == ARV_DEVICE_ERROR_TRANSFER_ERROR);
}

/* Sets err from a GError (consumed) with the camera's id in front; returns code, or -EIO when
 * the camera did not answer. */
static int fail(av_t *a, GError **e, int code, const char *what, err_t *err)
{
    if (transport_error(*e)) {
        code = -EIO;
        if (a) a->silent = 1;
    }
    int rc = err_set(err, code, "camera %s: %s: %s", a ? a->info.id : "?", what,
                     *e && (*e)->message ? (*e)->message : "unknown Aravis error");
    g_clear_error(e);
    return rc;
}

static void on_control_lost(ArvDevice *dev, gpointer user)
{
    (void)dev;
    atomic_store((atomic_int *)user, 1);
}

static void free_lost(gpointer user, GClosure *closure)
{
    (void)closure;
    free(user);
}

static int is_lost(const av_t *a)
{
    return a->lost && atomic_load(a->lost);
}

static int check_lost(av_t *a, err_t *err)
{
    if (!is_lost(a)) return 0;
    return err_set(err, -EIO,
                   "camera %s: control channel lost (the camera stopped answering its "
                   "heartbeat: unplugged, switched off or unreachable)",
                   a->info.id);
}

static void copy(char *dst, size_t size, const char *src)
{
    snprintf(dst, size, "%s", src ? src : "");
}

/* A string feature, or "" when the camera has none. */
static void get_string(ArvCamera *cam, const char *feature, char *dst, size_t size)
{
    GError *e = NULL;
    const char *v = NULL;
    if (arv_camera_is_feature_available(cam, feature, NULL))
        v = arv_camera_get_string(cam, feature, &e);
    copy(dst, size, e ? NULL : v);
    g_clear_error(&e);
}

/* ---- listing ---- */

static int av_list(cam_info_t **infos, size_t *n, err_t *err)
{
    *infos = NULL;
    *n = 0;
    pthread_mutex_lock(&list_mu);
    arv_update_device_list();
    unsigned count = arv_get_n_devices();
    int rc = 0;
    if (count > 0 && !(*infos = calloc(count, sizeof **infos)))
        rc = err_set(err, -ENOMEM, "out of memory for the camera list");
    for (unsigned i = 0; rc == 0 && i < count; i++) {
        cam_info_t *in = &(*infos)[i];
        copy(in->backend, sizeof in->backend, "aravis");
        copy(in->id, sizeof in->id, arv_get_device_id(i));
        copy(in->vendor, sizeof in->vendor, arv_get_device_vendor(i));
        copy(in->model, sizeof in->model, arv_get_device_model(i));
        copy(in->serial, sizeof in->serial, arv_get_device_serial_nbr(i));
        in->pitch_um = in->gain_e_per_dn = in->read_noise_e = in->bias_dn = NAN;
        in->full_scale_dn = in->exposure_min_us = in->exposure_max_us = NAN;
        in->gain_min = in->gain_max = NAN;
        (*n)++;
    }
    pthread_mutex_unlock(&list_mu);
    return rc;
}

/* ---- opening ---- */

/* The device id to open: id itself when Aravis finds it, the first camera for NULL / "". */
static int find_device(const char *id, char *out, size_t size, err_t *err)
{
    pthread_mutex_lock(&list_mu);
    arv_update_device_list();
    unsigned count = arv_get_n_devices(), i = 0;
    int rc = 0;
    if (count == 0) {
        rc = err_set(err, -ENODEV, "no camera found by Aravis");
    } else if (id && *id) {
        while (i < count && strcmp(arv_get_device_id(i), id) != 0)
            i++;
        if (i == count)
            rc = err_set(err, -ENODEV, "no camera '%s' found by Aravis (%u other%s present)", id,
                         count, count == 1 ? "" : "s");
    }
    if (rc == 0) copy(out, size, arv_get_device_id(i));
    pthread_mutex_unlock(&list_mu);
    return rc;
}

/* The deepest monochrome format the camera offers, set. -ENOTSUP naming what it offers. */
static int choose_format(av_t *a, err_t *err)
{
    GError *e = NULL;
    guint n = 0;
    const char **offered = arv_camera_dup_available_pixel_formats_as_strings(a->cam, &n, &e);
    if (e) return fail(a, &e, -EIO, "cannot read PixelFormat", err);
    for (size_t m = 0; m < sizeof monos / sizeof monos[0] && !a->fmt; m++)
        for (guint i = 0; i < n && !a->fmt; i++)
            if (offered[i] && strcmp(offered[i], monos[m].name) == 0) a->fmt = &monos[m];
    if (!a->fmt) {
        char list[256] = "";
        for (guint i = 0; i < n; i++)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", i ? ", " : "",
                     offered[i] ? offered[i] : "?");
        g_free(offered);
        return err_set(err, -ENOTSUP,
                       "camera %s: PixelFormat offers no monochrome format ipsd reads (it offers "
                       "%s; ipsd needs Mono16, Mono14, Mono12, Mono10 or Mono8)",
                       a->info.id, n ? list : "none");
    }
    g_free(offered);
    arv_camera_set_pixel_format_from_string(a->cam, a->fmt->name, &e);
    if (e) return fail(a, &e, -EIO, "cannot set PixelFormat", err);
    a->pixel_format = arv_camera_get_pixel_format(a->cam, &e);
    if (e) return fail(a, &e, -EIO, "cannot read PixelFormat", err);
    copy(a->info.pixel_format, sizeof a->info.pixel_format, a->fmt->name);
    a->info.bits = a->fmt->bits;
    a->info.full_scale_dn = ldexp(1.0, a->fmt->bits) - 1;
    return 0;
}

/* Exposure and gain: automatic modes off, ranges read. -ENOTSUP without an exposure time. */
static int setup_controls(av_t *a, err_t *err)
{
    GError *e = NULL;
    if (!arv_camera_is_exposure_time_available(a->cam, NULL))
        return err_set(err, -ENOTSUP, "camera %s has no ExposureTime feature", a->info.id);
    if (arv_camera_is_exposure_auto_available(a->cam, NULL)) {
        arv_camera_set_exposure_time_auto(a->cam, ARV_AUTO_OFF, &e);
        if (e) return fail(a, &e, -EIO, "cannot switch ExposureAuto off", err);
    }
    arv_camera_get_exposure_time_bounds(a->cam, &a->info.exposure_min_us, &a->info.exposure_max_us,
                                        &e);
    if (e) return fail(a, &e, -EIO, "cannot read the ExposureTime range", err);
    a->info.gain_min = a->info.gain_max = 1;
    if (arv_camera_is_gain_available(a->cam, NULL)) {
        if (arv_camera_is_gain_auto_available(a->cam, NULL)) {
            arv_camera_set_gain_auto(a->cam, ARV_AUTO_OFF, &e);
            if (e) return fail(a, &e, -EIO, "cannot switch GainAuto off", err);
        }
        double lo, hi;
        arv_camera_get_gain_bounds(a->cam, &lo, &hi, &e);
        if (e) return fail(a, &e, -EIO, "cannot read the Gain range", err);
        a->gain_feature_min = lo;
        a->gain_db = arv_camera_is_feature_available(a->cam, "Gain", NULL);
        if (a->gain_db) a->info.gain_max = pow(10, (hi - lo) / 20);
        arv_camera_set_gain(a->cam, lo, &e); /* factor 1: the base gain */
        if (e) return fail(a, &e, -EIO, "cannot set the gain", err);
    }
    a->gain = 1;
    a->exposure_us = arv_camera_get_exposure_time(a->cam, &e);
    if (e) return fail(a, &e, -EIO, "cannot read ExposureTime", err);
    return 0;
}

/* Software trigger when the camera has one; continuous acquisition either way. */
static int setup_acquisition(av_t *a, err_t *err)
{
    GError *e = NULL;
    a->trigger = arv_camera_is_software_trigger_supported(a->cam, NULL);
    if (a->trigger) {
        arv_camera_set_trigger(a->cam, "Software", &e);
        if (e) return fail(a, &e, -EIO, "cannot select the software trigger", err);
    } else {
        arv_camera_clear_triggers(a->cam, NULL); /* free running; absent triggers are fine */
    }
    arv_camera_set_acquisition_mode(a->cam, ARV_ACQUISITION_MODE_CONTINUOUS, &e);
    if (e) return fail(a, &e, -EIO, "cannot set AcquisitionMode Continuous", err);
    return 0;
}

/* The test hooks of cam_aravis_release: IPSD_ARAVIS_RELEASE_GATE=FD holds the release of a
 * camera closed at fault, IPSD_ARAVIS_RESET_GATE=FD that of the old stream after a faulty frame
 * (reset), until a byte can be read from FD; -1 when not set. */
static int release_gate(const char *name)
{
    const char *s = getenv(name);
    char *end = NULL;
    long fd = s && *s ? strtol(s, &end, 10) : -1;
    return fd >= 0 && fd <= 1 << 20 && *end == '\0' ? (int)fd : -1;
}

/* A camera at fault (a command unanswered, the control channel lost, or the release of a reset
 * still going on) is released in the background at once: every command Aravis's finalizers send
 * it would wait out its timeouts. A healthy one is waited for up to CLOSE_WAIT_S (milliseconds in
 * practice), which bounds the close of a camera that vanished unnoticed too. */
static void av_close(void *impl)
{
    av_t *a = impl;
    if (!a) return;
    int fault = a->silent || is_lost(a) || a->releasing;
    if (a->cam && a->lost_handler) /* frees a->lost once no emission uses it */
        g_signal_handler_disconnect(arv_camera_get_device(a->cam), a->lost_handler);
    else
        free(a->lost); /* never handed to a handler */
    if (a->cam || a->stream)
        cam_aravis_release(a->info.id, a->cam, a->stream, a->acquiring && !fault,
                           fault ? 0 : CLOSE_WAIT_S,
                           fault ? release_gate("IPSD_ARAVIS_RELEASE_GATE") : -1);
    free(a);
}

static int av_open(const char *id, void **out, err_t *err)
{
    *out = NULL;
    av_t *a = calloc(1, sizeof *a);
    if (!a) return err_set(err, -ENOMEM, "out of memory for the camera");
    GError *e = NULL;
    cam_info_t *in = &a->info;
    int rc = find_device(id, in->id, sizeof in->id, err);
    if (rc) goto out;
    cam_aravis_release_wait(in->id); /* an earlier handle's late commands come first */
    copy(in->backend, sizeof in->backend, "aravis");
    if (!(a->cam = arv_camera_new(in->id, &e))) {
        rc =
            fail(a, &e,
                 e && g_error_matches(e, ARV_DEVICE_ERROR, ARV_DEVICE_ERROR_PROTOCOL_ERROR) ? -EBUSY
                                                                                            : -EIO,
                 "cannot open", err);
        goto out;
    }
    /* GigE Vision streams on a plain UDP socket. Aravis's packet socket method (taken when the
     * process may open one: root, CAP_NET_RAW) reads the interface's IP packets through an
     * AF_PACKET ring and attaches its filter for the stream's port only after binding it: packets
     * of other traffic on that interface in between are parsed as the camera's, and one may hold
     * a buffer as a frame that never completes, which then comes out, timed out, before the good
     * frame the camera sent after it (docs/instrument.md, "Stray packets"). */
    if (arv_camera_is_gv_device(a->cam))
        arv_camera_gv_set_stream_options(a->cam, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
    if (!(a->lost = calloc(1, sizeof *a->lost))) {
        rc = err_set(err, -ENOMEM, "out of memory for the camera");
        goto out;
    }
    a->lost_handler = g_signal_connect_data(arv_camera_get_device(a->cam), "control-lost",
                                            G_CALLBACK(on_control_lost), a->lost, free_lost, 0);
    get_string(a->cam, "DeviceVendorName", in->vendor, sizeof in->vendor);
    get_string(a->cam, "DeviceModelName", in->model, sizeof in->model);
    get_string(a->cam, "DeviceSerialNumber", in->serial, sizeof in->serial);
    if (!in->serial[0]) get_string(a->cam, "DeviceID", in->serial, sizeof in->serial);
    get_string(a->cam, "DeviceFirmwareVersion", in->firmware, sizeof in->firmware);
    if (!in->firmware[0]) get_string(a->cam, "DeviceVersion", in->firmware, sizeof in->firmware);
    arv_camera_get_sensor_size(a->cam, &in->width, &in->height, &e);
    if (e) {
        rc = fail(a, &e, -EIO, "cannot read SensorWidth / SensorHeight", err);
        goto out;
    }
    /* what GenICam does not say: given by the scan's sensor */
    in->pitch_um = in->gain_e_per_dn = in->read_noise_e = in->bias_dn = NAN;
    if ((rc = choose_format(a, err)) || (rc = setup_controls(a, err)) ||
        (rc = setup_acquisition(a, err)))
        goto out;
out:
    if (rc) {
        av_close(a);
        return rc;
    }
    *out = a;
    return 0;
}

/* ---- operations ---- */

static int av_info(void *impl, cam_info_t *info, err_t *err)
{
    (void)err;
    *info = ((av_t *)impl)->info;
    return 0;
}

/* Before the camera is used: the release of a reset that outlived its wait has ended. */
static void settle(av_t *a)
{
    if (!a->releasing) return;
    cam_aravis_release_wait(a->info.id);
    a->releasing = 0;
}

static int av_set_exposure(void *impl, double us, err_t *err)
{
    av_t *a = impl;
    GError *e = NULL;
    if (!(us >= a->info.exposure_min_us && us <= a->info.exposure_max_us))
        return err_set(err, -ERANGE, "exposure %g us is outside the camera's range [%g, %g] us", us,
                       a->info.exposure_min_us, a->info.exposure_max_us);
    int rc = check_lost(a, err);
    if (rc) return rc;
    settle(a);
    arv_camera_set_exposure_time(a->cam, us, &e);
    if (e) return fail(a, &e, -EIO, "cannot set ExposureTime", err);
    a->exposure_us = arv_camera_get_exposure_time(a->cam, &e); /* on the camera's own steps */
    if (e) return fail(a, &e, -EIO, "cannot read ExposureTime", err);
    return 0;
}

static int av_set_gain(void *impl, double gain, err_t *err)
{
    av_t *a = impl;
    GError *e = NULL;
    if (!(gain >= a->info.gain_min * (1 - 1e-12) && gain <= a->info.gain_max * (1 + 1e-12)))
        return err_set(err, -ERANGE, "analogue gain %g is outside the camera's range [%g, %g]%s",
                       gain, a->info.gain_min, a->info.gain_max,
                       a->gain_db ? "" : " (its GainRaw has no known unit: only 1, the base gain)");
    int rc = check_lost(a, err);
    if (rc) return rc;
    settle(a);
    if (arv_camera_is_gain_available(a->cam, NULL)) {
        arv_camera_set_gain(a->cam, a->gain_feature_min + (a->gain_db ? 20 * log10(gain) : 0), &e);
        if (e) return fail(a, &e, -EIO, "cannot set the gain", err);
    }
    a->gain = gain;
    return 0;
}

static int av_set_timeout(void *impl, double seconds, err_t *err)
{
    (void)err;
    ((av_t *)impl)->timeout_s = seconds;
    return 0;
}

/* The smallest region on the camera's increments that holds [lo, lo + len) on one axis of size
 * total, with offset increment oinc and size increment sinc (size at least smin); 0 or -1. */
static int fit_axis(int lo, int len, int total, int oinc, int sinc, int smin, int offset_ok,
                    int *off, int *size)
{
    if (oinc < 1) oinc = 1;
    if (sinc < 1) sinc = 1;
    int o = offset_ok ? lo / oinc * oinc : 0;
    int s = (lo + len - o + sinc - 1) / sinc * sinc;
    if (s < smin) s = smin;
    while (o + s > total && o >= oinc)
        o -= oinc; /* pushed against the far edge */
    if (o + s > total || o > lo) return -1;
    *off = o;
    *size = s;
    return 0;
}

/* Stops the acquisition and drops the stream (the region or the buffers change). */
static void stop(av_t *a)
{
    if (a->acquiring && !is_lost(a)) arv_camera_stop_acquisition(a->cam, NULL);
    a->acquiring = 0;
    if (a->stream) g_object_unref(a->stream);
    a->stream = NULL;
}

/* After a faulty frame: a new acquisition and stream at the next capture, so that nothing of the
 * old one (a frame arriving late) is taken for a later frame. Stopping the acquisition and
 * releasing the stream (whose finalizer writes the stream channel's port register) are commands
 * to the camera: milliseconds when it answers, 5 s of Aravis's timeouts when it stopped answering
 * after the trigger (docs/instrument.md). So they run on a release thread (cam_aravis_release.c),
 * waited for at most CLOSE_WAIT_S, and a camera known at fault gets no AcquisitionStop and no
 * wait. A release that goes on is waited for before the camera is used again (settle): ArvCamera
 * is not used from two threads at once, and the old stream's port write must not land after a
 * new stream has set the port. */
static void reset(av_t *a)
{
    int fault = a->silent || is_lost(a), halt = a->acquiring && !fault;
    if ((a->stream || halt) &&
        !cam_aravis_release(a->info.id, halt ? g_object_ref(a->cam) : NULL, a->stream, halt,
                            fault ? 0 : CLOSE_WAIT_S, release_gate("IPSD_ARAVIS_RESET_GATE")))
        a->releasing = 1;
    a->stream = NULL;
    a->acquiring = 0;
    a->has_region = 0;
}

/* A GigE Vision frame arrives as a burst of datagrams, each counted in the stream socket's receive
 * buffer at about twice its payload: the default buffer (net.core.rmem_default, 208 KiB) holds
 * about 90 of them, and a 128 KiB frame (94 packets of 1400 bytes) lost its last ones whenever
 * the stream's thread waited for a core. So the socket asks for four frames, at least 1 MiB, which
 * the kernel caps at net.core.rmem_max (docs/instrument.md, "Socket buffers"). Aravis sets a size
 * it is given only when the first packet of a frame is read, after the burst has begun, so the
 * backend also sets it at once on the socket (Aravis keeps it private: the UDP socket of this
 * process bound to the stream's port). */
static void size_socket(ArvGvStream *stream, guint payload)
{
    int size = payload < (1u << 18) ? 1 << 20 : (int)MIN(payload, 1u << 28) * 4;
    g_object_set(stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size",
                 size, NULL);
    guint16 port = arv_gv_stream_get_port(stream);
    DIR *d = opendir("/proc/self/fd");
    for (struct dirent *e; d && (e = readdir(d));) {
        int fd = atoi(e->d_name), type = 0;
        struct sockaddr_in sa;
        socklen_t len = sizeof sa, tlen = sizeof type;
        if (e->d_name[0] != '.' && getsockname(fd, (struct sockaddr *)&sa, &len) == 0 &&
            sa.sin_family == AF_INET && ntohs(sa.sin_port) == port &&
            getsockopt(fd, SOL_SOCKET, SO_TYPE, &type, &tlen) == 0 && type == SOCK_DGRAM) {
            setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &size, sizeof size);
            break;
        }
    }
    if (d) closedir(d);
}

/* A camera region holding r: the current one, or a new one set, with a stream for it. */
static int ensure_region(av_t *a, const cam_roi_t *r, err_t *err)
{
    GError *e = NULL;
    if (a->has_region && r->col >= a->region.col && r->row >= a->region.row &&
        r->col + r->width <= a->region.col + a->region.width &&
        r->row + r->height <= a->region.row + a->region.height && a->stream)
        return 0;
    stop(a);
    a->has_region = 0;
    int offset_ok = arv_camera_is_region_offset_available(a->cam, NULL);
    gint wmin = 1, wmax = 0, hmin = 1, hmax = 0;
    arv_camera_get_width_bounds(a->cam, &wmin, &wmax, NULL);
    arv_camera_get_height_bounds(a->cam, &hmin, &hmax, NULL);
    int xinc = offset_ok ? arv_camera_get_x_offset_increment(a->cam, NULL) : 1;
    int yinc = offset_ok ? arv_camera_get_y_offset_increment(a->cam, NULL) : 1;
    cam_roi_t want;
    if (fit_axis(r->col, r->width, a->info.width, xinc,
                 arv_camera_get_width_increment(a->cam, NULL), wmin, offset_ok, &want.col,
                 &want.width) ||
        fit_axis(r->row, r->height, a->info.height, yinc,
                 arv_camera_get_height_increment(a->cam, NULL), hmin, offset_ok, &want.row,
                 &want.height))
        return err_set(err, -ENOTSUP,
                       "camera %s: no region OffsetX/OffsetY/Width/Height can hold %dx%d at "
                       "column %d, row %d on its increments",
                       a->info.id, r->width, r->height, r->col, r->row);
    /* offsets to 0 first: a smaller offset may be needed before a larger size is allowed */
    if (offset_ok) arv_camera_set_region(a->cam, 0, 0, want.width, want.height, &e);
    if (transport_error(e)) return fail(a, &e, -EIO, "cannot set the region", err);
    g_clear_error(&e);
    arv_camera_set_region(a->cam, want.col, want.row, want.width, want.height, &e);
    if (e)
        return fail(a, &e, -ENOTSUP, "cannot set the region (OffsetX/OffsetY/Width/Height)", err);
    gint x, y, w, h;
    arv_camera_get_region(a->cam, &x, &y, &w, &h, &e);
    if (e) return fail(a, &e, -EIO, "cannot read the region back", err);
    if (x > r->col || y > r->row || x + w < r->col + r->width || y + h < r->row + r->height)
        return err_set(err, -ENOTSUP,
                       "camera %s: the region set (%dx%d at %d, %d) does not hold the one asked "
                       "for (%dx%d at %d, %d): OffsetX/OffsetY/Width/Height refused it",
                       a->info.id, w, h, x, y, r->width, r->height, r->col, r->row);
    a->region = (cam_roi_t){x, y, w, h};
    guint payload = arv_camera_get_payload(a->cam, &e);
    if (e) return fail(a, &e, -EIO, "cannot read PayloadSize", err);
    if (!(a->stream = arv_camera_create_stream(a->cam, NULL, NULL, &e)))
        return fail(a, &e, -EIO, "cannot open a stream", err);
    if (ARV_IS_GV_STREAM(a->stream)) size_socket(ARV_GV_STREAM(a->stream), payload);
    for (int i = 0; i < N_BUFFERS; i++)
        arv_stream_push_buffer(a->stream, arv_buffer_new(payload, NULL));
    a->has_region = 1;
    if (a->trigger) {
        arv_camera_start_acquisition(a->cam, &e);
        if (e) return fail(a, &e, -EIO, "cannot start the acquisition", err);
        a->acquiring = 1;
    }
    return 0;
}

/* What a buffer's status means. */
static const char *status_text(ArvBufferStatus s)
{
    switch (s) {
    case ARV_BUFFER_STATUS_TIMEOUT:
        return "incomplete frame: its transfer timed out";
    case ARV_BUFFER_STATUS_MISSING_PACKETS:
        return "incomplete frame: packets missing";
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID:
        return "corrupt frame: a packet of another frame";
    case ARV_BUFFER_STATUS_SIZE_MISMATCH:
        return "size mismatch: the frame is larger than its buffer";
    case ARV_BUFFER_STATUS_ABORTED:
        return "frame aborted";
    case ARV_BUFFER_STATUS_CLEARED:
        return "frame cleared";
    case ARV_BUFFER_STATUS_FILLING:
        return "frame still filling";
    default:
        return "frame with an unknown status";
    }
}

/* Asks for one frame and waits for it; *out is the stream's buffer (push it back). */
static int get_frame(av_t *a, ArvBuffer **out, err_t *err)
{
    GError *e = NULL;
    ArvBuffer *b = NULL;
    while ((b = arv_stream_try_pop_buffer(a->stream))) /* an older frame is not this one */
        arv_stream_push_buffer(a->stream, b);
    if (a->trigger) {
        arv_camera_software_trigger(a->cam, &e);
        if (e) return fail(a, &e, -EIO, "software trigger failed", err);
    } else {
        arv_camera_start_acquisition(a->cam, &e);
        if (e) return fail(a, &e, -EIO, "cannot start the acquisition", err);
        a->acquiring = 1;
    }
    double limit_s = a->timeout_s > 0 ? a->timeout_s : a->exposure_us * 1e-6 + 5;
    gint64 end_us = g_get_monotonic_time() + (gint64)(limit_s * 1e6), left_us;
    /* a buffer handed back still cleared holds no frame at all (the emulator's stream gave one
     * once in a long scan): not this frame, nor a faulty one; the wait goes on */
    while ((left_us = end_us - g_get_monotonic_time()) > 0 &&
           (b = arv_stream_timeout_pop_buffer(a->stream, (guint64)left_us)) &&
           arv_buffer_get_status(b) == ARV_BUFFER_STATUS_CLEARED) {
        arv_stream_push_buffer(a->stream, b);
        b = NULL;
    }
    if (!a->trigger) {
        arv_camera_stop_acquisition(a->cam, NULL);
        a->acquiring = 0;
    }
    if (!b) {
        reset(a);
        int rc = check_lost(a, err);
        return rc ? rc
                  : err_set(err, -ETIMEDOUT, "camera %s: no frame within %g s", a->info.id,
                            limit_s);
    }
    *out = b;
    return 0;
}

static int av_capture(void *impl, const cam_roi_t *roi, cam_frame_t *f, err_t *err)
{
    av_t *a = impl;
    cam_roi_t r;
    int rc = cam_roi_check(roi, a->info.width, a->info.height, &r, err);
    if (rc || (rc = check_lost(a, err))) return rc;
    settle(a);
    if ((rc = ensure_region(a, &r, err))) return rc;
    ArvBuffer *b = NULL;
    if ((rc = get_frame(a, &b, err))) return rc;
    ArvBufferStatus st = arv_buffer_get_status(b);
    gint x = 0, y = 0, w = 0, h = 0;
    size_t size = 0;
    const uint8_t *data = NULL;
    if (st != ARV_BUFFER_STATUS_SUCCESS) {
        rc = err_set(err, -EIO, "camera %s: frame %llu: %s", a->info.id,
                     (unsigned long long)arv_buffer_get_frame_id(b), status_text(st));
        goto out;
    }
    arv_buffer_get_image_region(b, &x, &y, &w, &h);
    data = arv_buffer_get_image_data(b, &size);
    if (x != a->region.col || y != a->region.row || w != a->region.width || h != a->region.height ||
        !data || size < (size_t)w * h * a->fmt->bytes ||
        arv_buffer_get_image_pixel_format(b) != a->pixel_format) {
        rc = err_set(err, -EIO,
                     "camera %s: frame %llu: size mismatch: %dx%d at %d, %d with %zu bytes, "
                     "the region set is %dx%d at %d, %d in %s",
                     a->info.id, (unsigned long long)arv_buffer_get_frame_id(b), w, h, x, y, size,
                     a->region.width, a->region.height, a->region.col, a->region.row, a->fmt->name);
        goto out;
    }
    if (!(f->dn = malloc(sizeof(uint16_t) * (size_t)r.width * r.height))) {
        rc = err_set(err, -ENOMEM, "out of memory for a frame");
        goto out;
    }
    /* GigE Vision and USB3 Vision send multi-byte pixels little-endian */
    for (int j = 0; j < r.height; j++) {
        const uint8_t *row = data + ((size_t)(r.row - y + j) * w + (r.col - x)) * a->fmt->bytes;
        uint16_t *dst = f->dn + (size_t)j * r.width;
        for (int i = 0; i < r.width; i++)
            dst[i] = a->fmt->bytes == 1 ? row[i] : (uint16_t)(row[2 * i] | row[2 * i + 1] << 8);
    }
    f->roi = r;
    f->exposure_us = a->exposure_us;
    f->gain = a->gain;
    guint64 ts = arv_buffer_get_timestamp(b);
    f->timestamp_ns = (int64_t)(ts ? ts : arv_buffer_get_system_timestamp(b));
    f->temperature_c = NAN;
    f->camera_frame_id = arv_buffer_get_frame_id(b);
out:
    arv_stream_push_buffer(a->stream, b);
    if (rc) reset(a);
    return rc;
}

static const struct cam_ops av_ops = {av_close,    av_info,    av_set_exposure,
                                      av_set_gain, av_capture, av_set_timeout};

static const struct cam_backend av_backend = {CAM_BACKEND_HEADER, "aravis", av_list, av_open,
                                              &av_ops};

/* The module's entry point (cam_impl.h), the one symbol it exports. */
__attribute__((visibility("default"))) const struct cam_backend *ipsd_cam_backend_v3(void)
{
    return &av_backend;
}
