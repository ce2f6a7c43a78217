/* stage_zaber.c: the stage backend for Zaber devices speaking the Zaber ASCII protocol (firmware 6
 * and 7: X-LSM, X-LRQ, X-MCC controllers, ...) over TCP or a serial line (stage_link.h, shared
 * with the GCS backend). Written from Zaber's published protocol descriptions, not from any
 * driver's code:
 *   - "Zaber's ASCII Protocol" (zaber.com/articles/ascii-protocol, 2022): a message is one line
 *     of space-separated fields whose first character says its type: commands "/" (sent by the
 *     host), replies "@" (one per command, from the addressed device), info "#" (sent after the
 *     reply to some commands), alerts "!" (sent spontaneously, e.g. when a move ends, if enabled);
 *     a reply is "@DD A FLAG STATUS WARNING DATA": the device's address (two digits), the axis
 *     (0: the whole device), OK or RJ (rejected), BUSY (moving) or IDLE, the highest warning
 *     flag ("--": none) and the data (0 when there is none, the rejection reason after RJ);
 *   - the ZaberWiki "ASCII" protocol page: commands end with CR, LF or both; devices always reply
 *     with CR LF (stage_link drops the CR);
 *   - Zaber's ASCII Protocol Manual (zaber.com/wiki/Manuals/ASCII_Protocol_Manual; its command
 *     and warning-flag reference, as also encoded by the zproto library's checks): "/D A move abs
 *     N" (N in microsteps), "/D A home" (to the home sensor; establishes the reference position),
 *     "/D A stop", "/D A get pos", "get limit.min" / "get limit.max" (the travel, microsteps),
 *     "/D 0 get deviceid" / "get version", "/D A" alone (the status reply: BUSY or IDLE),
 *     "/D A warnings clear" (the flags as "NN F1 F2 ...", then cleared); rejection reasons
 *     BADDATA (data out of range or not a number), BADCOMMAND, BADAXIS, PARKED, ...; warning
 *     flags by level: F* faults (FS stalled and stopped, FQ encoder error, ...), W* warnings (WR no
 *     reference position, WH not homed (firmware 6), WL unexpected limit trigger, ...), N* notices
 *     (NI a move interrupted by a command or the knob, NC manual control, ...).
 * Units: Zaber positions are integer microsteps; step_um= of the stage string gives their size
 * (stage.h), this file converts to the interface's micrometres. Each axis is "/D A": device
 * number and axis number, both from the stage string.
 *
 * A move sends one "move abs" per axis and polls each axis's status until all are IDLE; a flag
 * other than "--" when a move ends is read and cleared with "warnings clear" and becomes the
 * move's error if it says the move went wrong (F*, WL, NI, WR/WH). Alerts and info messages
 * between replies are skipped. A lost connection closes the link; the next call reconnects and
 * runs the opening sequence again, as in stage_gcs.c. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "stage_impl.h"
#include "stage_link.h"
#include "stage_url.h"

struct zaber {
    stage_url_t url;
    stage_link_t *link; /* NULL after a lost connection: reopened at the next call */
    char identity[256]; /* "Zaber device 1: deviceid 30222, version 7.38; ..." */
    stage_limits_t limits;
    int stale; /* a stop or a failed move may have left flags: clear before moving */
};

/* One reply: "@DD A OK|RJ BUSY|IDLE FLAG DATA". */
typedef struct reply {
    int device, axis;
    int rejected, busy;
    char flag[3];
    char data[200];
} reply_t;

/* What the rejection reasons mean (the manual's list; the others are named as they come). */
static const char *reason_text(const char *r)
{
    static const struct {
        const char *reason, *text;
    } t[] = {
        {"BADDATA", "data out of range or not a number"},
        {"BADCOMMAND", "command not recognised"},
        {"BADAXIS", "no such axis"},
        {"DEVICEONLY", "a command for the whole device (axis 0)"},
        {"PARKED", "the axis is parked"},
        {"AGAIN", "busy, try again"},
        {"STATUSBUSY", "the device is busy"},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(r, t[i].reason) == 0) return t[i].text;
    return "see the protocol manual";
}

/* What the warning flags this backend acts on mean. */
static const char *flag_text(const char *f)
{
    static const struct {
        const char *flag, *text;
    } t[] = {
        {"FS", "stalled and stopped"}, {"FQ", "encoder error"},
        {"FD", "driver disabled"},     {"FT", "excessive twist"},
        {"FE", "limit error"},         {"WR", "no reference position (home the axis)"},
        {"WH", "not homed"},           {"WL", "unexpected limit switch"},
        {"NI", "move interrupted"},    {"NC", "manual control"},
    };
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(f, t[i].flag) == 0) return t[i].text;
    return "see the protocol manual";
}

