/* stage_url.c: parsing the stage string (stage_url.h; syntax in stage.h). Hand-written: the
 * string is a small fixed grammar (FAMILY:LINK with key=value options), not a general URI. The
 * families (gcs, zaber) share the links and the common options; family_option has the rest. */
#include "stage_url.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parse.h"

/* The baud rates termios offers that serial motion controllers use. */
static const int bauds[] = {9600, 19200, 38400, 57600, 115200, 230400, 460800};

static int bad(err_t *err, const char *what, const char *text)
{
    return err_set(err, -EINVAL, "%s (got '%.120s')", what, text);
}

/* "A,B[,C]": GCS axis identifiers, 1..8 characters of [A-Za-z0-9_-]. */
static int parse_axes(const char *v, stage_url_t *u, err_t *err)
{
    int n = 0;
    const char *p = v;
    for (;;) {
        size_t len = strcspn(p, ",");
        if (n == STAGE_URL_AXES || len == 0 || len >= STAGE_URL_AXIS_LEN)
            return bad(err, "axes= needs 2 or 3 comma-separated GCS axis names of 1..8 characters",
                       v);
        for (size_t i = 0; i < len; i++) {
            char c = p[i];
            if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                  c == '_' || c == '-'))
                return bad(err, "axes= names are letters, digits, _ and -", v);
        }
        memcpy(u->axes[n], p, len);
        u->axes[n][len] = 0;
        n++;
        if (!p[len]) break;
        p += len + 1;
    }
    if (n < 2) return bad(err, "axes= needs 2 or 3 comma-separated GCS axis names", v);
    if (u->backend == STAGE_URL_ZABER)
        for (int i = 0; i < n; i++)
            if (strlen(u->axes[i]) != 1 || u->axes[i][0] < '1' || u->axes[i][0] > '9')
                return bad(err, "axes= of a Zaber stage are axis numbers 1..9", v);
    u->n_axes = n;
    return 0;
}

/* "D,D[,D]": Zaber device numbers 1..99 of x, y[, z]. */
static int parse_devices(const char *v, stage_url_t *u, int *n_devices, err_t *err)
{
    int n = 0;
    const char *p = v;
    for (;;) {
        size_t len = strcspn(p, ",");
        char num[8];
        long long d;
        if (n == STAGE_URL_AXES || len == 0 || len >= sizeof num)
            return bad(err, "devices= needs 2 or 3 comma-separated device numbers 1..99", v);
        memcpy(num, p, len);
        num[len] = 0;
        if (parse_ll(num, &d) || d < 1 || d > 99)
            return bad(err, "devices= needs 2 or 3 comma-separated device numbers 1..99", v);
        u->devices[n++] = (int)d;
        if (!p[len]) break;
        p += len + 1;
    }
    if (n < 2) return bad(err, "devices= needs 2 or 3 comma-separated device numbers 1..99", v);
    *n_devices = n;
    return 0;
}

/* No axis named twice (GCS: the same identifier; Zaber: the same device and axis). */
static int check_repeats(const stage_url_t *u, err_t *err)
{
    for (int i = 0; i < u->n_axes; i++)
        for (int j = 0; j < i; j++)
            if (strcmp(u->axes[i], u->axes[j]) == 0 &&
                (u->backend != STAGE_URL_ZABER || u->devices[i] == u->devices[j]))
                return err_set(err, -EINVAL, "axes= repeats an axis (%s)", u->axes[i]);
    return 0;
}

/* A number of seconds in (0, 3600]. */
static int parse_seconds(const char *key, const char *v, double *out, err_t *err)
{
    double s;
    if (parse_double(v, &s) || !(s > 0 && s <= 3600))
        return err_set(err, -EINVAL, "%s= must be seconds in (0, 3600] (got '%.60s')", key, v);
    *out = s;
    return 0;
}

/* What one_option saw of the options that depend on each other. */
struct seen {
    int n_devices; /* devices= entries (0: not given) */
    int step_um;   /* step_um= given */
};

/* The options only one family has: unit= (GCS), step_um=, device=, devices= (Zaber). Returns 1
 * when k is none of them. */
