/* test_stage_zaber.c: the Zaber ASCII stage backend (instrument/stage_zaber.c) through the stage
 * interface (stage.h), against the emulated Zaber devices of tests/zaber_emulator.py (written
 * from Zaber's published ASCII protocol descriptions), over TCP loopback and over a
 * pseudo-terminal: opening (homing axes without a reference position, limits from limit.min /
 * limit.max, identity), moves read back with get pos in microsteps of step_um, a daisy chain of
 * single-axis devices, the travel limits, rejections with their reasons (BADDATA, BADCOMMAND,
 * BADAXIS), warning flags ending a move (FS stalled, NI interrupted, WL limit switch), alerts and
 * info messages between replies, a connection dropped mid-move (an error, then a reconnection),
 * devices that stop answering (a timeout, never a hang), the follower, and the stage strings.
 * Expected values are the emulator's configuration (travel in microsteps, the commanded
 * positions on the microstep grid), not the backend's. The emulator exits when its stdin closes;
 * nothing waits on a clock but the one silent-device case (its reply timeout, twice). */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "instrument/stage.h"

#ifndef IPSD_ZABER_EMULATOR /* set by tests/instrument.cmake */
#define IPSD_ZABER_EMULATOR "zaber_emulator.py"
#endif
#include "stage_emu.h"

/* Opens the stage on a new emulator (step_um=0.1 unless url_opts says otherwise). */
static stage_t *open_on(emu_t *e, const char *const *emu_opts, const char *url_opts, int *ret,
                        err_t *err)
{
    stage_t *st = NULL;
    if (emu_start_script(e, IPSD_ZABER_EMULATOR, emu_opts)) {
        CHECK(!"the emulator starts");
        *ret = -1;
        return NULL;
    }
    char url[512], opts[256];
    snprintf(opts, sizeof opts, "%s%s%s", strstr(url_opts, "step_um=") ? "" : "step_um=0.1",
             *url_opts && !strstr(url_opts, "step_um=") ? "&" : "", url_opts);
    emu_url(e, "zaber", opts, url, sizeof url);
    *ret = stage_open_url(url, &st, err);
    if (*ret) fprintf(stderr, "  open %s: %d %s\n", url, *ret, err->msg);
    return st;
}

/* |got - want| within half a microstep: positions are whole microsteps. */
#define CHECK_STEP(got, want, step) CHECK(fabs((got) - (want)) <= (step) / 2 + 1e-9)

/* Homing at opening, moves, read-back, limits, homing; chatty devices (alerts, info lines). */
static void test_basic(const char *transport)
{
    emu_t e;
    err_t err;
    int ret;
    const char *opts[] = {transport, "--unhomed", "--chatty", NULL};
    stage_t *st = open_on(&e, opts, "", &ret, &err);
    CHECK(ret == 0);
    if (!st) return emu_stop(&e);
    CHECK(strcmp(stage_backend(st), "zaber") == 0);
    CHECK(strstr(stage_identity(st), "device 1: deviceid 30222, version 7.38") != NULL);
    stage_limits_t lim; /* the emulator's travel: -250000..250000 microsteps of 0.1 um */
    CHECK(stage_get_limits(st, &lim, NULL) == 0);
    CHECK(lim.min.x_um == -25000 && lim.max.x_um == 25000 && lim.min.z_um == -25000 &&
          lim.max.z_um == 25000);
    stage_pos_t p, t = {1234.5, -20.25, 3.0};
    CHECK(stage_get_position(st, &p, NULL) == 0 && p.x_um == 0 && p.y_um == 0); /* homed */
    CHECK(stage_move(st, &t, &err) == 0);
    CHECK(stage_get_position(st, &p, NULL) == 0);
    CHECK_STEP(p.x_um, 1234.5, 0.1);
    CHECK_STEP(p.y_um, -20.25, 0.1);
    CHECK_STEP(p.z_um, 3.0, 0.1);
    stage_pos_t ends = {-25000, 25000, 24999.9}; /* the travel's ends */
    CHECK(stage_move(st, &ends, &err) == 0 && stage_get_position(st, &p, NULL) == 0);
    CHECK(p.x_um == -25000 && p.y_um == 25000);
    CHECK_STEP(p.z_um, 24999.9, 0.1);
    stage_pos_t far = {0, 25000.1, 0};
    CHECK(stage_move(st, &far, &err) == -ERANGE && strstr(err.msg, "y ="));
    CHECK(stage_get_position(st, &p, NULL) == 0 && p.y_um == 25000); /* did not move */
    CHECK(stage_home(st, NULL) == 0 && stage_get_position(st, &p, NULL) == 0);
    CHECK(p.x_um == 0 && p.y_um == 0 && p.z_um == 0);
    stage_close(st);
    emu_stop(&e);
}