/* A lost link: closed, to be reopened at the next call. */
static int lost(struct zaber *z, int ret)
{
    if (stage_link_broken(ret)) {
        stage_link_close(z->link);
        z->link = NULL;
    }
    return ret;
}

/* Parses "@DD A OK IDLE -- DATA" (DATA may hold spaces: "warnings" lists flags). */
static int parse_reply(const char *line, reply_t *r)
{
    char flag[4], status[6], warn[4];
    int used = 0;
    if (sscanf(line, "@%2d %d %3s %5s %3s %n", &r->device, &r->axis, flag, status, warn, &used) !=
            5 ||
        used == 0)
        return -1;
    if (strcmp(flag, "OK") && strcmp(flag, "RJ")) return -1;
    if (strcmp(status, "BUSY") && strcmp(status, "IDLE")) return -1;
    if (strlen(warn) != 2) return -1;
    r->rejected = flag[0] == 'R';
    r->busy = status[0] == 'B';
    memcpy(r->flag, warn, 3);
    snprintf(r->data, sizeof r->data, "%s", line + used);
    return 0;
}

/* Sends "/D A cmd" (cmd "" asks for the status) and reads its reply, skipping alerts ("!") and
 * info messages ("#"). A rejection is an error naming the command and the reason: BADDATA of a
 * move is -ERANGE, PARKED -EPERM, BADAXIS -EINVAL, the others -EIO. */
static int transact(struct zaber *z, int dev, int axis, const char *cmd, reply_t *r, err_t *err)
{
    char line[256];
    snprintf(line, sizeof line, "/%d %d%s%s", dev, axis, *cmd ? " " : "", cmd);
    int ret = stage_link_send(z->link, line, err);
    double deadline = clock_mono_s() + z->url.timeout_s;
    while (ret == 0) {
        double left = deadline - clock_mono_s();
        int len = stage_link_read_line(z->link, line, sizeof line, left > 0 ? left : 0, err);
        if (len < 0) return lost(z, len);
        if (len == 0 || line[0] == '!' || line[0] == '#') continue;
        if (line[0] != '@' || parse_reply(line, r))
            return lost(
                z, err_set(err, -EIO, "Zaber device %d: cannot read the reply '%.60s'", dev, line));
        if (r->device != dev || r->axis != axis) continue; /* not the reply to this command */
        if (!r->rejected) return 0;
        int code = strcmp(r->data, "BADDATA") == 0 && strncmp(cmd, "move", 4) == 0 ? -ERANGE
                   : strcmp(r->data, "PARKED") == 0                                ? -EPERM
                   : strcmp(r->data, "BADAXIS") == 0                               ? -EINVAL
                                                                                   : -EIO;
        return err_set(err, code, "Zaber device %d axis %d rejected '%.40s': %.40s (%s)", dev, axis,
                       *cmd ? cmd : "status", r->data, reason_text(r->data));
    }
    return lost(z, ret);
}

/* A reply's data as an integer (positions and limits are microsteps). */
static int data_ll(struct zaber *z, const reply_t *r, const char *what, long long *v, err_t *err)
{
    char *end;
    *v = strtoll(r->data, &end, 10);
    if (end == r->data || *end)
        return lost(z, err_set(err, -EIO, "Zaber device %d axis %d: %s is '%.40s', not a number",
                               r->device, r->axis, what, r->data));
    return 0;
}

/* "get SETTING" of axis a as an integer. */
static int get_ll(struct zaber *z, int a, const char *setting, long long *v, err_t *err)
{
    char cmd[64];
    reply_t r;
    snprintf(cmd, sizeof cmd, "get %s", setting);
    int ret = transact(z, z->url.devices[a], atoi(z->url.axes[a]), cmd, &r, err);
    return ret ? ret : data_ll(z, &r, setting, v, err);
}

/* Reads and clears axis a's warning flags. *unreferenced says whether WR or WH is among them,
 * *flag_err the error a flag means for the move that just ended (0 when none does: a fault first,
 * then WL, NI, WR/WH); err has its message. Returns 0 or the link's error. */