static int family_option(const char *k, const char *v, stage_url_t *u, struct seen *seen,
                         err_t *err)
{
    int zaber = u->backend == STAGE_URL_ZABER;
    if (strcmp(k, "unit") == 0) {
        if (zaber) return bad(err, "unit= is for gcs stages; a Zaber stage's unit is step_um=", v);
        if (strcmp(v, "mm") && strcmp(v, "um")) return bad(err, "unit= must be mm or um", v);
        u->unit_um = v[0] == 'm' ? 1000.0 : 1.0;
        return 0;
    }
    if (strcmp(k, "step_um") && strcmp(k, "device") && strcmp(k, "devices")) return 1;
    if (!zaber) return err_set(err, -EINVAL, "%s= is for zaber stages", k);
    if (strcmp(k, "step_um") == 0) {
        double s;
        if (parse_double(v, &s) || !(s > 0 && s <= 1000))
            return bad(err, "step_um= must be the microstep size in um, in (0, 1000]", v);
        u->unit_um = s;
        seen->step_um = 1;
        return 0;
    }
    if (strcmp(k, "devices") == 0) return parse_devices(v, u, &seen->n_devices, err);
    long long d;
    if (parse_ll(v, &d) || d < 1 || d > 99) return bad(err, "device= must be 1..99", v);
    for (int a = 0; a < STAGE_URL_AXES; a++)
        u->devices[a] = (int)d;
    return 0;
}

static int one_option(char *kv, stage_url_t *u, struct seen *seen, err_t *err)
{
    char *eq = strchr(kv, '=');
    if (!eq) return bad(err, "options are key=value", kv);
    *eq = 0;
    const char *k = kv, *v = eq + 1;
    long long n;
    int ret = family_option(k, v, u, seen, err);
    if (ret <= 0) return ret;
    if (strcmp(k, "axes") == 0) return parse_axes(v, u, err);
    if (strcmp(k, "timeout") == 0) return parse_seconds(k, v, &u->timeout_s, err);
    if (strcmp(k, "move_timeout") == 0) return parse_seconds(k, v, &u->move_timeout_s, err);
    if (strcmp(k, "poll_ms") == 0) {
        if (parse_ll(v, &n) || n < 0 || n > 10000) return bad(err, "poll_ms= must be 0..10000", v);
        u->poll_ms = (int)n;
        return 0;
    }
    if (strcmp(k, "reference") == 0) {
        if (strcmp(v, "0") && strcmp(v, "1")) return bad(err, "reference= must be 0 or 1", v);
        u->reference = v[0] == '1';
        return 0;
    }
    if (strcmp(k, "baud") == 0) {
        if (u->link != STAGE_LINK_SERIAL) return bad(err, "baud= is for serial lines only", v);
        int ok = 0;
        if (parse_ll(v, &n) == 0)
            for (size_t i = 0; i < sizeof bauds / sizeof bauds[0]; i++)
                ok |= n == bauds[i];
        if (!ok)
            return bad(err, "baud= must be 9600, 19200, 38400, 57600, 115200, 230400 or 460800", v);
        u->baud = (int)n;
        return 0;
    }
    return err_set(err, -EINVAL,
                   "unknown option '%.40s' (%s, axes, timeout, move_timeout, poll_ms, "
                   "reference, baud)",
                   k, u->backend == STAGE_URL_ZABER ? "step_um, device, devices" : "unit");
}

/* "HOST:PORT" or "[V6]:PORT". */
static int parse_host_port(const char *hp, const char *fam, stage_url_t *u, err_t *err)
{
    const char *colon = strrchr(hp, ':');
    const char *host = hp;
    size_t hlen = colon ? (size_t)(colon - hp) : 0;
    if (hlen >= 2 && hp[0] == '[' && hp[hlen - 1] == ']') {
        host++;
        hlen -= 2;
    }
    long long port;
    /* the port only digits (parse_ll takes a leading space: "h: 80"); the host a name or an
     * IPv4 address, or an IPv6 address in brackets: no bracket, space or control character
     * reaches the resolver ("[::1" was looked up as the host "[:") */
    int ok = colon && colon[1] && strspn(colon + 1, "0123456789") == strlen(colon + 1);
    const char *allowed = host != hp ? "0123456789abcdefABCDEF:.%" /* [v6] */
                                     : "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                       "0123456789.-_";
    for (size_t i = 0; ok && i < hlen; i++)
        ok = strchr(allowed, host[i]) != NULL;
    if (!ok || hlen == 0 || hlen >= sizeof u->host || parse_ll(colon + 1, &port) || port < 1 ||
        port > 65535)
        return err_set(err, -EINVAL,
                       "need %s:tcp://HOST:PORT with a host name, an IPv4 address or [IPv6] and "
                       "a port 1..65535 (got '%.120s')",
                       fam, hp);
    memcpy(u->host, host, hlen);
    u->host[hlen] = 0;
    u->port = (int)port;
    return 0;
}

/* The controller families: the prefix of their stage strings. */
static const struct {
    const char *prefix;
    int backend;
} families[] = {{"gcs:", STAGE_URL_GCS}, {"zaber:", STAGE_URL_ZABER}};

