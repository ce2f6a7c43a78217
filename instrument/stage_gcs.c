/* stage_gcs.c: the stage backend for Physik Instrumente (PI) controllers speaking GCS 2.0 (the
 * "General Command Set" of the C-884, C-863/C-663 Mercury, E-709, E-727, ... controllers) over
 * TCP or a serial line (stage_link.h). Written from PI's published GCS 2.0 command descriptions
 * (the "GCS Commands" chapter and error-code list of e.g. the C-884 DC motor controller user
 * manual), not from any driver's code:
 *   - a command is one ASCII line ended by LF; commands that are not queries send no reply;
 *   - a query's reply is one or more lines; every line of a multi-line reply but the last ends
 *     with a space before its LF;
 *   - axis queries (POS?, ONT?, SVO?, FRF?, TMN?, TMX?) answer one "AXIS=VALUE" line per axis;
 *   - a failed command only sets the controller's error code, which ERR? returns (and clears):
 *     0 no error, 1 parameter syntax error, 2 unknown command, 5 move on an unreferenced axis or
 *     with the servo off, 7 position out of limits, 10 stopped by command, 15 invalid axis
 *     identifier, ... (gcs_error_text);
 *   - MOV starts an absolute move; ONT? says when each axis is on target; SVO switches the
 *     position servo; FRF references an axis against its reference switch and FRF? says whether
 *     it is referenced; TMN?/TMX? are the soft travel limits; GOH moves to the home position;
 *     SAI? lists the controller's axis identifiers; *IDN? identifies it.
 * Units: GCS positions are in the stage's unit (mm for most, um for piezo stages); unit= of the
 * stage string says which (stage.h). This file converts to the interface's micrometres.
 *
 * After every command (not query) the backend asks ERR?, so an error is seen at the command that
 * caused it. A lost connection closes the link; the next call reconnects and runs the opening
 * sequence again (servo, reference, limits), so a dropped connection costs one failed call. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "stage_impl.h"
#include "stage_link.h"
#include "stage_url.h"

struct gcs {
    stage_url_t url;
    stage_link_t *link; /* NULL after a lost connection: reopened at the next call */
    char idn[256];      /* the controller's *IDN? reply */
    stage_limits_t limits;
};

/* The texts of the GCS 2.0 error codes this backend may meet (PI's error code list). */
static const char *gcs_error_text(int code)
{
    switch (code) {
    case 0:
        return "no error";
    case 1:
        return "parameter syntax error";
    case 2:
        return "unknown command";
    case 3:
        return "command length out of limits or command buffer overrun";
    case 5:
        return "unallowable move attempted on unreferenced axis, or move attempted with "
               "servo off";
    case 7:
        return "position out of limits";
    case 8:
        return "velocity out of limits";
    case 10:
        return "controller was stopped by command";
    case 15:
        return "invalid axis identifier";
    case 17:
        return "parameter out of range";
    case 23:
        return "illegal axis";
    default:
        return "see the controller's error code list";
    }
}

/* The stage interface's error for a GCS error code: 7 is the travel limit (-ERANGE), 5 a move
 * the controller does not allow now (servo off or unreferenced: -EPERM), anything else -EIO. */
static int gcs_errno(int code)
{
    return code == 7 ? -ERANGE : code == 5 ? -EPERM : -EIO;
}

/* A lost link: closed, to be reopened at the next call. */
static int lost(struct gcs *g, int ret)
{
    if (stage_link_broken(ret)) {
        stage_link_close(g->link);
        g->link = NULL;
    }
    return ret;
}

/* Sends a query and reads its reply: lines joined by '\n' into out (n bytes), the trailing space
 * of continued lines removed. */
static int query(struct gcs *g, const char *q, char *out, size_t n, err_t *err)
{
    int ret = stage_link_send(g->link, q, err);
    size_t used = 0;
    out[0] = 0;
    while (ret == 0) {
        char line[512];
        int len = stage_link_read_line(g->link, line, sizeof line, g->url.timeout_s, err);
        if (len < 0) {
            ret = len;
            break;
        }
        int more = len > 0 && line[len - 1] == ' '; /* the continuation mark */
        if (more) line[--len] = 0;
        if (used + (size_t)len + 2 > n) {
            ret = err_set(err, -EOVERFLOW, "GCS reply to %s too long", q);
            break;
        }
        if (used) out[used++] = '\n';
        memcpy(out + used, line, (size_t)len + 1);
        used += (size_t)len;
        if (!more) break;
    }
    return lost(g, ret);
}

/* ERR?: the controller's error code (cleared by asking). A non-zero code becomes an error naming
 * the command that caused it, with the controller's code and its text. */