static int take_flags(struct zaber *z, int a, int *unreferenced, int *flag_err, err_t *err)
{
    reply_t r;
    int dev = z->url.devices[a], axis = atoi(z->url.axes[a]);
    int ret = transact(z, dev, axis, "warnings clear", &r, err);
    *unreferenced = 0;
    *flag_err = 0;
    if (ret) return ret;
    char worst[3] = "";
    /* "NN F1 F2 ...": the count, then the flags */
    char *save = NULL, *t = strtok_r(r.data, " ", &save);
    for (t = t ? strtok_r(NULL, " ", &save) : NULL; t; t = strtok_r(NULL, " ", &save)) {
        int unref = strcmp(t, "WR") == 0 || strcmp(t, "WH") == 0;
        *unreferenced |= unref;
        int code = t[0] == 'F' || strcmp(t, "WL") == 0 || strcmp(t, "NI") == 0 ? -EIO
                   : unref                                                     ? -EPERM
                                                                               : 0;
        if (code && (!*flag_err || (t[0] == 'F' && worst[0] != 'F'))) {
            *flag_err = code;
            snprintf(worst, sizeof worst, "%.2s", t);
        }
    }
    if (*flag_err)
        err_set(err, *flag_err, "Zaber device %d axis %d: warning %s (%s)", dev, axis, worst,
                flag_text(worst));
    return 0;
}

/* Tells every axis to stop (best effort: after an error, whose message err keeps). */
static void stop_all(struct zaber *z)
{
    for (int a = 0; a < z->url.n_axes && z->link; a++) {
        reply_t r;
        err_t ignored;
        transact(z, z->url.devices[a], atoi(z->url.axes[a]), "stop", &r, &ignored);
    }
    z->stale = 1;
}

/* Polls every axis until all are IDLE (at most move_timeout_s), then reads and clears the flags
 * of those that show one; with judge, a flag that says the move went wrong is the error. On the
 * timeout the axes are told to stop. */
static int wait_idle(struct zaber *z, const char *what, int judge, err_t *err)
{
    double deadline = clock_mono_s() + z->url.move_timeout_s;
    for (;;) {
        int busy = 0, flagged[STAGE_URL_AXES] = {0};
        for (int a = 0; a < z->url.n_axes; a++) {
            reply_t r;
            int ret = transact(z, z->url.devices[a], atoi(z->url.axes[a]), "", &r, err);
            if (ret) return ret;
            busy |= r.busy;
            flagged[a] = strcmp(r.flag, "--") != 0;
        }
        if (!busy) {
            for (int a = 0; a < z->url.n_axes; a++) {
                int unref, bad = 0, ret = flagged[a] ? take_flags(z, a, &unref, &bad, err) : 0;
                if (ret || (judge && bad)) return ret ? ret : bad;
            }
            return 0;
        }
        if (clock_mono_s() > deadline) {
            stop_all(z);
            return err_set(err, -ETIMEDOUT, "Zaber stage: %s not done within %g s", what,
                           z->url.move_timeout_s);
        }
        stage_link_pause_ms(z->url.poll_ms);
    }
}

/* "home" on the axes in mask, then waits. */
static int home_axes(struct zaber *z, unsigned mask, err_t *err)
{
    for (int a = 0; a < z->url.n_axes; a++) {
        reply_t r;
        if (!(mask >> a & 1)) continue;
        int ret = transact(z, z->url.devices[a], atoi(z->url.axes[a]), "home", &r, err);
        if (ret) return ret;
    }
    return wait_idle(z, "homing", 1, err);
}

/* The identity: deviceid and firmware version of each device the axes are on. */
static int identify(struct zaber *z, err_t *err)
{
    size_t used = 0;
    z->identity[0] = 0;
    for (int a = 0; a < z->url.n_axes; a++) {
        int dev = z->url.devices[a], seen = 0;
        for (int b = 0; b < a; b++)
            seen |= z->url.devices[b] == dev;
        if (seen) continue;
        reply_t id, ver;
        int ret = transact(z, dev, 0, "get deviceid", &id, err);
        if (ret || (ret = transact(z, dev, 0, "get version", &ver, err))) return ret;
        used += (size_t)snprintf(z->identity + used, sizeof z->identity - used,
                                 "%sZaber device %d: deviceid %.20s, version %.20s",
                                 used ? "; " : "", dev, id.data, ver.data);
        if (used >= sizeof z->identity) used = sizeof z->identity - 1;
    }
    return 0;
}