/* Two single-axis devices in a daisy chain (devices=1,2&axes=1,1): z stays 0; another step
 * size; an axis a device does not have; no reference position with reference=0. */
static void test_chain_axes(void)
{
    emu_t e;
    err_t err;
    int ret;
    const char *opts[] = {"--tcp=0", "--device", "1:1", "--device", "2:1", NULL};
    stage_t *st = open_on(&e, opts, "step_um=0.047625&devices=1,2&axes=1,1", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        CHECK(strstr(stage_identity(st), "device 1:") && strstr(stage_identity(st), "device 2:"));
        stage_limits_t lim;
        CHECK(stage_get_limits(st, &lim, NULL) == 0);
        CHECK_NEAR(lim.max.x_um, 250000 * 0.047625, 0, 1e-9);
        CHECK(lim.min.z_um == 0 && lim.max.z_um == 0);
        stage_pos_t p, t = {100.0, -55.5, 0};
        CHECK(stage_move(st, &t, &err) == 0 && stage_get_position(st, &p, NULL) == 0);
        CHECK_STEP(p.x_um, 100.0, 0.047625);
        CHECK_STEP(p.y_um, -55.5, 0.047625);
        CHECK(p.z_um == 0);
        t.z_um = 1;
        CHECK(stage_move(st, &t, &err) == -ERANGE && strstr(err.msg, "z ="));
        stage_close(st);
    }
    emu_stop(&e);
    const char *opts2[] = {"--tcp=0", NULL}; /* device 1 has axes 1..3 */
    st = open_on(&e, opts2, "axes=1,2,4", &ret, &err);
    CHECK(ret == -EINVAL && strstr(err.msg, "axis 4") && strstr(err.msg, "BADAXIS"));
    stage_close(st);
    emu_stop(&e);
    const char *opts3[] = {"--tcp=0", "--unhomed", NULL};
    st = open_on(&e, opts3, "reference=0", &ret, &err);
    CHECK(ret == -EPERM && strstr(err.msg, "reference"));
    stage_close(st);
    emu_stop(&e);
}

/* Rejections and warning flags: the reason or flag reaches the caller; the stage stays usable. */
static void test_device_errors(const char *transport)
{
    emu_t e;
    err_t err;
    int ret;
    /* "move abs" commands: move 1 sends 2 (y's rejected), moves 2-5 three each, move 6 two (y's
     * rejected); axis moves (n_mov): move 1 x = 1, move 2 = 2..4, move 3 = 5..7 (y, 6, stalls),
     * move 4 = 8..10 (y, 9, interrupted), move 5 = 11..13 (z, 13, hits a limit switch) */
    const char *opts[] = {
        transport, "--reject", "move abs:2:BADDATA", "--reject", "move abs:16:BADCOMMAND",
        "--stall", "6",        "--interrupt",        "9",        "--limit-hit",
        "13",      NULL};
    stage_t *st = open_on(&e, opts, "", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        stage_pos_t a = {10, 20, 30}, b = {-500, 1000, 2}, p;
        CHECK(stage_move(st, &a, &err) == -ERANGE && strstr(err.msg, "BADDATA") &&
              strstr(err.msg, "axis 2") && strstr(err.msg, "move abs 200"));
        CHECK(stage_move(st, &a, &err) == 0 && stage_get_position(st, &p, NULL) == 0);
        CHECK(p.x_um == 10 && p.y_um == 20 && p.z_um == 30);
        CHECK(stage_move(st, &b, &err) == -EIO && strstr(err.msg, "FS") &&
              strstr(err.msg, "stalled") && strstr(err.msg, "axis 2"));
        CHECK(stage_get_position(st, &p, NULL) == 0);
        CHECK(p.x_um == -500 && p.y_um == 510); /* y stopped halfway from 20 to 1000 */
        CHECK(stage_move(st, &a, &err) == -EIO && strstr(err.msg, "NI") &&
              strstr(err.msg, "interrupted"));
        CHECK(stage_move(st, &b, &err) == -EIO && strstr(err.msg, "WL") &&
              strstr(err.msg, "limit switch") && strstr(err.msg, "axis 3"));
        CHECK(stage_move(st, &a, &err) == -EIO && strstr(err.msg, "BADCOMMAND"));
        CHECK(stage_move(st, &b, &err) == 0 && stage_get_position(st, &p, NULL) == 0);
        CHECK(p.x_um == -500 && p.y_um == 1000 && p.z_um == 2);
        stage_close(st);
    }
    emu_stop(&e);
}