static int check_error(struct gcs *g, const char *after, err_t *err)
{
    char r[64], *end;
    int ret = query(g, "ERR?", r, sizeof r, err);
    if (ret) return ret;
    long code = strtol(r, &end, 10);
    if (end == r || *end)
        return lost(g, err_set(err, -EIO, "GCS controller: ERR? answered '%.40s'", r));
    if (code == 0) return 0;
    return err_set(err, gcs_errno((int)code), "GCS controller error %ld after %.40s: %s", code,
                   after, gcs_error_text((int)code));
}

/* A command (no reply), then ERR?. */
static int command(struct gcs *g, const char *c, err_t *err)
{
    int ret = lost(g, stage_link_send(g->link, c, err));
    if (ret) return ret;
    char what[48];
    snprintf(what, sizeof what, "%.*s", (int)strcspn(c, " "), c);
    return check_error(g, what, err);
}

/* " A B C": the configured axes, for a query or command. */
static void axes_list(const struct gcs *g, char *out, size_t n)
{
    size_t used = 0;
    out[0] = 0;
    for (int a = 0; a < g->url.n_axes; a++)
        used += (size_t)snprintf(out + used, n - used, " %s", g->url.axes[a]);
}

/* Asks "Q? A B C" and parses its "AXIS=VALUE" lines into v[axis index] (in any order; every
 * configured axis must be answered). */
static int query_axes(struct gcs *g, const char *q, double v[STAGE_URL_AXES], err_t *err)
{
    char cmd[128], reply[1024], ax[64];
    axes_list(g, ax, sizeof ax);
    snprintf(cmd, sizeof cmd, "%s%s", q, ax);
    int ret = query(g, cmd, reply, sizeof reply, err);
    if (ret) return ret;
    int seen[STAGE_URL_AXES] = {0};
    for (char *save = NULL, *line = strtok_r(reply, "\n", &save); line;
         line = strtok_r(NULL, "\n", &save)) {
        char *eq = strchr(line, '='), *end;
        if (!eq) goto bad;
        *eq = 0;
        double x = strtod(eq + 1, &end);
        while (*end == ' ')
            end++;
        if (end == eq + 1 || *end || !isfinite(x)) goto bad;
        for (int a = 0; a < g->url.n_axes; a++)
            if (strcmp(line, g->url.axes[a]) == 0) {
                v[a] = x;
                seen[a] = 1;
            }
    }
    for (int a = 0; a < g->url.n_axes; a++)
        if (!seen[a])
            return lost(g, err_set(err, -EIO, "GCS controller: %s did not answer for axis %s", q,
                                   g->url.axes[a]));
    return 0;
bad:
    return lost(g, err_set(err, -EIO, "GCS controller: cannot read the reply to %s", q));
}

/* Polls query q (ONT? or FRF?) until every axis answers 1, at most move_timeout_s. */
static int wait_all(struct gcs *g, const char *q, const char *what, err_t *err)
{
    double deadline = clock_mono_s() + g->url.move_timeout_s;
    for (;;) {
        double v[STAGE_URL_AXES];
        int ret = query_axes(g, q, v, err);
        if (ret) return ret;
        int all = 1;
        for (int a = 0; a < g->url.n_axes; a++)
            all &= v[a] == 1;
        if (all) return 0;
        if (clock_mono_s() > deadline)
            return err_set(err, -ETIMEDOUT, "GCS stage: %s not done within %g s", what,
                           g->url.move_timeout_s);
        stage_link_pause_ms(g->url.poll_ms);
    }
}

