/* test_stage_gcs.c: the GCS 2.0 stage backend (instrument/stage_gcs.c) through the stage
 * interface (stage.h), against the emulated PI controller of tests/gcs_emulator.py (written from
 * PI's GCS 2.0 command descriptions), over TCP loopback and over a pseudo-terminal: opening
 * (servo on, referencing, limits from TMN?/TMX?), moves read back with POS?, both units, the
 * travel limits, controller errors with their GCS codes (5 servo off, 7 out of limits, 10 stopped),
 * a connection dropped mid-move (an error, then a reconnection), a controller that stops
 * answering (a timeout, never a hang), the follower (the simulated bench's stage following the
 * reported position), and the stage strings' syntax. Expected values are the
 * emulator's configuration (travel in mm, positions commanded), not the backend's.
 * The emulator exits when its stdin closes: no test leaves it running, nothing waits on a clock
 * but the one hung-controller case, which waits its reply timeout twice (1.5 s: long
 * enough that a busy machine never makes the emulator miss it before it falls silent). */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "instrument/stage.h"

#ifndef IPSD_GCS_EMULATOR /* set by tests/instrument.cmake */
#define IPSD_GCS_EMULATOR "gcs_emulator.py"
#endif
#include "stage_emu.h"

static int emu_start(emu_t *e, const char *const *opts)
{
    return emu_start_script(e, IPSD_GCS_EMULATOR, opts);
}

static void url_of(const emu_t *e, const char *opts, char *url, size_t n)
{
    emu_url(e, "gcs", opts, url, n);
}

/* Opens the stage on a new emulator. */
static stage_t *open_on(emu_t *e, const char *const *emu_opts, const char *url_opts, int *ret,
                        err_t *err)
{
    stage_t *st = NULL;
    if (emu_start(e, emu_opts)) {
        CHECK(!"the emulator starts");
        *ret = -1;
        return NULL;
    }
    char url[512];
    url_of(e, url_opts, url, sizeof url);
    *ret = stage_open_url(url, &st, err);
    return st;
}

/* Moves, read-back, limits, homing on a stage that starts servo off and unreferenced. */
static void test_basic(const char *transport)
{
    emu_t e;
    err_t err;
    int ret;
    const char *opts[] = {transport, "--servo-off", "--unreferenced", NULL};
    stage_t *st = open_on(&e, opts, "", &ret, &err);
    CHECK(ret == 0);
    if (ret) fprintf(stderr, "open: %s\n", err.msg);
    if (!st) return emu_stop(&e);
    CHECK(strcmp(stage_backend(st), "gcs") == 0 && strstr(stage_identity(st), "emulator"));
    stage_limits_t lim; /* the emulator's travel: -25..25 mm on every axis */
    CHECK(stage_get_limits(st, &lim, NULL) == 0);
    CHECK(lim.min.x_um == -25000 && lim.max.x_um == 25000 && lim.min.z_um == -25000 &&
          lim.max.z_um == 25000);
    stage_pos_t p, t = {1234.5, -20.25, 3.0};
    CHECK(stage_get_position(st, &p, NULL) == 0 && p.x_um == 0 && p.y_um == 0); /* referenced */
    CHECK(stage_move(st, &t, &err) == 0);
    CHECK(stage_get_position(st, &p, NULL) == 0);
    /* POS? has 7 decimals of mm: 0.1 nm */
    CHECK_NEAR(p.x_um, t.x_um, 0, 1e-4);
    CHECK_NEAR(p.y_um, t.y_um, 0, 1e-4);
    CHECK_NEAR(p.z_um, t.z_um, 0, 1e-4);
    stage_pos_t sub = {0.0123, 24999.9999, -24999.9999}; /* a sub-nm step, the travel's ends */
    CHECK(stage_move(st, &sub, NULL) == 0 && stage_get_position(st, &p, NULL) == 0);
    CHECK_NEAR(p.x_um, 0.0123, 0, 1e-4);
    CHECK_NEAR(p.y_um, 24999.9999, 0, 1e-4);
    stage_pos_t far = {0, 25000.5, 0};
    CHECK(stage_move(st, &far, &err) == -ERANGE && strstr(err.msg, "y ="));
    CHECK(stage_get_position(st, &p, NULL) == 0);
    CHECK_NEAR(p.y_um, 24999.9999, 0, 1e-4); /* did not move */
    CHECK(stage_home(st, NULL) == 0 && stage_get_position(st, &p, NULL) == 0);
    CHECK(p.x_um == 0 && p.y_um == 0 && p.z_um == 0);
    stage_close(st);
    emu_stop(&e);
}

