/* test_cam_aravis.c: the Aravis camera backend (instrument/cam_aravis.c, a module cam.c loads at
 * run time) against Aravis's own GigE Vision camera emulator (ArvGvFakeCamera) on 127.0.0.1 in
 * this process: the real protocol (GVCP control, GVSP streaming, the GenICam XML) over loopback.
 *
 * The emulator's frames are drawn by this test's fill pattern, a value that depends on the
 * sensor position and the camera's frame id, so every frame ipsd reads is checked pixel for pixel
 * against what the emulator sent. Then: the camera's description (vendor, model, serial,
 * firmware, Mono16 at 16 bits), exposure reaching the camera, one trigger one frame (consecutive
 * frame ids), regions inside the current one reused, the stream on a UDP socket (no AF_PACKET
 * socket in this process, which Aravis would open when run as root), and the faults, each an error and never a
 * hang: a frame that does not come (-ETIMEDOUT, and the next capture is good), a frame of another
 * size than the region set (-EIO, "size mismatch"), a frame losing packets (-EIO or -ETIMEDOUT), a
 * camera gone (an error with Aravis's words) and back (opened again), and a camera without a
 * monochrome format (refused at open naming PixelFormat).
 *
 * Closing the camera that went away waits for none of Aravis's commands to it: its release is
 * held at the backend's test gate (IPSD_ARAVIS_RELEASE_GATE, a pipe of this test) while close
 * returns, with Aravis's stream thread still there (its finalizer, the first to talk to the
 * camera, has not run); let go, it ends by itself and leaves no thread behind. The close and the
 * release are printed as figures, not asserted (a wide bound only as a safety net), as is the
 * close of the camera gone again unnoticed (no command failed: a bounded wait). The emulator
 * binds the GigE Vision control port 3956: ctest runs the tests that use it one at a time
 * (RESOURCE_LOCK), and a lock file orders them across ctest runs (gige_lock.h). */
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
#include <time.h>
#include <unistd.h>

#include "instrument/cam.h"
#include "check.h"
#include "gige_lock.h"

#define SERIAL "IPSDTEST1"
#define DEVICE_ID "Aravis-Fake-" SERIAL /* Aravis's id: vendor, model, serial */

static atomic_uint seen_exposure_us, fills;

/* The camera going away right after it sent a frame: armed by the test, the emulator's thread
 * says when it filled the next frame, and a thread of the test then stops the emulator. */
static struct {
    pthread_mutex_t mu;
    pthread_cond_t cond;
    int armed, filled;
    ArvGvFakeCamera *gv;
} vanish = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER, 0, 0, NULL};

/* What the emulator sends at sensor column x, row y in frame fid. */
static uint16_t pattern(int x, int y, uint64_t fid)
{
    return (uint16_t)((unsigned)x * 7u + (unsigned)y * 131u + (unsigned)fid * 977u);
}

static void fill(ArvBuffer *buffer, void *data, guint32 exposure_us, guint32 gain,
                 ArvPixelFormat format)
{
    (void)data;
    (void)gain;
    atomic_store(&seen_exposure_us, exposure_us);
    gint x0, y0, w, h;
    arv_buffer_get_image_region(buffer, &x0, &y0, &w, &h);
    /* the emulator's own buffer, allocated for the region and format its registers say (the
     * size it reports is what a pattern has filled so far: none yet) */
    uint8_t *p = (uint8_t *)arv_buffer_get_data(buffer, NULL);
    if (format != ARV_PIXEL_FORMAT_MONO_16) return;
    uint64_t fid = arv_buffer_get_frame_id(buffer);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            uint16_t v = pattern(x0 + x, y0 + y, fid);
            p[2 * ((size_t)y * w + x)] = (uint8_t)(v & 0xff); /* GigE Vision: little-endian */
            p[2 * ((size_t)y * w + x) + 1] = (uint8_t)(v >> 8);
        }
    atomic_fetch_add(&fills, 1);
    pthread_mutex_lock(&vanish.mu);
    if (vanish.armed) {
        vanish.filled = 1;
        pthread_cond_signal(&vanish.cond);
    }
    pthread_mutex_unlock(&vanish.mu);
}

