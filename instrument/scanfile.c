/* scanfile.c: the scan-file reader and writer (see scanfile.h). Parsing is jansson's; this file
 * adds the non-finite-number pre-pass, the validation with one-line messages, and the writer. */
#include "instrument/scanfile.h"

#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "base/outfile.h"
#include "instrument/scan_limits.h"

/* ---- pre-pass for NaN / Infinity / -Infinity ----
 *
 * Why: JSON (RFC 8259) has no non-finite numbers and jansson rejects them, but Python's json
 * module writes NaN, Infinity and -Infinity as bare tokens by default (allow_nan=True), so scan
 * files written by lab scripts contain them wherever a reading failed. jansson has no hook for
 * extra tokens, so before parsing, every such token outside a string is rewritten as the same
 * word in quotes ("NaN", ...), which the array reader accepts. The scan tracks string state
 * (with backslash escapes), so nothing inside a string is touched, and it only rewrites whole
 * tokens (not followed by a letter, digit or underscore), so e.g. NaNx stays a syntax error.
 * Each rewrite inserts two bytes; their offsets are kept to map jansson's error line/column back
 * to the original text. */

struct nonfinite_token {
    const char *word;
    size_t len;
};

static const struct nonfinite_token tokens[] = {{"NaN", 3}, {"Infinity", 8}, {"-Infinity", 9}};

/* Length of the non-finite token starting at in[i] (0 if none). */
static size_t token_at(const char *in, size_t len, size_t i)
{
    for (size_t t = 0; t < sizeof tokens / sizeof tokens[0]; t++) {
        size_t l = tokens[t].len;
        if (l > len - i || memcmp(in + i, tokens[t].word, l) != 0) continue;
        if (i + l < len) {
            char c = in[i + l];
            if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                c == '_')
                return 0;
        }
        return l;
    }
    return 0;
}

/* Copies in to out (if not NULL) quoting the non-finite tokens outside strings, records the
 * output offset of each inserted opening quote in at (if not NULL), and returns their number. */
static size_t quote_nonfinite(const char *in, size_t len, char *out, size_t *at)
{
    size_t count = 0, o = 0;
    int in_string = 0;
    for (size_t i = 0; i < len;) {
        char c = in[i];
        size_t l = in_string ? 0 : token_at(in, len, i);
        if (l) {
            if (at) at[count] = o;
            if (out) {
                out[o] = '"';
                memcpy(out + o + 1, in + i, l);
                out[o + l + 1] = '"';
            }
            o += l + 2;
            i += l;
            count++;
            continue;
        }
        if (in_string && c == '\\' && i + 1 < len) { /* an escape: copy both bytes */
            if (out) out[o] = c;
            o++, i++;
            c = in[i];
        } else if (c == '"') {
            in_string = !in_string;
        }
        if (out) out[o] = c;
        o++, i++;
    }
    return count;
}

/* Parses the quoted text, mapping a syntax error's column back to the original text. */
static json_t *load_quoted(const char *text, size_t len, const size_t *at, size_t n_at,
                           err_t *err)
{
    json_error_t je;
    json_t *root = json_loadb(text, len, JSON_REJECT_DUPLICATES, &je);
    if (root) return root;
    /* jansson's column (1-based, in characters) and position (bytes) include the two quotes
     * of every rewrite before the error on the same line */
    size_t pos = je.position > 0 ? (size_t)je.position : 0, line_start = 0;
    for (size_t i = pos < len ? pos : len; i > 0; i--)
        if (text[i - 1] == '\n') {
            line_start = i;
            break;
        }
    int column = je.column;
    for (size_t k = 0; k < n_at; k++)
        if (at[k] >= line_start && at[k] < pos) column -= 2;
    err_set(err, -EINVAL, "invalid JSON at line %d, column %d: %s", je.line, column, je.text);
    return NULL;
}

/* ---- validation ---- */

/* Records the offending key for the caller and gives the error code. */
static int bad(const char **field, const char *key)
{
    if (field) *field = key;
    return -EINVAL;
}

/* "a string", "an object", ... for messages. */
static const char *type_name(const json_t *j)
{
    switch (json_typeof(j)) {
    case JSON_OBJECT: return "an object";
    case JSON_ARRAY: return "an array";
    case JSON_STRING: return "a string";
    case JSON_INTEGER:
    case JSON_REAL: return "a number";
    case JSON_TRUE: return "true";
    case JSON_FALSE: return "false";
    default: return "null";
    }
}