/* The opening sequence: connect, identify, check the axes, home the unreferenced ones, limits. */
static int zaber_connect(struct zaber *z, err_t *err)
{
    int ret = stage_link_open(&z->url, &z->link, err);
    if (ret || (ret = identify(z, err))) return ret;
    unsigned unref_mask = 0;
    for (int a = 0; a < z->url.n_axes; a++) {
        long long pos;
        int unref, flag_err; /* flags from before us are not ours: only WR / WH counts */
        if ((ret = get_ll(z, a, "pos", &pos, err)) || /* BADAXIS: not an axis */
            (ret = take_flags(z, a, &unref, &flag_err, err)))
            return ret;
        if (unref) unref_mask |= 1u << a;
    }
    if (unref_mask && !z->url.reference)
        return err_set(err, -EPERM,
                       "Zaber stage: axes without a reference position (WR) and reference=0 "
                       "forbids homing");
    if (unref_mask && (ret = home_axes(z, unref_mask, err))) return ret;
    double *mn = &z->limits.min.x_um, *mx = &z->limits.max.x_um;
    for (int a = 0; a < STAGE_URL_AXES; a++) {
        long long lo = 0, hi = 0;
        if (a < z->url.n_axes && ((ret = get_ll(z, a, "limit.min", &lo, err)) ||
                                  (ret = get_ll(z, a, "limit.max", &hi, err))))
            return ret;
        mn[a] = (double)lo * z->url.unit_um;
        mx[a] = (double)hi * z->url.unit_um;
        if (lo > hi)
            return err_set(err, -EIO, "Zaber stage: travel of device %d axis %s is empty",
                           z->url.devices[a], z->url.axes[a]);
    }
    z->stale = 1; /* the first move lets axes moving from before come to rest, clears flags */
    return 0;
}

/* Reconnects after a lost connection (a failed opening sequence leaves no link). */
static int ready(struct zaber *z, err_t *err)
{
    if (z->link) return 0;
    int ret = zaber_connect(z, err);
    if (ret) {
        stage_link_close(z->link);
        z->link = NULL;
    }
    return ret;
}

static void zaber_close(void *impl)
{
    struct zaber *z = impl;
    if (!z) return;
    stage_link_close(z->link);
    free(z);
}

static int zaber_move(void *impl, const stage_pos_t *t, err_t *err)
{
    struct zaber *z = impl;
    int ret = ready(z, err);
    if (ret) return ret;
    /* after a stop or a failed move: let the axes come to rest and clear the flags they left
     * (a move under way, or its flags, are not this move's) */
    if (z->stale && (ret = wait_idle(z, "stopping", 0, err))) return ret;
    z->stale = 0;
    const double *um = &t->x_um;
    for (int a = 0; a < z->url.n_axes; a++) {
        char cmd[64];
        reply_t r;
        snprintf(cmd, sizeof cmd, "move abs %lld", llround(um[a] / z->url.unit_um));
        if ((ret = transact(z, z->url.devices[a], atoi(z->url.axes[a]), cmd, &r, err))) break;
    }
    if (ret == 0) ret = wait_idle(z, "move", 1, err);
    if (ret) stop_all(z); /* no axis goes on alone towards a target the move gave up */
    return ret;
}

static int zaber_position(void *impl, stage_pos_t *pos, err_t *err)
{
    struct zaber *z = impl;
    long long v[STAGE_URL_AXES] = {0, 0, 0};
    int ret = ready(z, err);
    for (int a = 0; ret == 0 && a < z->url.n_axes; a++)
        ret = get_ll(z, a, "pos", &v[a], err);
    if (ret) return ret;
    pos->x_um = (double)v[0] * z->url.unit_um;
    pos->y_um = (double)v[1] * z->url.unit_um;
    pos->z_um = (double)v[2] * z->url.unit_um;
    return 0;
}

static int zaber_home(void *impl, err_t *err)
{
    struct zaber *z = impl;
    int ret = ready(z, err);
    return ret ? ret : home_axes(z, (1u << z->url.n_axes) - 1, err);
}

static int zaber_limits(void *impl, stage_limits_t *lim, err_t *err)
{
    struct zaber *z = impl;
    int ret = ready(z, err);
    if (ret) return ret;
    *lim = z->limits;
    return 0;
}

static const char *zaber_identity(void *impl)
{
    return ((struct zaber *)impl)->identity;
}

const struct stage_ops stage_zaber_ops = {
    .backend = "zaber",
    .close = zaber_close,
    .move = zaber_move,
    .position = zaber_position,
    .home = zaber_home,
    .limits = zaber_limits,
    .identity = zaber_identity,
};

int stage_zaber_new(const stage_url_t *u, void **impl, err_t *err)
{
    *impl = NULL;
    struct zaber *z = calloc(1, sizeof *z);
    if (!z) return err_set(err, -ENOMEM, "out of memory for the Zaber stage");
    z->url = *u;
    int ret = zaber_connect(z, err);
    if (ret) {
        zaber_close(z);
        return ret;
    }
    *impl = z;
    return 0;
}
