/* scene.c: the simulated bench's sensor and sensitivity maps (see scene.h): the built-in uniform
 * and paperlike scenes, maps read from JSON files, and the exact sub-pixel truth. */
#include "instrument/scene.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_integration.h>
#include <jansson.h>

#include "fit/gslerr.h"

struct scene {
    scene_sensor_t sensor;
    char name[128];
    int m;
    double *map; /* m*m */
    scene_stats_t stats;
};

scene_sensor_t scene_sensor_default(void)
{
    return (scene_sensor_t){.cols = 256,
                            .rows = 256,
                            .pitch_um = 6.0,
                            .gain_e_per_dn = 3.153,
                            .read_noise_e = 5.67,
                            .bias_dn = 100.0,
                            .full_scale_dn = 16383.0,
                            .full_well_e = 60000.0};
}

int scene_sensor_check(const scene_sensor_t *s, err_t *err)
{
    if (s->cols < 1 || s->rows < 1 || s->cols > 100000 || s->rows > 100000)
        return err_set(err, -EINVAL, "sensor size must be 1..100000 pixels a side (got %d x %d)",
                       s->cols, s->rows);
    if (!(s->pitch_um > 0) || !isfinite(s->pitch_um))
        return err_set(err, -EINVAL, "sensor pitch must be positive (got %g um)", s->pitch_um);
    if (!(s->gain_e_per_dn > 0) || !isfinite(s->gain_e_per_dn))
        return err_set(err, -EINVAL, "sensor gain must be positive (got %g e-/DN)",
                       s->gain_e_per_dn);
    if (!(s->read_noise_e >= 0) || !isfinite(s->read_noise_e))
        return err_set(err, -EINVAL, "read noise must be >= 0 (got %g e-)", s->read_noise_e);
    if (!(s->full_scale_dn >= 1 && s->full_scale_dn <= 65535))
        return err_set(err, -EINVAL, "ADC full scale must be in 1..65535 DN (got %g)",
                       s->full_scale_dn);
    if (!(s->bias_dn >= 0 && s->bias_dn < s->full_scale_dn))
        return err_set(err, -EINVAL, "bias must be in [0, full scale) (got %g DN)", s->bias_dn);
    if (!(s->full_well_e > 0) || !isfinite(s->full_well_e))
        return err_set(err, -EINVAL, "full well must be positive (got %g e-)", s->full_well_e);
    return 0;
}

static void compute_stats(scene_t *s)
{
    int n = s->m * s->m;
    double cell = s->sensor.pitch_um * s->sensor.pitch_um / n, sum = 0, mx = 0;
    for (int c = 0; c < n; c++) {
        sum += s->map[c];
        if (s->map[c] > mx) mx = s->map[c];
    }
    double mean = sum / n, l1 = 0, md = 0;
    for (int c = 0; c < n; c++) {
        double d = fabs(s->map[c] - mean);
        l1 += d * cell;
        if (d > md) md = d;
    }
    s->stats = (scene_stats_t){.mean = mean, .max = mx, .l1_dev = l1, .max_dev = md};
}

int scene_open_map(const double *map, int m, const scene_sensor_t *sensor, const char *name,
                   scene_t **out, err_t *err)
{
    fit_gsl_policy(); /* GSL reports failures by return code, never by abort() */
    *out = NULL;
    int rc = scene_sensor_check(sensor, err);
    if (rc) return rc;
    if (m < 1 || m > SCENE_MAX_RES)
        return err_set(err, -EINVAL, "map resolution must be 1..%d (got %d)", SCENE_MAX_RES, m);
    int any = 0;
    for (int c = 0; c < m * m; c++) {
        if (!isfinite(map[c]) || map[c] < 0)
            return err_set(err, -EINVAL,
                           "map value %d is %g: sensitivities must be finite and >= 0", c, map[c]);
        any |= map[c] > 0;
    }
    if (!any) return err_set(err, -EINVAL, "map is zero everywhere: the pixel sees nothing");
    scene_t *s = calloc(1, sizeof *s);
    if (s) s->map = malloc(sizeof(double) * (size_t)m * m);
    if (!s || !s->map) {
        free(s);
        return err_set(err, -ENOMEM, "out of memory for a %d x %d map", m, m);
    }
    s->sensor = *sensor;
    s->m = m;
    memcpy(s->map, map, sizeof(double) * (size_t)m * m);
    snprintf(s->name, sizeof s->name, "%s", name ? name : "map");
    compute_stats(s);
    *out = s;
    return 0;
}