/* unit=um: a piezo stage of 100 um travel; two axes: z stays 0. */
static void test_units_axes(void)
{
    emu_t e;
    err_t err;
    int ret;
    const char *opts[] = {"--tcp", "0", "--axes", "A,B", "--travel", "0:100", NULL};
    stage_t *st = open_on(&e, opts, "unit=um&axes=A,B", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        stage_limits_t lim;
        CHECK(stage_get_limits(st, &lim, NULL) == 0);
        CHECK(lim.min.x_um == 0 && lim.max.y_um == 100 && lim.min.z_um == 0 && lim.max.z_um == 0);
        stage_pos_t p, t = {12.5, 99.75, 0};
        CHECK(stage_move(st, &t, NULL) == 0 && stage_get_position(st, &p, NULL) == 0);
        CHECK_NEAR(p.x_um, 12.5, 0, 1e-7);
        CHECK_NEAR(p.y_um, 99.75, 0, 1e-7);
        CHECK(p.z_um == 0);
        t.z_um = 1;
        CHECK(stage_move(st, &t, &err) == -ERANGE && strstr(err.msg, "z ="));
        stage_close(st);
    }
    emu_stop(&e);
    /* an axis the controller does not have: named at opening */
    const char *opts3[] = {"--tcp", "0", NULL};
    st = open_on(&e, opts3, "axes=1,2,9", &ret, &err);
    CHECK(ret == -EINVAL && strstr(err.msg, "axis 9") && strstr(err.msg, "SAI?"));
    stage_close(st);
    emu_stop(&e);
    /* unreferenced and reference=0: refused at opening */
    const char *opts4[] = {"--tcp", "0", "--unreferenced", NULL};
    st = open_on(&e, opts4, "reference=0", &ret, &err);
    CHECK(ret == -EPERM && strstr(err.msg, "referenced"));
    stage_close(st);
    emu_stop(&e);
}

/* Controller errors: the GCS code and its text reach the caller. */
static void test_controller_errors(const char *transport)
{
    emu_t e;
    err_t err;
    int ret;
    /* MOV #2 refused with 7 (the controller's own limit), MOV #3 stopped (10); after MOV #4 the
     * servo trips, so MOV #5 is refused with 5 */
    const char *opts[] = {transport,  "--fail",       "MOV:2:7", "--fail",
                          "MOV:3:10", "--servo-trip", "2",       NULL};
    stage_t *st = open_on(&e, opts, "", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        stage_pos_t a = {10, 20, 0}, b = {30, 40, 0}, p;
        CHECK(stage_move(st, &a, &err) == 0);
        CHECK(stage_move(st, &b, &err) == -ERANGE && strstr(err.msg, "error 7") &&
              strstr(err.msg, "MOV") && strstr(err.msg, "position out of limits"));
        CHECK(stage_move(st, &b, &err) == -EIO && strstr(err.msg, "error 10") &&
              strstr(err.msg, "stopped"));
        CHECK(stage_get_position(st, &p, NULL) == 0 && p.x_um == 10 && p.y_um == 20);
        CHECK(stage_move(st, &b, &err) == 0); /* MOV #4 (the emulator's 2nd executed): trips */
        CHECK(stage_move(st, &a, &err) == -EPERM && strstr(err.msg, "error 5") &&
              strstr(err.msg, "servo off"));
        CHECK(stage_get_position(st, &p, NULL) == 0);
        CHECK_NEAR(p.x_um, 30, 0, 1e-4);
        stage_close(st);
    }
    emu_stop(&e);
}