static void *vanish_run(void *unused)
{
    (void)unused;
    pthread_mutex_lock(&vanish.mu);
    while (!vanish.filled)
        pthread_cond_wait(&vanish.cond, &vanish.mu);
    pthread_mutex_unlock(&vanish.mu);
    g_object_unref(vanish.gv); /* its thread joined, its sockets closed: the camera is gone */
    return NULL;
}

static ArvGvFakeCamera *emulator(const char *genicam)
{
    ArvGvFakeCamera *gv = arv_gv_fake_camera_new_full("127.0.0.1", SERIAL, genicam);
    if (!arv_gv_fake_camera_is_running(gv)) {
        fprintf(stderr, "the GigE Vision emulator does not run (port 3956 in use?)\n");
        exit(1);
    }
    ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera(gv);
    arv_fake_camera_set_fill_pattern(fake, fill, NULL);
    arv_fake_camera_set_trigger_frequency(fake, 1000); /* a software trigger is seen within 1 ms */
    return gv;
}

/* Every pixel of f is what the emulator sent in the frame f says it is. */
static int frame_is_pattern(const cam_frame_t *f)
{
    if (!f->dn || f->camera_frame_id == 0) return 0;
    for (int y = 0; y < f->roi.height; y++)
        for (int x = 0; x < f->roi.width; x++)
            if (f->dn[y * f->roi.width + x] !=
                pattern(f->roi.col + x, f->roi.row + y, f->camera_frame_id)) {
                fprintf(stderr, "frame %llu (%d, %d): %u, sent %u\n",
                        (unsigned long long)f->camera_frame_id, f->roi.col + x, f->roi.row + y,
                        f->dn[y * f->roi.width + x],
                        pattern(f->roi.col + x, f->roi.row + y, f->camera_frame_id));
                return 0;
            }
    return 1;
}

static int listed(const char *id)
{
    cam_info_t *l = NULL;
    size_t n = 0;
    err_t err;
    int found = 0;
    if (cam_list("aravis", &l, &n, &err) != 0) return 0;
    for (size_t i = 0; i < n; i++)
        found |= strcmp(l[i].id, id) == 0 && strcmp(l[i].backend, "aravis") == 0 &&
                 strcmp(l[i].serial, SERIAL) == 0;
    free(l);
    return found;
}

/* The emulator's GenICam XML without its monochrome formats, written to path. */
static int xml_without_mono(const char *path)
{
    ArvFakeCamera *fake = arv_fake_camera_new("X");
    size_t n;
    const char *xml = arv_fake_camera_get_genicam_xml(fake, &n);
    char *copy = g_strndup(xml, n);
    g_object_unref(fake);
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    for (char *line = strtok(copy, "\n"); line; line = strtok(NULL, "\n")) {
        /* an EnumEntry of Mono8 or Mono16: its three lines go */
        if (strstr(line, "EnumEntry Name=\"Mono")) {
            strtok(NULL, "\n");
            strtok(NULL, "\n");
            continue;
        }
        fprintf(f, "%s\n", line);
    }
    g_free(copy);
    return fclose(f);
}

/* How many threads of this process are named name (their /proc comm). */
static int threads_named(const char *name)
{
    DIR *d = opendir("/proc/self/task");
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        char path[300], comm[64] = "";
        if (e->d_name[0] == '.') continue;
        snprintf(path, sizeof path, "/proc/self/task/%s/comm", e->d_name);
        FILE *f = fopen(path, "r");
        if (f && fgets(comm, sizeof comm, f)) {
            comm[strcspn(comm, "\n")] = '\0';
            n += strcmp(comm, name) == 0;
        }
        if (f) fclose(f);
    }
    if (d) closedir(d);
    return n;
}

/* Whether this process may open an AF_PACKET socket (root or CAP_NET_RAW), as Aravis checks
 * before it streams through one. */
static int may_open_packet_socket(void)
{
    int fd = socket(AF_PACKET, SOCK_RAW, 0);
    if (fd >= 0) close(fd);
    return fd >= 0;
}

