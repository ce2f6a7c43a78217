/* stage_emu.h: starting and stopping an emulated stage controller (tests/gcs_emulator.py,
 * tests/zaber_emulator.py) from a C test: the emulator runs as a child with its stdin on a pipe
 * (closing it ends the emulator, so no test leaves one running) and says on its first stdout line
 * where it listens ("tcp PORT" or "pty /dev/pts/N"). Also the cases every stage protocol family
 * shares, run on the family's own emulator: the faults (a connection dropped mid-move over TCP,
 * a controller falling silent and a line going away over a pseudo-terminal), the follower, and
 * wrong stage strings. Header-only, for test_stage_*.c (after check.h and instrument/stage.h). */
#ifndef IPSD_TEST_STAGE_EMU_H
#define IPSD_TEST_STAGE_EMU_H

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#ifndef IPSD_PYTHON3
#define IPSD_PYTHON3 "python3"
#endif

typedef struct emu {
    pid_t pid;
    int in;          /* the emulator's stdin: closing it ends the emulator */
    char where[256]; /* "tcp PORT" or "pty /dev/pts/N" */
} emu_t;

/* Starts script with options (NULL-terminated) and reads where it listens. */
static int emu_start_script(emu_t *e, const char *script, const char *const *opts)
{
    int in[2], out[2];
    if (pipe(in) || pipe(out)) return -1;
    const char *argv[32] = {IPSD_PYTHON3, "-B", script};
    int n = 3;
    for (; *opts && n < 31; opts++)
        argv[n++] = *opts;
    argv[n] = NULL;
    e->pid = fork();
    if (e->pid == 0) {
        dup2(in[0], 0);
        dup2(out[1], 1);
        close(in[1]);
        close(out[0]);
        execvp(IPSD_PYTHON3, (char *const *)argv);
        _exit(127);
    }
    close(in[0]);
    close(out[1]);
    e->in = in[1];
    size_t len = 0;
    while (len + 1 < sizeof e->where) { /* the first line: blocks until the emulator is up */
        ssize_t r = read(out[0], e->where + len, 1);
        if (r <= 0 || e->where[len] == '\n') break;
        len++;
    }
    e->where[len] = 0;
    close(out[0]);
    return len > 4 ? 0 : -1;
}

static void emu_stop(emu_t *e)
{
    close(e->in);
    int st;
    waitpid(e->pid, &st, 0);
}

/* The stage string FAMILY:tcp://127.0.0.1:PORT?poll_ms=0[&opts] or FAMILY:serial:DEV?... for e. */
static void emu_url(const emu_t *e, const char *family, const char *opts, char *url, size_t n)
{
    if (strncmp(e->where, "tcp ", 4) == 0)
        snprintf(url, n, "%s:tcp://127.0.0.1:%s?poll_ms=0%s%s", family, e->where + 4,
                 *opts ? "&" : "", opts);
    else
        snprintf(url, n, "%s:serial:%s?baud=115200&poll_ms=0%s%s", family, e->where + 4,
                 *opts ? "&" : "", opts);
}

/* A family's opener: starts its emulator with emu_opts and opens the stage with url_opts (the
 * options after the transport's in the stage string); *ret is stage_open_url's return. */
typedef stage_t *(*emu_open_fn)(emu_t *e, const char *const *emu_opts, const char *url_opts,
                                int *ret, err_t *err);

/* The fault cases, on the family's emulator opened by open_on. second_move: the emulator's move
 * count (its --drop-after-mov / --silent-after-mov N) at which the second stage move starts (a
 * GCS MOV carries every axis: 2; a Zaber "move abs" one axis, three a stage move: 4). tol: how
 * far a position read back may be from the one commanded (0: exactly; 1e-4 um: POS?'s 7
 * decimals of mm).
 * 1. TCP, the connection dropped mid-move: the move fails at once, the next call reconnects.
 * 2. Pseudo-terminal, a controller that stops answering: a timeout (again at the next call:
 *    reopening the line does not hang either).
 * 3. Pseudo-terminal, a line that goes away: -EIO. */