/* Stage strings of the zaber family: the syntax, and errors that say what is wrong. */
static void test_urls(void)
{
    err_t err;
    int sim = -1;
    CHECK(stage_url_check("zaber:tcp://zaber-stage.example:55550?step_um=0.047625", &sim, NULL) ==
              0 &&
          sim == 0);
    CHECK(stage_url_check("zaber:serial:/dev/ttyUSB0?baud=115200&step_um=0.1&device=2&axes=1,2",
                          NULL, NULL) == 0);
    CHECK(stage_url_check("zaber:serial:/dev/ttyUSB0?step_um=0.1&devices=1,2,3&axes=1,1,1", NULL,
                          NULL) == 0);
    static const emu_bad_url_t bad[] = {
        {"zaber:tcp://h:1", "step_um="},
        {"zaber:udp://h:1?step_um=1", "zaber:tcp://HOST:PORT"},
        {"zaber:tcp://h?step_um=1", "zaber:tcp://HOST:PORT"},
        {"zaber:serial:ttyUSB0?step_um=1", "absolute"},
        {"zaber:tcp://h:1?step_um=0", "step_um="},
        {"zaber:tcp://h:1?step_um=nan", "step_um="},
        {"zaber:tcp://h:1?step_um=1&unit=mm", "unit= is for gcs"},
        {"zaber:tcp://h:1?step_um=1&axes=A,B", "axis numbers 1..9"},
        {"zaber:tcp://h:1?step_um=1&axes=1,10", "axis numbers 1..9"},
        {"zaber:tcp://h:1?step_um=1&axes=2,2", "repeats"},
        {"zaber:tcp://h:1?step_um=1&devices=1,1&axes=1,1", "repeats"},
        {"zaber:tcp://h:1?step_um=1&device=0", "device="},
        {"zaber:tcp://h:1?step_um=1&device=100", "device="},
        {"zaber:tcp://h:1?step_um=1&devices=1", "devices="},
        {"zaber:tcp://h:1?step_um=1&devices=1,2", "2 devices for 3 axes"},
        {"zaber:tcp://h:1?step_um=1&devices=1,x,3", "devices="},
        {"zaber:tcp://h:1?step_um=1&speed=3", "unknown option 'speed' (step_um"},
        {"zaber:tcp://h:1?step_um=1&baud=9600", "serial lines only"},
    };
    emu_check_bad_urls(bad, sizeof bad / sizeof bad[0]);
    stage_t *st;
    CHECK(stage_open_url("zaber:serial:/dev/nonexistent-ipsd-stage?step_um=1", &st, &err) ==
          -ENOENT);
    CHECK(stage_open("zaber", "tcp://h:1", &st, &err) == -EINVAL && strstr(err.msg, "step_um"));
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    test_urls();
    test_basic("--tcp=0");
    test_basic("--pty");
    test_chain_axes();
    test_device_errors("--tcp=0");
    test_device_errors("--pty");
    emu_test_follow(open_on, "step_um=0.047625", "30222", 250000 * 0.047625, 0.047625 / 2 + 1e-9,
                    0.047625);
    emu_test_faults(open_on, "4", 0); /* tests/stage_emu.h */
    CHECK_DONE();
}