/* How many AF_PACKET sockets this process holds: the inodes of /proc/net/packet (its last
 * column) among the sockets of /proc/self/fd. */
static int packet_sockets_held(void)
{
    FILE *f = fopen("/proc/net/packet", "r");
    char line[512];
    int n = 0;
    if (!f || !fgets(line, sizeof line, f)) { /* the header */
        if (f) fclose(f);
        return -1;
    }
    while (fgets(line, sizeof line, f)) {
        char *last = strrchr(line, ' '), want[64], path[300], link[64];
        snprintf(want, sizeof want, "socket:[%lu]", last ? strtoul(last + 1, NULL, 10) : 0ul);
        DIR *d = opendir("/proc/self/fd");
        for (struct dirent *e; d && (e = readdir(d));) {
            snprintf(path, sizeof path, "/proc/self/fd/%s", e->d_name);
            ssize_t k = readlink(path, link, sizeof link - 1);
            if (k > 0) link[k] = '\0';
            n += k > 0 && strcmp(link, want) == 0;
        }
        if (d) closedir(d);
    }
    fclose(f);
    return n;
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

/* test_cam_aravis --reset: the reset after a frame that did not come (instrument/cam_aravis.c,
 * reset) stops the acquisition and releases the old stream on a thread of its own, and the
 * capture waits for it a bounded time. Shown by a test hook, not by the clock: with
 * IPSD_ARAVIS_RESET_GATE=FD set (for this whole process: every reset in it is held), that
 * release first reads a byte from FD, so the capture returns while it is held, with the old
 * stream's thread still there. Then: let go, the next capture waits for it and gets a good frame
 * on a new stream; and the camera gone right after its trigger, whose release (AcquisitionStop
 * and the stream's port write, each waiting out Aravis's timeouts) goes on in the background
 * while the capture has returned. The times are printed as figures. */
static int reset_case(void)
{
    int gate[2];
    char gate_fd[16];
    CHECK(pipe(gate) == 0);
    snprintf(gate_fd, sizeof gate_fd, "%d", gate[0]);
    setenv("IPSD_ARAVIS_RESET_GATE", gate_fd, 1); /* before any thread runs */
    err_t err = {{0}};
    cam_t *cam = NULL;
    cam_frame_t f = {0};
    ArvGvFakeCamera *gv = emulator(NULL);
    cam_roi_t roi = {1000, 1200, 9, 9};
    CHECK(cam_open("aravis", DEVICE_ID, &cam, &err) == 0 && cam != NULL);
    if (!cam) {
        fprintf(stderr, "%s\n", err.msg);
        CHECK_DONE();
    }
    CHECK(cam_capture(cam, &roi, &f, &err) == 0 && frame_is_pattern(&f));
    cam_frame_free(&f);
    CHECK(threads_named("arv_gv_stream") == 1);

    /* ---- a frame that does not come: the capture returns, its reset's release held ---- */
    CHECK(cam_set_timeout(cam, 0.3, &err) == 0);
    g_object_set(gv, "gvsp-lost-ratio", 1.0, NULL);
    double t0 = now_s();
    int rc = cam_capture(cam, &roi, &f, &err);
    double late_s = now_s() - t0 - 0.3;
    CHECK(rc == -ETIMEDOUT && strstr(err.msg, "no frame within 0.3 s"));
    /* the release thread names itself once it runs: polled for (held, it cannot end) */
    while (!threads_named("ipsd-arv-close") && now_s() < t0 + 60)
        usleep(10000);
    CHECK(threads_named("ipsd-arv-close") == 1 && threads_named("arv_gv_stream") == 1);
    printf("a frame timed out with its reset held: the capture returned %.3f s after its "
           "timeout\n", late_s);
    /* let go: the next capture waits for that release, then sets up a new stream */
    g_object_set(gv, "gvsp-lost-ratio", 0.0, NULL);
    CHECK(cam_set_timeout(cam, 0, &err) == 0);
    CHECK(write(gate[1], "r", 1) == 1);
    rc = cam_capture(cam, &roi, &f, &err);
    if (rc) fprintf(stderr, "after the reset: %s\n", err.msg);
    CHECK(rc == 0 && frame_is_pattern(&f));
    cam_frame_free(&f);
    CHECK(threads_named("ipsd-arv-close") == 0 && threads_named("arv_gv_stream") == 1);

    /* ---- the camera gone right after its trigger: the capture returns, the release goes on ---- */
    pthread_t vanisher;
    vanish.gv = gv;
    pthread_mutex_lock(&vanish.mu);
    vanish.armed = 1;
    pthread_mutex_unlock(&vanish.mu);
    CHECK(pthread_create(&vanisher, NULL, vanish_run, NULL) == 0);
    CHECK(cam_set_timeout(cam, 0.3, &err) == 0);
    g_object_set(gv, "gvsp-lost-ratio", 1.0, NULL);
    t0 = now_s();
    rc = cam_capture(cam, &roi, &f, &err);
    late_s = now_s() - t0 - 0.3;
    CHECK(rc == -ETIMEDOUT && f.dn == NULL);
    CHECK(pthread_join(vanisher, NULL) == 0); /* the camera is gone before its release runs */
    while (!threads_named("ipsd-arv-close") && now_s() < t0 + 60)
        usleep(10000);
    CHECK(threads_named("ipsd-arv-close") == 1 && threads_named("arv_gv_stream") == 1);
    printf("the camera gone after its trigger: the capture returned %.3f s after its timeout\n",
           late_s);
    CHECK(write(gate[1], "r", 1) == 1);
    double r0 = now_s();
    while ((threads_named("ipsd-arv-close") || threads_named("arv_gv_stream")) && now_s() < r0 + 60)
        usleep(10000);
    CHECK(threads_named("ipsd-arv-close") == 0 && threads_named("arv_gv_stream") == 0);
    printf("its reset (AcquisitionStop, the stream released) took %.2f s in the background\n",
           now_s() - r0);
    double c0 = now_s();
    cam_close(cam); /* at fault: sends nothing, waits for nothing */
    printf("closed in %.3f s\n", now_s() - c0);
    close(gate[0]);
    close(gate[1]);
    CHECK_DONE();
}

/* test_cam_aravis --lost-loop N [--size S]: not a test (ctest does not run it) but the figures of
 * docs/instrument.md ("Stray packets", "Socket buffers", "The reset after a faulty frame"): N
 * times on one camera a good frame, a frame whose packets are all lost (or half of them, with
 * --half), and a good frame again, in an S x S region (9 by default; 256: ~90 packets a frame).
 * Prints how many frames failed and how long the faulty frame's capture took after its timeout
 * (its reset). Run it with busy loops on the cores, and other loopback traffic for the first. */
static int lost_loop(int n, int size, double lost)
{
    err_t err = {{0}};
    cam_t *cam = NULL;
    cam_frame_t f = {0};
    ArvGvFakeCamera *gv = emulator(NULL);
    cam_roi_t roi = size > 9 ? (cam_roi_t){0, 0, size, size} : (cam_roi_t){1000, 1200, 9, 9};
    double timeout_s = size > 9 ? 2 : 0.3, sum_s = 0, max_s = 0;
    int before = 0, faulty = 0, after = 0, timeouts = 0;
    if (cam_open("aravis", DEVICE_ID, &cam, &err) != 0) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    for (int i = 0; i < n; i++) {
        cam_set_timeout(cam, 0, &err);
        if (cam_capture(cam, &roi, &f, &err) || !frame_is_pattern(&f)) {
            printf("run %d, the frame before: %s\n", i, err.msg);
            before++;
        }
        cam_frame_free(&f);
        cam_set_timeout(cam, timeout_s, &err);
        g_object_set(gv, "gvsp-lost-ratio", lost, NULL);
        double t0 = now_s();
        int rc = cam_capture(cam, &roi, &f, &err);
        double late_s = now_s() - t0 - timeout_s;
        if (rc == -ETIMEDOUT) {
            timeouts++;
            sum_s += late_s;
            max_s = late_s > max_s ? late_s : max_s;
        }
        if (!(rc == -ETIMEDOUT || (lost < 1 && rc == -EIO))) {
            printf("run %d, the faulty frame: %d %s\n", i, rc, rc ? err.msg : "");
            faulty++;
        }
        cam_frame_free(&f);
        g_object_set(gv, "gvsp-lost-ratio", 0.0, NULL);
        cam_set_timeout(cam, 0, &err);
        if (cam_capture(cam, &roi, &f, &err) || !frame_is_pattern(&f)) {
            printf("run %d, the frame after: %s\n", i, err.msg);
            after++;
        }
        cam_frame_free(&f);
    }
    printf("%d runs of %dx%d, %.0f %% of the packets lost: %d failed at the frame after, %d at the "
           "frame before, %d faulty frames not an error; a timed-out capture returned %.4f s after "
           "its timeout on average (longest %.4f s)\n",
           n, roi.width, roi.height, lost * 100, after, before, faulty,
           timeouts ? sum_s / timeouts : NAN, max_s);
    cam_close(cam);
    g_object_unref(gv);
    return 0;
}

int main(int argc, char **argv)
{
    if (gige_lock() != 0) return 1; /* another test's emulator would take our commands */
    if (argc > 1 && strcmp(argv[1], "--reset") == 0) return reset_case();
    if (argc > 2 && strcmp(argv[1], "--lost-loop") == 0) {
        int size = 9;
        double lost = 1;
        for (int i = 3; i < argc; i++) {
            if (strcmp(argv[i], "--size") == 0 && i + 1 < argc) size = atoi(argv[++i]);
            if (strcmp(argv[i], "--half") == 0) lost = 0.5;
        }
        return lost_loop(atoi(argv[2]), size < 9 ? 9 : size > 1024 ? 1024 : size, lost);
    }
    double t0 = now_s();
    /* the backend's test gate: a release of a camera closed at fault waits for a byte of it (set
     * before any thread runs: the backend reads it at each close) */
    int gate[2];
    char gate_fd[16];
    CHECK(pipe(gate) == 0);
    snprintf(gate_fd, sizeof gate_fd, "%d", gate[0]);
    setenv("IPSD_ARAVIS_RELEASE_GATE", gate_fd, 1);
    err_t err = {{0}};
    cam_t *cam = NULL;
    cam_info_t info;
    cam_frame_t f = {0}, g = {0};
    ArvGvFakeCamera *gv = emulator(NULL);

    /* ---- found, opened, described ---- */
    CHECK(listed(DEVICE_ID));
    CHECK(cam_open("aravis", "Aravis-Fake-NOSUCH", &cam, &err) == -ENODEV && cam == NULL);
    CHECK(strstr(err.msg, "Aravis-Fake-NOSUCH") != NULL);
    CHECK(cam_open("aravis", DEVICE_ID, &cam, &err) == 0 && cam != NULL);
    if (!cam) {
        fprintf(stderr, "%s\n", err.msg);
        CHECK_DONE();
    }
    CHECK(cam_get_info(cam, &info, &err) == 0);
    CHECK(strcmp(info.backend, "aravis") == 0 && strcmp(info.id, DEVICE_ID) == 0);
    CHECK(strcmp(info.vendor, "Aravis") == 0 && strcmp(info.model, "Fake") == 0);
    CHECK(strcmp(info.serial, SERIAL) == 0);
    CHECK(strcmp(info.firmware, ARAVIS_VERSION) == 0);                  /* its DeviceVersion */
    CHECK(strcmp(info.pixel_format, "Mono16") == 0 && info.bits == 16); /* deeper than Mono8 */
    CHECK(info.full_scale_dn == 65535);
    CHECK(info.width == ARV_FAKE_CAMERA_SENSOR_WIDTH &&
          info.height == ARV_FAKE_CAMERA_SENSOR_HEIGHT);
    CHECK(info.exposure_min_us == 10 && info.exposure_max_us == 1e7); /* its ExposureTimeAbs */
    printf("opened %s: %s %s serial %s firmware %s, %s\n", info.id, info.vendor, info.model,
           info.serial, info.firmware, info.pixel_format);

    /* ---- frames pixel for pixel, exposure, one trigger one frame ---- */
    CHECK(cam_set_exposure(cam, 2500, &err) == 0);
    CHECK(cam_set_exposure(cam, 5, &err) == -ERANGE);
    CHECK(cam_set_gain(cam, 1, &err) == 0);
    CHECK(cam_set_gain(cam, 2, &err) == -ERANGE && strstr(err.msg, "GainRaw"));
    cam_roi_t roi = {1000, 1200, 9, 9};
    int first = cam_capture(cam, &roi, &f, &err);
    if (first) fprintf(stderr, "first capture: %s\n", err.msg); /* what a failure was */
    CHECK(first == 0);
    CHECK(frame_is_pattern(&f));
    CHECK(f.exposure_us == 2500 && atomic_load(&seen_exposure_us) == 2500);
    CHECK(f.gain == 1 && f.timestamp_ns > 0);
    /* the stream reads a UDP socket of its own port, never Aravis's AF_PACKET ring of the whole
     * interface, which it would take here when the process may open one (docs/instrument.md,
     * "Stray packets") */
    CHECK(threads_named("arv_gv_stream") == 1 && packet_sockets_held() == 0);
    printf("stream socket: UDP (%s)\n", may_open_packet_socket()
                                            ? "an AF_PACKET ring was open to this process"
                                            : "this process may not open an AF_PACKET socket");
    CHECK(cam_capture(cam, &roi, &g, &err) == 0 && frame_is_pattern(&g));
    CHECK(g.camera_frame_id == f.camera_frame_id + 1); /* nothing in between: one per trigger */
    cam_frame_free(&g);
    cam_roi_t inner = {1002, 1203, 3, 3}; /* inside the region set: cut out of it */
    CHECK(cam_capture(cam, &inner, &g, &err) == 0 && frame_is_pattern(&g));
    CHECK(g.roi.col == 1002 && g.roi.row == 1203 && g.roi.width == 3);
    cam_frame_free(&g);
    cam_roi_t outside = {2040, 0, 9, 9};
    CHECK(cam_capture(cam, &outside, &g, &err) == -EINVAL);
    cam_roi_t corner = {2039, 2039, 9, 9}; /* a new region, at the sensor's far corner */
    CHECK(cam_capture(cam, &corner, &g, &err) == 0 && frame_is_pattern(&g));
    cam_frame_free(&g);
    cam_frame_free(&f);

    printf("frames: %.2f s\n", now_s() - t0);
    /* ---- a frame that does not come (every packet lost): -ETIMEDOUT, then good frames ---- */
    CHECK(cam_set_timeout(cam, 0.3, &err) == 0);
    g_object_set(gv, "gvsp-lost-ratio", 1.0, NULL);
    double l0 = now_s();
    CHECK(cam_capture(cam, &roi, &f, &err) == -ETIMEDOUT && f.dn == NULL);
    printf("a frame lost: the capture returned %.3f s after its timeout (with its reset)\n",
           now_s() - l0 - 0.3);
    CHECK(strstr(err.msg, DEVICE_ID) && strstr(err.msg, "no frame within 0.3 s"));
    g_object_set(gv, "gvsp-lost-ratio", 0.0, NULL);
    CHECK(cam_set_timeout(cam, 0, &err) == 0);
    int rc = cam_capture(cam, &roi, &f, &err);
    if (rc) fprintf(stderr, "after the frame lost: %s\n", err.msg); /* what a failure was */
    CHECK(rc == 0 && frame_is_pattern(&f));
    cam_frame_free(&f);

    /* ---- a frame of another size than the region set: size mismatch ---- */
    ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera(gv);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, 8);
    CHECK(cam_capture(cam, &roi, &f, &err) == -EIO && strstr(err.msg, "size mismatch"));
    printf("size mismatch: %s\n", err.msg);
    CHECK(cam_capture(cam, &roi, &f, &err) == 0 && frame_is_pattern(&f)); /* region set anew */
    cam_frame_free(&f);

    /* ---- packets lost on the way: an incomplete frame is an error ---- */
    cam_roi_t big = {0, 0, 256, 256}; /* 128 KiB: ~90 packets */
    CHECK(cam_set_timeout(cam, 2, &err) == 0);
    g_object_set(gv, "gvsp-lost-ratio", 0.5, NULL);
    rc = cam_capture(cam, &big, &f, &err);
    CHECK((rc == -EIO || rc == -ETIMEDOUT) && f.dn == NULL);
    printf("packets lost: %s\n", err.msg);
    g_object_set(gv, "gvsp-lost-ratio", 0.0, NULL);
    CHECK(cam_capture(cam, &big, &f, &err) == 0 && frame_is_pattern(&f));
    cam_frame_free(&f);
    CHECK(cam_capture(cam, &roi, &f, &err) == 0 && frame_is_pattern(&f)); /* its region again */
    cam_frame_free(&f);

    printf("faults: %.2f s\n", now_s() - t0);
    /* ---- the camera goes away: an error in Aravis's words, never a hang; then back ---- */
    g_object_unref(gv);
    rc = cam_capture(cam, &roi, &f, &err);
    CHECK((rc == -EIO || rc == -ETIMEDOUT) && strstr(err.msg, DEVICE_ID));
    printf("camera gone: %s\n", err.msg);
    printf("gone: %.2f s\n", now_s() - t0);
    /* closed: the release held at the gate, close returns; Aravis's stream thread still runs */
    CHECK(threads_named("arv_gv_stream") == 1 && threads_named("ipsd-arv-close") == 0);
    double c0 = now_s();
    cam_close(cam);
    double close_s = now_s() - c0;
    CHECK(threads_named("arv_gv_stream") == 1); /* the stream not released: nothing sent */
    /* the release thread names itself once it runs: polled for (held, it cannot end) */
    while (!threads_named("ipsd-arv-close") && now_s() < c0 + 60)
        usleep(10000);
    CHECK(threads_named("ipsd-arv-close") == 1 && threads_named("arv_gv_stream") == 1);
    CHECK(close_s < 8); /* a safety net only: the gate is what shows it (Aravis's: 10 s) */
    printf("closed the camera gone in %.3f s\n", close_s);
    /* let go: the release ends by itself (Aravis's commands time out) and no thread stays */
    CHECK(write(gate[1], "r", 1) == 1);
    double r0 = now_s();
    while ((threads_named("ipsd-arv-close") || threads_named("arv_gv_stream")) && now_s() < r0 + 60)
        usleep(10000);
    CHECK(threads_named("ipsd-arv-close") == 0 && threads_named("arv_gv_stream") == 0);
    printf("released in the background in %.2f s\n", now_s() - r0);
    gv = emulator(NULL);
    CHECK(cam_open("aravis", DEVICE_ID, &cam, &err) == 0);
    rc = cam ? cam_capture(cam, &roi, &f, &err) : -1;
    if (rc) fprintf(stderr, "back: %s\n", err.msg);
    CHECK(rc == 0 && frame_is_pattern(&f));
    cam_frame_free(&f);
    /* gone again, unnoticed (no command failed yet): close waits for its release a bounded time
     * (its AcquisitionStop alone is Aravis's 2.5 s), the next open of the camera for all of it */
    g_object_unref(gv);
    c0 = now_s();
    cam_close(cam);
    close_s = now_s() - c0;
    CHECK(close_s < 8); /* a safety net only (Aravis's: 12.5 s) */
    printf("closed the camera gone unnoticed in %.3f s\n", close_s);

    /* ---- a camera without a monochrome format: refused, naming PixelFormat ---- */
    char xml[] = "/tmp/ipsd-arv-XXXXXX";
    int fd = mkstemp(xml);
    CHECK(fd >= 0 && close(fd) == 0 && xml_without_mono(xml) == 0);
    gv = emulator(xml);
    CHECK(cam_open("aravis", DEVICE_ID, &cam, &err) == -ENOTSUP && cam == NULL);
    CHECK(strstr(err.msg, "PixelFormat") && strstr(err.msg, "RGB8") &&
          !strstr(err.msg, "offers Mono"));
    printf("refused: %s\n", err.msg);
    g_object_unref(gv);
    unlink(xml);
    close(gate[0]);
    close(gate[1]);
    CHECK_DONE();
}