/* Stage strings: the syntax, and errors that say what is wrong. */
static void test_urls(void)
{
    err_t err;
    int sim = -1;
    CHECK(stage_url_check("sim", &sim, NULL) == 0 && sim == 1);
    CHECK(stage_url_check("gcs:tcp://lab-stage.example:50000", &sim, NULL) == 0 && sim == 0);
    CHECK(stage_url_check("gcs:tcp://[::1]:50000?unit=um&axes=X,Y,Z&timeout=0.5", NULL, NULL) == 0);
    CHECK(stage_url_check("gcs:serial:/dev/ttyUSB0?baud=115200&move_timeout=120&reference=0", NULL,
                          NULL) == 0);
    static const emu_bad_url_t bad[] = {
        {"pi:tcp://h:1", "need sim, or gcs:"},
        {"gcs:udp://h:1", "gcs:tcp://HOST:PORT"},
        {"gcs:tcp://h", "port"},
        {"gcs:tcp://h:0", "port"},
        {"gcs:tcp://h:70000", "port"},
        {"gcs:tcp://:50000", "port"},
        {"gcs:serial:ttyUSB0", "absolute"},
        {"gcs:tcp://h:1?unit=nm", "unit="},
        {"gcs:tcp://h:1?baud=9600", "serial lines only"},
        {"gcs:serial:/dev/ttyS0?baud=1234", "baud="},
        {"gcs:tcp://h:1?axes=1", "axes="},
        {"gcs:tcp://h:1?axes=1,2,3,4", "axes="},
        {"gcs:tcp://h:1?axes=1,1", "repeats"},
        {"gcs:tcp://h:1?axes=1,a b", "axes="},
        {"gcs:tcp://h:1?timeout=0", "timeout="},
        {"gcs:tcp://h:1?timeout=abc", "timeout="},
        {"gcs:tcp://h:1?poll_ms=-1", "poll_ms="},
        {"gcs:tcp://h:1?reference=yes", "reference="},
        {"gcs:tcp://h:1?speed=3", "unknown option 'speed'"},
        {"gcs:tcp://h:1?step_um=0.1", "for zaber"},
        {"gcs:tcp://h:1?unit", "key=value"},
        /* a host the resolver would have been asked for, a port with a space, a repeated key */
        {"gcs:tcp://[::1", "[IPv6]"},
        {"gcs:tcp://[::1]x:1", "[IPv6]"},
        {"gcs:tcp://::1:50000", "[IPv6]"},
        {"gcs:tcp://ho st:1", "host name"},
        {"gcs:tcp://127.0.0.1: 80", "port 1..65535"},
        {"gcs:tcp://127.0.0.1:+80", "port 1..65535"},
        {"gcs:tcp://h:1?unit=mm&unit=um", "unit= is given twice"},
        {"gcs:tcp://h:1?timeout=1&axes=1,2&timeout=2", "timeout= is given twice"},
    };
    emu_check_bad_urls(bad, sizeof bad / sizeof bad[0]);
    /* the one-line error escapes the string's control characters and other bytes */
    CHECK(stage_url_check("gcs:tcp://h\n:1\x1b[2J", NULL, &err) == -EINVAL);
    int controls = 0;
    for (const char *p = err.msg; *p; p++)
        controls += (unsigned char)*p < 0x20 || (unsigned char)*p >= 0x7f;
    CHECK(controls == 0 && strstr(err.msg, "h\\x0a:1\\x1b[2J"));
    CHECK(stage_url_check("gcs:tcp://h:1?sp\xff" "eed\r=1", NULL, &err) == -EINVAL &&
          !strchr(err.msg, '\r') && strstr(err.msg, "sp\\xffeed\\x0d"));
    CHECK(stage_url_check("gcs:tcp://[fe80::1%2]:50000", NULL, NULL) == 0);
    /* nobody listening: refused at once; a device that does not exist */
    stage_t *st;
    emu_t e;
    const char *opts[] = {"--tcp", "0", NULL};
    char url[512];
    CHECK(emu_start(&e, opts) == 0);
    url_of(&e, "", url, sizeof url);
    emu_stop(&e); /* its port is closed now */
    CHECK(stage_open_url(url, &st, &err) == -ECONNREFUSED && strstr(err.msg, "refused"));
    CHECK(stage_open_url("gcs:serial:/dev/nonexistent-ipsd-stage", &st, &err) == -ENOENT);
    CHECK(stage_open("gcs", "tcp://h", &st, &err) == -EINVAL);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    test_urls();
    test_basic("--tcp=0");
    test_basic("--pty");
    test_units_axes();
    test_controller_errors("--tcp=0");
    test_controller_errors("--pty");
    emu_test_follow(open_on, "", "emulator", 25000, 1e-4, 0);
    emu_test_faults(open_on, "2", 1e-4); /* tests/stage_emu.h */
    CHECK_DONE();
}