static void emu_test_faults(emu_open_fn open_on, const char *second_move, double tol)
{
    emu_t e;
    err_t err;
    int ret;
    const char *drop[] = {"--tcp=0", "--drop-after-mov", second_move, NULL};
    stage_t *st = open_on(&e, drop, "", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        stage_pos_t a = {100, 200, 5}, b = {-100, -200, -5}, c = {7, 8, 9}, p;
        CHECK(stage_move(st, &a, NULL) == 0);
        CHECK(stage_move(st, &b, &err) == -EIO && strstr(err.msg, "closed"));
        CHECK(stage_move(st, &c, &err) == 0);
        CHECK(stage_get_position(st, &p, NULL) == 0);
        CHECK_NEAR(p.x_um, 7, 0, tol);
        CHECK_NEAR(p.y_um, 8, 0, tol);
        CHECK_NEAR(p.z_um, 9, 0, tol);
        stage_close(st);
    }
    emu_stop(&e);
    const char *silent[] = {"--pty", "--silent-after-mov", second_move, NULL};
    st = open_on(&e, silent, "timeout=1.5", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        stage_pos_t a = {1, 2, 3}, p;
        CHECK(stage_move(st, &a, NULL) == 0);
        CHECK(stage_move(st, &a, &err) == -ETIMEDOUT && strstr(err.msg, "no reply"));
        CHECK(stage_get_position(st, &p, &err) == -ETIMEDOUT);
        stage_close(st);
    }
    emu_stop(&e);
    const char *gone[] = {"--pty", "--drop-after-mov", "1", NULL};
    st = open_on(&e, gone, "timeout=5", &ret, &err);
    CHECK(ret == 0);
    if (st) {
        stage_pos_t a = {1, 2, 3};
        int rc = stage_move(st, &a, &err); /* the emulator closes its end of the line and exits */
        CHECK(rc == -EIO);
        if (rc != -EIO) fprintf(stderr, "pty drop: %d %s\n", rc, err.msg);
        stage_close(st);
    }
    emu_stop(&e);
}

/* The follower: the simulated bench's stage (sim: x, y +-50 mm, z +-5 mm) following the
 * family's stage's reported position, its travel the intersection (xy_um: the family's x, y
 * travel end where it is the smaller). identity: a word of the family's identity; tol: how far
 * a position read back may be from the one commanded; step_um > 0: the reported position is a
 * whole microstep of it. */
static void emu_test_follow(emu_open_fn open_on, const char *url_opts, const char *identity,
                            double xy_um, double tol, double step_um)
{
    emu_t e;
    err_t err;
    int ret;
    const char *opts[] = {"--tcp=0", NULL};
    stage_t *lead = open_on(&e, opts, url_opts, &ret, &err), *shadow, *st;
    CHECK(ret == 0);
    if (lead) {
        CHECK(stage_open("sim", NULL, &shadow, NULL) == 0);
        CHECK(stage_open_follow(lead, shadow, &st, &err) == 0);
        CHECK(strcmp(stage_backend(st), "follow") == 0 && strstr(stage_identity(st), identity));
        stage_limits_t lim;
        CHECK(stage_get_limits(st, &lim, NULL) == 0);
        CHECK(lim.min.x_um == -xy_um && lim.max.y_um == xy_um);
        CHECK(lim.min.z_um == -5000 && lim.max.z_um == 5000);
        stage_pos_t t = {183.3, 183.9, -1.25}, p, q;
        CHECK(stage_move(st, &t, NULL) == 0);
        CHECK(stage_get_position(st, &p, NULL) == 0 && stage_get_position(shadow, &q, NULL) == 0);
        CHECK_NEAR(p.x_um, 183.3, 0, tol);
        if (step_um > 0) /* a whole microstep */
            CHECK(fabs(p.x_um / step_um - round(p.x_um / step_um)) < 1e-6);
        CHECK(q.x_um == p.x_um && q.y_um == p.y_um && q.z_um == p.z_um); /* the reported one */
        t.z_um = 6000; /* inside the controller's travel, outside the shadow's */
        CHECK(stage_move(st, &t, &err) == -ERANGE && strstr(err.msg, "z ="));
        CHECK(stage_home(st, NULL) == 0 && stage_get_position(shadow, &q, NULL) == 0);
        CHECK(q.x_um == 0 && q.y_um == 0 && q.z_um == 0);
        stage_close(st); /* closes the lead */
        stage_close(shadow);
    }
    emu_stop(&e);
}

/* A stage string that is wrong, and a word of the error that must say why. */
typedef struct emu_bad_url {
    const char *url, *says;
} emu_bad_url_t;

/* Each of the n strings is refused by stage_url_check with -EINVAL, the error saying why. */
static void emu_check_bad_urls(const emu_bad_url_t *bad, size_t n)
{
    err_t err;
    for (size_t i = 0; i < n; i++) {
        int rc = stage_url_check(bad[i].url, NULL, &err);
        CHECK(rc == -EINVAL && strstr(err.msg, bad[i].says));
        if (rc != -EINVAL || !strstr(err.msg, bad[i].says))
            fprintf(stderr, "  %s: %d '%s'\n", bad[i].url, rc, rc ? err.msg : "");
    }
}

#endif