/* One array element: a number, null, or a quoted non-finite word. 0 or -1 (not a number). */
static int element_value(const json_t *e, double *v)
{
    if (json_is_number(e)) *v = json_number_value(e);
    else if (json_is_null(e)) *v = NAN;
    else if (json_is_string(e) && strcmp(json_string_value(e), "NaN") == 0) *v = NAN;
    else if (json_is_string(e) && strcmp(json_string_value(e), "Infinity") == 0) *v = INFINITY;
    else if (json_is_string(e) && strcmp(json_string_value(e), "-Infinity") == 0) *v = -INFINITY;
    else return -1;
    return 0;
}

/* The shortest of %.15g, %.16g, %.17g that reads back as v, into buf (for messages). */
static const char *num_text(double v, char buf[32])
{
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, 32, "%.*g", prec, v);
        if (strtod(buf, NULL) == v) break;
    }
    return buf;
}

/* Reads a required number, root's member key, called name in messages and *field; sign: 1
 * must be > 0, 0 any, -1 must be >= 0. */
static int read_number_as(const json_t *root, const char *key, const char *name, int sign,
                          double *v, const char **field, err_t *err)
{
    const json_t *j = json_object_get(root, key);
    key = name;
    if (!j) return err_set(err, bad(field, key), "missing field %s", key);
    if (json_is_string(j) && element_value(j, v) == 0) /* a quoted or bare NaN, Infinity */
        return err_set(err, bad(field, key), "%s must be a finite number (got %s)", key,
                       json_string_value(j));
    if (!json_is_number(j))
        return err_set(err, bad(field, key), "%s must be a number (got %s)", key, type_name(j));
    *v = json_number_value(j);
    char t[32];
    if (sign > 0 && !(*v > 0))
        return err_set(err, bad(field, key), "%s must be positive (got %s)", key, num_text(*v, t));
    if (sign < 0 && !(*v >= 0))
        return err_set(err, bad(field, key), "%s must not be negative (got %s)", key,
                       num_text(*v, t));
    return 0;
}

static int read_number(const json_t *root, const char *key, int sign, double *v,
                       const char **field, err_t *err)
{
    return read_number_as(root, key, key, sign, v, field, err);
}

/* Reads "frames": a positive integer (an integral real such as 12.0 is accepted). */
static int read_frames(const json_t *root, int *frames, const char **field, err_t *err)
{
    const json_t *j = json_object_get(root, "frames");
    if (!j) return err_set(err, bad(field, "frames"), "missing field frames");
    double v = json_is_number(j) ? json_number_value(j) : NAN;
    if (!(v >= 1 && v <= INT_MAX && v == floor(v))) {
        char t[32];
        if (json_is_number(j))
            return err_set(err, bad(field, "frames"), "frames must be a positive integer (got %s)",
                           num_text(v, t));
        return err_set(err, bad(field, "frames"), "frames must be a positive integer (got %s)",
                       type_name(j));
    }
    *frames = (int)v;
    return 0;
}

/* Reads a required array of numbers into a new buffer (*out owned by the caller; NULL if
 * empty). */
static int read_array(const json_t *root, const char *key, double **out, size_t *n,
                      const char **field, err_t *err)
{
    *out = NULL;
    const json_t *a = json_object_get(root, key);
    if (!a) return err_set(err, bad(field, key), "missing field %s", key);
    if (!json_is_array(a))
        return err_set(err, bad(field, key), "%s must be an array of numbers (got %s)", key,
                       type_name(a));
    *n = json_array_size(a);
    if (*n == 0) return 0;
    double *v = malloc(*n * sizeof *v);
    if (!v) return err_set(err, -ENOMEM, "out of memory reading %s", key);
    for (size_t k = 0; k < *n; k++) {
        const json_t *e = json_array_get(a, k);
        if (element_value(e, &v[k]) < 0) {
            free(v);
            return err_set(err, bad(field, key),
                           "%s must be an array of numbers (element %zu is %s)", key, k,
                           type_name(e));
        }
    }
    *out = v;
    return 0;
}

/* The scalar fields of the contract into s. */
static int read_scalars(const json_t *root, fit_scan_t *s, const char **field, err_t *err)
{
    int rc;
    if ((rc = read_number(root, "pitch_um", 1, &s->pitch_um, field, err)) ||
        (rc = read_number(root, "spot_radius_um", 1, &s->spot_radius_um, field, err)) ||
        (rc = read_number(root, "bias_dn", 0, &s->bias_dn, field, err)) ||
        (rc = read_number(root, "gain_e_per_dn", 1, &s->gain_e_per_dn, field, err)) ||
        (rc = read_number(root, "read_noise_e", -1, &s->read_noise_e, field, err)) ||
        (rc = read_frames(root, &s->frames, field, err)))
        return rc;
    s->full_scale_dn = FIT_FULL_SCALE_DEFAULT; /* optional; null means "not given" too */
    const json_t *fs = json_object_get(root, "full_scale_dn");
    if (fs && !json_is_null(fs))
        return read_number(root, "full_scale_dn", 0, &s->full_scale_dn, field, err);
    return 0;
}

