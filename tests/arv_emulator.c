/* arv_emulator.c: Aravis's own GigE Vision camera emulator (ArvGvFakeCamera) on 127.0.0.1, run
 * as a process for the tests that drive ipsd through --bench aravis:ID
 * (tests/test_server_aravis.py). It speaks the real protocol (GVCP control, GVSP streaming, the
 * GenICam XML); this program only chooses what its frames hold and when it is there:
 *
 *   arv_emulator SERIAL                 the emulator's own pattern (Aravis's diagonal ramp)
 *   arv_emulator SERIAL --scene SCENE --gcs-log FILE [--axes A,B,C]
 *       each frame is the simulated bench's (instrument/sim.h, the paper's sensor and optics on
 *       SCENE, as ipsd's --bench sim) for the position of the stage at that moment: the last MOV
 *       the emulated PI controller (tests/gcs_emulator.py --verbose) logged to FILE, in mm, for
 *       axes A, B, C (x, y, z; default 1,2,3). ipsd triggers a frame only after its move is on
 *       target, and the controller logs a command before it answers it, so the log holds the
 *       move of the frame when the frame is drawn. The region, exposure and gain are the
 *       camera's registers as ipsd set them (GainRaw 0: the analogue gain 1).
 *
 * Commands on stdin, one a line: "stop" (the camera goes away: its sockets close, as a camera
 * switched off), "start" (it is back, same serial). Answers on stdout: "ready DEVICE-ID" after
 * each start, "stopped" after a stop. The program exits when stdin reaches end of file, so it
 * never outlives the test that runs it. */
#include <arv.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/cam.h"
#include "instrument/sim.h"

static struct {
    const char *serial, *scene, *gcs_log;
    char axes[3][16];
    sim_t *sim;
    pthread_mutex_t mu;
    FILE *log;
    char pending[4096]; /* a log line read in part */
    double pos_um[3];   /* the last move logged */
} E = {.axes = {"1", "2", "3"}, .mu = PTHREAD_MUTEX_INITIALIZER};

/* Reads the log's new lines; the last MOV's axes set pos_um (mm in the log). */
static void follow_log(void)
{
    if (!E.log && !(E.log = fopen(E.gcs_log, "r"))) return;
    char buf[4096];
    clearerr(E.log);
    while (fgets(buf, sizeof buf, E.log)) {
        size_t have = strlen(E.pending);
        snprintf(E.pending + have, sizeof E.pending - have, "%s", buf);
        if (!strchr(buf, '\n')) continue; /* the rest of the line is not written yet */
        char *mov = strstr(E.pending, "'MOV ");
        if (mov) {
            char *save = NULL, *tok = strtok_r(mov + 5, " '\n", &save);
            while (tok) {
                char *val = strtok_r(NULL, " '\n", &save);
                if (!val) break;
                for (int a = 0; a < 3; a++)
                    if (strcmp(tok, E.axes[a]) == 0) E.pos_um[a] = atof(val) * 1000;
                tok = strtok_r(NULL, " '\n", &save);
            }
        }
        E.pending[0] = 0;
    }
}

/* The simulated bench's frame of the buffer's region at the stage's position. */
static void fill_scene(ArvBuffer *buffer, void *data, guint32 exposure_us, guint32 gain,
                       ArvPixelFormat format)
{
    (void)data;
    gint x0, y0, w, h;
    arv_buffer_get_image_region(buffer, &x0, &y0, &w, &h);
    uint8_t *p = (uint8_t *)arv_buffer_get_data(buffer, NULL); /* allocated for the region */
    int bytes = format == ARV_PIXEL_FORMAT_MONO_16 ? 2 : 1;
    memset(p, 0, (size_t)w * h * bytes);
    pthread_mutex_lock(&E.mu);
    follow_log();
    stage_pos_t at = {E.pos_um[0], E.pos_um[1], E.pos_um[2]};
    cam_t *cam = sim_camera(E.sim);
    cam_info_t info;
    err_t err;
    cam_frame_t f;
    cam_roi_t roi = {x0, y0, w, h};
    int ok = stage_move(sim_stage(E.sim), &at, &err) == 0 && cam_get_info(cam, &info, &err) == 0 &&
             x0 + w <= info.width && y0 + h <= info.height &&
             cam_set_exposure(cam, exposure_us, &err) == 0 &&
             cam_set_gain(cam, 1 + gain, &err) == 0 && cam_capture(cam, &roi, &f, &err) == 0;
    if (!ok) fprintf(stderr, "arv_emulator: no frame of the bench: %s\n", err.msg);
    for (int i = 0; ok && i < w * h; i++) {
        p[bytes * i] = (uint8_t)(bytes == 2 ? f.dn[i] & 0xff : f.dn[i] > 255 ? 255 : f.dn[i]);
        if (bytes == 2) p[2 * i + 1] = (uint8_t)(f.dn[i] >> 8); /* little-endian, as GVSP */
    }
    if (ok) cam_frame_free(&f);
    pthread_mutex_unlock(&E.mu);
}

static ArvGvFakeCamera *start(void)
{
    ArvGvFakeCamera *gv = arv_gv_fake_camera_new("127.0.0.1", E.serial);
    if (!arv_gv_fake_camera_is_running(gv)) {
        fprintf(stderr, "arv_emulator: the GigE Vision emulator does not run on 127.0.0.1 "
                        "(port 3956 in use?)\n");
        exit(1);
    }
    ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera(gv);
    arv_fake_camera_set_trigger_frequency(fake, 1000); /* a software trigger seen within 1 ms */
    if (E.sim) arv_fake_camera_set_fill_pattern(fake, fill_scene, NULL);
    printf("ready Aravis-Fake-%s\n", E.serial);
    fflush(stdout);
    return gv;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: arv_emulator SERIAL [--scene SCENE --gcs-log FILE [--axes "
                        "A,B,C]]\n");
        return 2;
    }
    E.serial = argv[1];
    for (int i = 2; i + 1 < argc; i += 2) {
        if (strcmp(argv[i], "--scene") == 0)
            E.scene = argv[i + 1];
        else if (strcmp(argv[i], "--gcs-log") == 0)
            E.gcs_log = argv[i + 1];
        else if (strcmp(argv[i], "--axes") == 0)
            sscanf(argv[i + 1], "%15[^,],%15[^,],%15s", E.axes[0], E.axes[1], E.axes[2]);
        else {
            fprintf(stderr, "arv_emulator: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (E.scene) {
        err_t err;
        sim_config_t c = sim_config_default();
        c.scene = E.scene;
        if (!E.gcs_log || sim_open(&c, &E.sim, &err)) {
            fprintf(stderr, "arv_emulator: --scene needs --gcs-log and a scene: %s\n",
                    E.gcs_log ? err.msg : "no --gcs-log");
            return 2;
        }
    }
    ArvGvFakeCamera *gv = start();
    char line[64];
    while (fgets(line, sizeof line, stdin)) {
        if (strncmp(line, "stop", 4) == 0 && gv) {
            g_object_unref(gv);
            gv = NULL;
            printf("stopped\n");
            fflush(stdout);
        } else if (strncmp(line, "start", 5) == 0 && !gv) {
            gv = start();
        }
    }
    if (gv) g_object_unref(gv);
    sim_close(E.sim);
    return 0;
}