/* The one-line error quotes the string: its control characters (a newline, ESC) and bytes
 * over 0x7e written as \xNN, so a hostile string can neither break the line nor drive a
 * terminal. */
static void escape_controls(err_t *err)
{
    char out[sizeof err->msg];
    size_t o = 0;
    for (const unsigned char *p = (const unsigned char *)err->msg; *p && o + 5 < sizeof out; p++)
        if (*p < 0x20 || *p >= 0x7f)
            o += (size_t)snprintf(out + o, sizeof out - o, "\\x%02x", *p);
        else
            out[o++] = (char)*p;
    out[o] = 0;
    memcpy(err->msg, out, o + 1);
}

static int parse(const char *text, stage_url_t *u, err_t *err);

int stage_url_parse(const char *text, stage_url_t *u, err_t *err)
{
    int ret = parse(text, u, err);
    if (ret && err) escape_controls(err);
    return ret;
}

static int parse(const char *text, stage_url_t *u, err_t *err)
{
    memset(u, 0, sizeof *u);
    u->baud = 115200;
    u->unit_um = 1000.0; /* GCS 2.0 stages mostly report millimetres */
    strcpy(u->axes[0], "1");
    strcpy(u->axes[1], "2");
    strcpy(u->axes[2], "3");
    u->n_axes = 3;
    for (int a = 0; a < STAGE_URL_AXES; a++)
        u->devices[a] = 1;
    u->timeout_s = 5;
    u->move_timeout_s = 60;
    u->poll_ms = 10;
    u->reference = 1;
    if (!text || strcmp(text, "sim") == 0) {
        u->backend = STAGE_URL_SIM;
        return 0;
    }
    size_t skip = 0;
    char fam[8] = "";
    for (size_t f = 0; f < sizeof families / sizeof families[0]; f++)
        if (strncmp(text, families[f].prefix, strlen(families[f].prefix)) == 0) {
            u->backend = families[f].backend;
            skip = strlen(families[f].prefix);
            snprintf(fam, sizeof fam, "%.*s", (int)skip - 1, families[f].prefix);
        }
    if (!skip)
        return bad(err,
                   "need sim, or gcs: or zaber: followed by tcp://HOST:PORT[?OPTIONS] or "
                   "serial:DEVICE[?OPTIONS]",
                   text);
    char buf[1024];
    if (strlen(text) >= sizeof buf) return err_set(err, -EINVAL, "stage string too long");
    strcpy(buf, text + skip);
    char *query = strchr(buf, '?');
    if (query) *query++ = 0;
    int ret;
    if (strncmp(buf, "tcp://", 6) == 0) {
        u->link = STAGE_LINK_TCP;
        ret = parse_host_port(buf + 6, fam, u, err);
    } else if (strncmp(buf, "serial:", 7) == 0) {
        u->link = STAGE_LINK_SERIAL;
        const char *dev = buf + 7;
        if (dev[0] != '/' || strlen(dev) >= sizeof u->device)
            return err_set(err, -EINVAL,
                           "need %s:serial:/dev/DEVICE (an absolute path; got '%.120s')", fam,
                           text);
        strcpy(u->device, dev);
        ret = 0;
    } else {
        return err_set(err, -EINVAL, "need %s:tcp://HOST:PORT or %s:serial:DEVICE (got '%.120s')",
                       fam, fam, text);
    }
    if (ret) return ret;
    struct seen seen = {0, 0};
    const char *keys[64];
    int n_keys = 0;
    if (query)
        for (char *save = NULL, *kv = strtok_r(query, "&", &save); kv;
             kv = strtok_r(NULL, "&", &save)) {
            /* a key given twice is a mistake, not a last-one-wins (unit=mm&unit=um) */
            size_t klen = strcspn(kv, "=");
            for (int i = 0; i < n_keys; i++)
                if (strlen(keys[i]) == klen && strncmp(keys[i], kv, klen) == 0)
                    return err_set(err, -EINVAL, "option %.*s= is given twice", (int)klen, kv);
            if (n_keys == 64) return err_set(err, -EINVAL, "too many options");
            if ((ret = one_option(kv, u, &seen, err))) return ret;
            keys[n_keys++] = kv; /* one_option cut it at its '=' */
        }
    if (u->backend == STAGE_URL_ZABER) {
        if (!seen.step_um)
            return err_set(err, -EINVAL,
                           "a zaber stage needs step_um= (its microstep size in um, from the "
                           "stage's data sheet)");
        if (seen.n_devices && seen.n_devices != u->n_axes)
            return err_set(err, -EINVAL, "devices= names %d devices for %d axes", seen.n_devices,
                           u->n_axes);
    }
    return check_repeats(u, err);
}