/* The three arrays into out (owned by out on success). */
static int read_arrays(const json_t *root, scanfile_t *out, const char **field, err_t *err)
{
    size_t nx = 0, ny = 0, ns = 0;
    int rc;
    if ((rc = read_array(root, "x_um", &out->x_um, &nx, field, err)) ||
        (rc = read_array(root, "y_um", &out->y_um, &ny, field, err)) ||
        (rc = read_array(root, "signal_dn", &out->signal_dn, &ns, field, err)))
        return rc;
    if (ny != nx)
        return err_set(err, bad(field, "y_um"), "x_um has %zu values but y_um has %zu", nx, ny);
    if (ns != nx)
        return err_set(err, bad(field, "signal_dn"), "x_um has %zu values but signal_dn has %zu",
                       nx, ns);
    out->scan.n = nx;
    out->scan.x_um = out->x_um;
    out->scan.y_um = out->y_um;
    out->scan.signal_dn = out->signal_dn;
    return 0;
}

/* ---- the optional sub-frame (scanfile.h) ---- */

#define SUB "subframe"
#define SUB_DN "subframe.signal_dn"

/* Point k's m*m sub-frame means into dn (m*m); e is the point's array. */
static int read_sub_point(const json_t *e, size_t k, int m, double *dn, const char **field,
                          err_t *err)
{
    size_t mm = (size_t)m * m;
    if (!json_is_array(e))
        return err_set(err, bad(field, SUB_DN),
                       SUB_DN " must hold one array of sub_px^2 = %zu numbers per point (element "
                              "%zu is %s)",
                       mm, k, type_name(e));
    if (json_array_size(e) != mm)
        return err_set(err, bad(field, SUB_DN),
                       SUB_DN "[%zu] has %zu values, not sub_px^2 = %zu (sub_px %d)", k,
                       json_array_size(e), mm, m);
    for (size_t j = 0; j < mm; j++)
        if (element_value(json_array_get(e, j), &dn[j]) < 0)
            return err_set(err, bad(field, SUB_DN),
                           SUB_DN "[%zu] must be an array of numbers (element %zu is %s)", k, j,
                           type_name(json_array_get(e, j)));
    return 0;
}

/* The POI's value of each point's sub-frame is the point's signal_dn (the same number, or both
 * non-finite): a file whose two copies disagree is refused rather than fitted two ways. */
static int check_sub_centre(const scanfile_t *out, int m, const char **field, err_t *err)
{
    size_t mm = (size_t)m * m, c = (size_t)(m / 2) * m + (size_t)(m / 2);
    for (size_t k = 0; k < out->scan.n; k++) {
        double a = out->sub_dn[k * mm + c], b = out->signal_dn[k];
        if (a == b || (!isfinite(a) && !isfinite(b) && (isnan(a) || a == b))) continue;
        char ta[32], tb[32];
        return err_set(err, bad(field, SUB_DN),
                       SUB_DN "[%zu][%zu] (the POI, the centre of the sub-frame) is %s but "
                              "signal_dn[%zu] is %s",
                       k, c, num_text(a, ta), k, num_text(b, tb));
    }
    return 0;
}