/* A family's map: cell means of its function by 8 x 8 Gauss-Legendre per cell (accurate to
 * ~1e-12 where the function is smooth on a cell; on the cells a sharp family's step crosses, a
 * close estimate. Either way the m x m map is the scene: simulator and truth both use it). */
static int family_map(scene_fn fn, int m, double p, double **out, err_t *err)
{
    double *map = malloc(sizeof(double) * (size_t)m * m);
    gsl_integration_glfixed_table *gl = gsl_integration_glfixed_table_alloc(8);
    if (!map || !gl) {
        free(map);
        gsl_integration_glfixed_table_free(gl);
        return err_set(err, -ENOMEM, "out of memory for a %d x %d map", m, m);
    }
    double h = p / m, xg[8], wg[8];
    for (int k = 0; k < 8; k++)
        gsl_integration_glfixed_point(0, h, (size_t)k, &xg[k], &wg[k], gl);
    for (int j = 0; j < m; j++)
        for (int i = 0; i < m; i++) {
            double acc = 0;
            for (int b = 0; b < 8; b++)
                for (int a = 0; a < 8; a++)
                    acc += wg[a] * wg[b] * fn(i * h + xg[a], j * h + xg[b], p);
            map[j * m + i] = acc / (h * h);
        }
    gsl_integration_glfixed_table_free(gl);
    *out = map;
    return 0;
}

/* Reads a map file: {"S": [...], "r": m} (r optional) or a bare array of m*m numbers. */
static int read_map_file(const char *path, double **out, int *m_out, err_t *err)
{
    json_error_t je;
    json_t *root = json_load_file(path, 0, &je), *arr = root;
    if (!root) {
        FILE *f = fopen(path, "r");
        if (!f) return err_set(err, -ENOENT, "map file %s: cannot open it", path);
        fclose(f);
        return err_set(err, -EINVAL, "map file %s: line %d column %d: %s", path, je.line, je.column,
                       je.text);
    }
    int rc = 0;
    double *map = NULL;
    if (json_is_object(root)) arr = json_object_get(root, "S");
    if (!json_is_array(arr)) {
        rc = err_set(err, -EINVAL,
                     "map file %s: expected an array of numbers or an object with "
                     "an array \"S\"",
                     path);
        goto out;
    }
    size_t n = json_array_size(arr);
    int m = (int)lround(sqrt((double)n));
    if (n == 0 || (size_t)m * (size_t)m != n || m > SCENE_MAX_RES) {
        rc = err_set(err, -EINVAL, "map file %s: %zu values is not m*m for m in 1..%d", path, n,
                     SCENE_MAX_RES);
        goto out;
    }
    json_t *r = json_is_object(root) ? json_object_get(root, "r") : NULL;
    if (r && (!json_is_integer(r) || json_integer_value(r) != m)) {
        rc = err_set(err, -EINVAL, "map file %s: \"r\" does not match the %zu values of \"S\"",
                     path, n);
        goto out;
    }
    map = malloc(sizeof(double) * n);
    if (!map) {
        rc = err_set(err, -ENOMEM, "out of memory for map file %s", path);
        goto out;
    }
    for (size_t k = 0; k < n; k++) {
        json_t *v = json_array_get(arr, k);
        if (!json_is_number(v)) {
            rc = err_set(err, -EINVAL, "map file %s: value %zu is not a number", path, k);
            goto out;
        }
        map[k] = json_number_value(v);
    }
    *out = map;
    *m_out = m;
    map = NULL;
out:
    free(map);
    json_decref(root);
    return rc;
}