/* The opening sequence: connect, *IDN?, clear the error, servo on, reference if needed, limits. */
static int gcs_connect(struct gcs *g, err_t *err)
{
    int ret = stage_link_open(&g->url, &g->link, err);
    if (ret) return ret;
    char ax[64], cmd[160];
    axes_list(g, ax, sizeof ax);
    if ((ret = query(g, "*IDN?", g->idn, sizeof g->idn, err))) return ret;
    char sai[512]; /* SAI?: the controller's axis identifiers, one a line */
    if ((ret = query(g, "SAI?", sai, sizeof sai, err))) return ret;
    for (int a = 0; a < g->url.n_axes; a++) {
        int found = 0;
        char copy[512];
        strcpy(copy, sai);
        for (char *save = NULL, *t = strtok_r(copy, "\n", &save); t;
             t = strtok_r(NULL, "\n", &save))
            found |= strcmp(t, g->url.axes[a]) == 0;
        if (found) continue;
        for (char *c = sai; *c; c++)
            if (*c == '\n') *c = ' ';
        return err_set(err, -EINVAL,
                       "GCS stage: axis %s is not an axis of the controller "
                       "(SAI?: %.100s)",
                       g->url.axes[a], sai);
    }
    char stale[64]; /* an error left from before us is not ours */
    if ((ret = query(g, "ERR?", stale, sizeof stale, err))) return ret;
    double v[STAGE_URL_AXES], lo[STAGE_URL_AXES], hi[STAGE_URL_AXES];
    if ((ret = query_axes(g, "SVO?", v, err))) return ret;
    int off = 0;
    for (int a = 0; a < g->url.n_axes; a++)
        off |= v[a] != 1;
    if (off) { /* closed-loop stages move only with the servo on */
        size_t used = (size_t)snprintf(cmd, sizeof cmd, "SVO");
        for (int a = 0; a < g->url.n_axes; a++)
            used += (size_t)snprintf(cmd + used, sizeof cmd - used, " %s 1", g->url.axes[a]);
        if ((ret = command(g, cmd, err))) return ret;
    }
    if ((ret = query_axes(g, "FRF?", v, err))) return ret;
    int unref = 0;
    for (int a = 0; a < g->url.n_axes; a++)
        unref |= v[a] != 1;
    if (unref && !g->url.reference)
        return err_set(err, -EPERM,
                       "GCS stage: axes not referenced (FRF? = 0) and reference=0 forbids FRF");
    if (unref) {
        snprintf(cmd, sizeof cmd, "FRF%s", ax);
        if ((ret = command(g, cmd, err)) || (ret = wait_all(g, "FRF?", "referencing", err)))
            return ret;
    }
    if ((ret = query_axes(g, "TMN?", lo, err)) || (ret = query_axes(g, "TMX?", hi, err)))
        return ret;
    double *mn = &g->limits.min.x_um, *mx = &g->limits.max.x_um;
    for (int a = 0; a < STAGE_URL_AXES; a++) {
        mn[a] = a < g->url.n_axes ? lo[a] * g->url.unit_um : 0;
        mx[a] = a < g->url.n_axes ? hi[a] * g->url.unit_um : 0;
        if (!(mn[a] <= mx[a]))
            return err_set(err, -EIO, "GCS stage: travel of axis %s is empty (TMN? > TMX?)",
                           g->url.axes[a]);
    }
    return 0;
}

/* Reconnects after a lost connection (a failed opening sequence leaves no link). */
static int ready(struct gcs *g, err_t *err)
{
    if (g->link) return 0;
    int ret = gcs_connect(g, err);
    if (ret) {
        stage_link_close(g->link);
        g->link = NULL;
    }
    return ret;
}

static void gcs_close(void *impl)
{
    struct gcs *g = impl;
    if (!g) return;
    stage_link_close(g->link);
    free(g);
}

static int gcs_move(void *impl, const stage_pos_t *t, err_t *err)
{
    struct gcs *g = impl;
    int ret = ready(g, err);
    if (ret) return ret;
    const double *um = &t->x_um;
    char cmd[256];
    size_t used = (size_t)snprintf(cmd, sizeof cmd, "MOV");
    for (int a = 0; a < g->url.n_axes; a++) /* 10 significant digits: 0.1 nm of a 100 mm travel */
        used += (size_t)snprintf(cmd + used, sizeof cmd - used, " %s %.10g", g->url.axes[a],
                                 um[a] / g->url.unit_um);
    if ((ret = command(g, cmd, err))) return ret;
    return wait_all(g, "ONT?", "move", err);
}

static int gcs_position(void *impl, stage_pos_t *pos, err_t *err)
{
    struct gcs *g = impl;
    double v[STAGE_URL_AXES] = {0, 0, 0};
    int ret = ready(g, err);
    if (ret || (ret = query_axes(g, "POS?", v, err))) return ret;
    pos->x_um = v[0] * g->url.unit_um;
    pos->y_um = v[1] * g->url.unit_um;
    pos->z_um = g->url.n_axes > 2 ? v[2] * g->url.unit_um : 0;
    return 0;
}

static int gcs_home(void *impl, err_t *err)
{
    struct gcs *g = impl;
    char cmd[96], ax[64];
    int ret = ready(g, err);
    if (ret) return ret;
    axes_list(g, ax, sizeof ax);
    snprintf(cmd, sizeof cmd, "GOH%s", ax);
    if ((ret = command(g, cmd, err))) return ret;
    return wait_all(g, "ONT?", "homing", err);
}

static const char *gcs_idn(void *impl)
{
    return ((struct gcs *)impl)->idn;
}

static int gcs_limits(void *impl, stage_limits_t *lim, err_t *err)
{
    struct gcs *g = impl;
    int ret = ready(g, err);
    if (ret) return ret;
    *lim = g->limits;
    return 0;
}

const struct stage_ops stage_gcs_ops = {
    .backend = "gcs",
    .close = gcs_close,
    .move = gcs_move,
    .position = gcs_position,
    .home = gcs_home,
    .limits = gcs_limits,
    .identity = gcs_idn,
};

int stage_gcs_new(const stage_url_t *u, void **impl, err_t *err)
{
    *impl = NULL;
    struct gcs *g = calloc(1, sizeof *g);
    if (!g) return err_set(err, -ENOMEM, "out of memory for the GCS stage");
    g->url = *u;
    int ret = gcs_connect(g, err);
    if (ret) {
        gcs_close(g);
        return ret;
    }
    *impl = g;
    return 0;
}