/* The optional "subframe" into out (its arrays owned by out); absent or null: none. */
static int read_subframe(const json_t *root, scanfile_t *out, const char **field, err_t *err)
{
    const json_t *sub = json_object_get(root, SUB);
    if (!sub || json_is_null(sub)) return 0;
    if (!json_is_object(sub))
        return err_set(err, bad(field, SUB), SUB " must be an object (got %s)", type_name(sub));
    const json_t *jm = json_object_get(sub, "sub_px");
    if (!jm) return err_set(err, bad(field, SUB ".sub_px"), "missing field " SUB ".sub_px");
    if (!json_is_number(jm))
        return err_set(err, bad(field, SUB ".sub_px"), SUB ".sub_px must be a number (got %s)",
                       type_name(jm));
    int rc = scan_field_check(&scan_fields[SCAN_F_SUB_PX], json_number_value(jm),
                              SUB ".sub_px", err);
    if (rc) return bad(field, SUB ".sub_px");
    int m = (int)json_number_value(jm);
    double step;
    if ((rc = read_number_as(sub, "step_um", SUB ".step_um", 1, &step, field, err))) return rc;
    if (!isfinite(step))
        return err_set(err, bad(field, SUB ".step_um"), SUB ".step_um must be finite");
    const json_t *a = json_object_get(sub, "signal_dn");
    if (!a) return err_set(err, bad(field, SUB_DN), "missing field " SUB_DN);
    if (!json_is_array(a))
        return err_set(err, bad(field, SUB_DN),
                       SUB_DN " must be an array of one array per point (got %s)", type_name(a));
    size_t n = out->scan.n, mm = (size_t)m * m;
    if (json_array_size(a) != n)
        return err_set(err, bad(field, SUB_DN), "x_um has %zu values but " SUB_DN " has %zu", n,
                       json_array_size(a));
    if (n && !(out->sub_dn = malloc(n * mm * sizeof *out->sub_dn)))
        return err_set(err, -ENOMEM, "out of memory reading " SUB_DN);
    for (size_t k = 0; k < n; k++)
        if ((rc = read_sub_point(json_array_get(a, k), k, m, out->sub_dn + k * mm, field, err)))
            return rc;
    if ((rc = check_sub_centre(out, m, field, err))) return rc;
    out->sub_px = m;
    out->sub_step_um = step;
    return 0;
}

int scanfile_parse(const char *buf, size_t len, scanfile_t *out, const char **field, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (field) *field = NULL;
    size_t n_at = quote_nonfinite(buf, len, NULL, NULL), qlen = len + 2 * n_at;
    char *text = malloc(qlen ? qlen : 1);
    size_t *at = malloc((n_at ? n_at : 1) * sizeof *at);
    json_t *root = NULL;
    int rc = 0;
    if (!text || !at) {
        rc = err_set(err, -ENOMEM, "out of memory parsing a scan file");
        goto out;
    }
    quote_nonfinite(buf, len, text, at);
    root = load_quoted(text, qlen, at, n_at, err);
    if (!root) {
        rc = -EINVAL;
        goto out;
    }
    if (!json_is_object(root)) {
        rc = err_set(err, -EINVAL, "a scan file must be a JSON object (got %s)", type_name(root));
        goto out;
    }
    rc = read_scalars(root, &out->scan, field, err);
    if (!rc) rc = read_arrays(root, out, field, err);
    if (!rc) rc = read_subframe(root, out, field, err);
out:
    if (rc) scanfile_free(out);
    json_decref(root);
    free(at);
    free(text);
    return rc;
}

/* Reads all of f into a new buffer (*buf owned by the caller). 0 or -errno. */
static int slurp(FILE *f, char **buf, size_t *len)
{
    size_t cap = 1 << 16, n = 0;
    char *b = malloc(cap);
    if (!b) return -ENOMEM;
    for (;;) {
        n += fread(b + n, 1, cap - n, f);
        if (ferror(f)) {
            int e = errno ? errno : EIO;
            free(b);
            return -e;
        }
        if (n < cap) break;
        char *nb = cap > SIZE_MAX / 2 ? NULL : realloc(b, cap * 2);
        if (!nb) {
            free(b);
            return -ENOMEM;
        }
        b = nb;
        cap *= 2;
    }
    *buf = b;
    *len = n;
    return 0;
}

int scanfile_read(const char *path, scanfile_t *out, const char **field, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (field) *field = NULL;
    FILE *f = fopen(path, "rb");
    if (!f) {
        int e = errno;
        return err_set(err, -e, "%s: %s", path, strerror(e));
    }
    char *buf = NULL;
    size_t len = 0;
    int rc = slurp(f, &buf, &len);
    fclose(f);
    if (rc) return err_set(err, rc, "%s: %s", path, strerror(-rc));
    err_t sub;
    rc = scanfile_parse(buf, len, out, field, &sub);
    free(buf);
    if (rc) return err_set(err, rc, "%s: %s", path, sub.msg);
    return 0;
}

void scanfile_free(scanfile_t *sf)
{
    if (!sf) return;
    free(sf->x_um);
    free(sf->y_um);
    free(sf->signal_dn);
    free(sf->sub_dn);
    memset(sf, 0, sizeof *sf);
}

/* ---- writer ---- */

static const char *const contract_keys[] = {
    "pitch_um", "spot_radius_um", "bias_dn", "gain_e_per_dn", "read_noise_e", "frames",
    "full_scale_dn", "x_um", "y_um", "signal_dn"};