int scene_open(const char *spec, const scene_sensor_t *sensor, scene_t **out, err_t *err)
{
    fit_gsl_policy(); /* GSL reports failures by return code, never by abort() */
    *out = NULL;
    if (!spec) spec = "paperlike";
    int rc = scene_sensor_check(sensor, err);
    if (rc) return rc;
    if (strcmp(spec, "uniform") == 0) {
        double one = 1.0;
        return scene_open_map(&one, 1, sensor, "uniform", out, err);
    }
    double *map = NULL;
    int m = 0;
    char name[128];
    size_t len = strcspn(spec, ":");
    scene_fn fn = scene_family(spec, len);
    if (fn) { /* NAME or NAME:M */
        m = SCENE_FAMILY_RES;
        if (spec[len] == ':') {
            char *end;
            long v = strtol(spec + len + 1, &end, 10);
            if (end == spec + len + 1 || *end || v < 1 || v > SCENE_MAX_RES)
                return err_set(err, -EINVAL, "scene %s: the resolution after ':' must be 1..%d",
                               spec, SCENE_MAX_RES);
            m = (int)v;
        }
        rc = family_map(fn, m, sensor->pitch_um, &map, err);
        snprintf(name, sizeof name, "%.*s", (int)len, spec);
    } else if (strncmp(spec, "map:", 4) == 0 && spec[4]) {
        rc = read_map_file(spec + 4, &map, &m, err);
        snprintf(name, sizeof name, "%.120s", spec);
    } else {
        return err_set(err, -EINVAL,
                       "unknown scene '%s' (uniform, paperlike, gradient, dip, deadcorner, edge, "
                       "softedge, ring, busline, diagedge, bowl, twodips [:M], or map:FILE)",
                       spec);
    }
    if (rc == 0) rc = scene_open_map(map, m, sensor, name, out, err);
    free(map);
    return rc;
}

void scene_close(scene_t *s)
{
    if (!s) return;
    free(s->map);
    free(s);
}

const scene_sensor_t *scene_sensor(const scene_t *s)
{
    return &s->sensor;
}
const char *scene_name(const scene_t *s)
{
    return s->name;
}
const scene_stats_t *scene_stats(const scene_t *s)
{
    return &s->stats;
}

const double *scene_map(const scene_t *s, int *m)
{
    if (m) *m = s->m;
    return s->map;
}

/* o[I*m + i] = length of [I/r, (I+1)/r] intersected with [i/m, (i+1)/m], in units of the pitch. */
static void overlaps(int r, int m, double *o)
{
    for (int I = 0; I < r; I++)
        for (int i = 0; i < m; i++) {
            double lo = fmax((double)I / r, (double)i / m),
                   hi = fmin((double)(I + 1) / r, (double)(i + 1) / m);
            o[I * m + i] = hi > lo ? hi - lo : 0;
        }
}

int scene_truth(const scene_t *s, int r, double *S, err_t *err)
{
    if (r < 1 || r > SCENE_MAX_RES)
        return err_set(err, -EINVAL, "truth resolution r must be 1..%d (got %d)", SCENE_MAX_RES, r);
    int m = s->m;
    double *o = malloc(sizeof(double) * (size_t)r * m), *t = malloc(sizeof(double) * (size_t)r * m);
    if (!o || !t) {
        free(o);
        free(t);
        return err_set(err, -ENOMEM, "out of memory for the r = %d truth", r);
    }
    overlaps(r, m, o);
    /* the sub-pixel mean is separable: S_r = O S O^T / (1/r)^2, O the 1-D overlap matrix */
    for (int j = 0; j < m; j++)
        for (int I = 0; I < r; I++) {
            double acc = 0;
            for (int i = 0; i < m; i++)
                acc += s->map[j * m + i] * o[I * m + i];
            t[j * r + I] = acc;
        }
    for (int J = 0; J < r; J++)
        for (int I = 0; I < r; I++) {
            double acc = 0;
            for (int j = 0; j < m; j++)
                acc += o[J * m + j] * t[j * r + I];
            S[J * r + I] = acc * r * r;
        }
    free(o);
    free(t);
    return 0;
}