/* A JSON array of n doubles (non-finite as null); NULL when out of memory. Owned by caller. */
static json_t *number_array(const double *v, size_t n)
{
    json_t *a = json_array();
    for (size_t k = 0; a && k < n; k++)
        if (json_array_append_new(a, isfinite(v[k]) ? json_real(v[k]) : json_null())) {
            json_decref(a);
            a = NULL;
        }
    return a;
}

json_t *scanfile_subframe_json(int m, double step_um, const double *dn, size_t n)
{
    size_t mm = (size_t)m * m;
    json_t *a = json_array();
    for (size_t k = 0; a && k < n; k++)
        if (json_array_append_new(a, number_array(dn + k * mm, mm))) {
            json_decref(a);
            a = NULL;
        }
    if (!a) return NULL;
    return json_pack("{s:i, s:f, s:o}", "sub_px", m, "step_um", step_um, "signal_dn", a);
}

/* Adds the scalars and arrays of scan to root; -ENOMEM if jansson could not allocate. */
static int put_scan(json_t *root, const fit_scan_t *s)
{
    const double vals[] = {s->pitch_um, s->spot_radius_um, s->bias_dn, s->gain_e_per_dn,
                           s->read_noise_e};
    int bad_set = 0;
    for (size_t i = 0; i < sizeof vals / sizeof vals[0]; i++)
        bad_set |= json_object_set_new(root, contract_keys[i], json_real(vals[i]));
    bad_set |= json_object_set_new(root, "frames", json_integer(s->frames));
    bad_set |= json_object_set_new(root, "full_scale_dn", json_real(s->full_scale_dn));
    bad_set |= json_object_set_new(root, "x_um", number_array(s->x_um, s->n));
    bad_set |= json_object_set_new(root, "y_um", number_array(s->y_um, s->n));
    bad_set |= json_object_set_new(root, "signal_dn", number_array(s->signal_dn, s->n));
    return bad_set ? -ENOMEM : 0;
}

/* Checks that scan can be written: finite constants, arrays present when n > 0. */
static int check_writable(const fit_scan_t *s, err_t *err)
{
    const double vals[] = {s->pitch_um, s->spot_radius_um, s->bias_dn, s->gain_e_per_dn,
                           s->read_noise_e, s->full_scale_dn};
    const char *names[] = {"pitch_um", "spot_radius_um", "bias_dn", "gain_e_per_dn",
                           "read_noise_e", "full_scale_dn"};
    for (size_t i = 0; i < sizeof vals / sizeof vals[0]; i++)
        if (!isfinite(vals[i])) return err_set(err, -EINVAL, "%s is not finite", names[i]);
    if (s->n && (!s->x_um || !s->y_um || !s->signal_dn))
        return err_set(err, -EINVAL, "scan has %zu points but no arrays", s->n);
    return 0;
}

int scanfile_dump(FILE *f, const fit_scan_t *scan, json_t *extra, err_t *err)
{
    int rc = check_writable(scan, err);
    if (rc) return rc;
    if (extra && !json_is_object(extra))
        return err_set(err, -EINVAL, "scan-file metadata must be a JSON object");
    json_t *root = json_object();
    if (!root) return err_set(err, -ENOMEM, "out of memory writing a scan file");
    const char *key;
    json_t *v;
    json_object_foreach(extra, key, v) {
        for (size_t i = 0; i < sizeof contract_keys / sizeof contract_keys[0]; i++)
            if (strcmp(key, contract_keys[i]) == 0) {
                rc = err_set(err, -EINVAL, "scan-file metadata must not redefine %s", key);
                goto out;
            }
        if (json_object_set(root, key, v)) {
            rc = err_set(err, -ENOMEM, "out of memory writing a scan file");
            goto out;
        }
    }
    if (put_scan(root, scan)) {
        rc = err_set(err, -ENOMEM, "out of memory writing a scan file");
        goto out;
    }
    if (json_dumpf(root, f, JSON_INDENT(1) | JSON_REAL_PRECISION(17)) || fputc('\n', f) == EOF ||
        fflush(f) == EOF)
        rc = err_set(err, -EIO, "writing the scan file failed: %s", strerror(errno));
out:
    json_decref(root);
    return rc;
}

int scanfile_write(const char *path, const fit_scan_t *scan, json_t *extra, err_t *err)
{
    outfile_t o;
    int rc = outfile_open(path, &o, err); /* never replaces a link, a FIFO or a device */
    if (rc) return rc;
    err_t sub;
    rc = scanfile_dump(o.f, scan, extra, &sub);
    if (rc) {
        err_set(err, rc, "%s: %s", path, sub.msg);
        outfile_abort(&o);
        return rc;
    }
    return outfile_commit(&o, err);
}
