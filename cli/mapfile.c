/* mapfile.c: IPS maps from the JSON documents ipsd and ips write (mapfile.h), with jansson. */
#include "mapfile.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

static double num(json_t *o, const char *key)
{
    json_t *x = json_object_get(o, key);
    return json_is_number(x) ? json_number_value(x) : NAN;
}

static int64_t id(json_t *o, const char *key)
{
    json_t *x = json_object_get(o, key);
    return json_is_integer(x) ? (int64_t)json_integer_value(x) : 0;
}

static const char *str(json_t *o, const char *key)
{
    return json_string_value(json_object_get(o, key));
}

/* n numbers of a JSON array (null: NaN) into a new array; NULL when a is not n numbers. */
static double *numbers(json_t *a, size_t n)
{
    if (!json_is_array(a) || json_array_size(a) != n) return NULL;
    double *v = malloc(sizeof(double) * (n ? n : 1));
    for (size_t k = 0; v && k < n; k++) {
        json_t *x = json_array_get(a, k);
        if (json_is_number(x)) {
            v[k] = json_number_value(x);
        } else if (json_is_null(x)) {
            v[k] = NAN;
        } else {
            free(v);
            return NULL;
        }
    }
    return v;
}

/* One map from an object with "S" (and "r", "S_err" and a Calibration's other members). */
static int one_map(json_t *o, const char *what, mapfile_map_t *m, err_t *err)
{
    json_t *S = json_object_get(o, "S");
    size_t n = json_array_size(S);
    int r = json_is_integer(json_object_get(o, "r")) ? (int)id(o, "r") : (int)lround(sqrt(n));
    if (r < 1 || r > 256 || n != (size_t)r * r)
        return err_set(err, -EINVAL, "%s: S must be r*r numbers (r %d, %zu numbers)", what, r, n);
    *m = (mapfile_map_t){.r = r, .current = -1};
    m->S = numbers(S, n);
    json_t *E = json_object_get(o, "S_err");
    m->S_err = E ? numbers(E, n) : malloc(sizeof(double) * n);
    if (!m->S || !m->S_err) {
        free(m->S);
        free(m->S_err);
        return err_set(err, -EINVAL, "%s: S and S_err must be %zu numbers", what, n);
    }
    if (!E)
        for (size_t k = 0; k < n; k++)
            m->S_err[k] = NAN;
    json_t *R = json_object_get(o, "S_res");
    if (R && !json_is_null(R) && !(m->S_res = numbers(R, n))) {
        free(m->S);
        free(m->S_err);
        return err_set(err, -EINVAL, "%s: S_res must be null or %zu numbers", what, n);
    }
    json_t *px = json_object_get(o, "pixel"), *opt = json_object_get(o, "optics");
    m->col = (int)id(px, "col");
    m->row = (int)id(px, "row");
    m->wavelength_um = num(opt, "wavelength_nm") / 1000;
    m->na = num(opt, "na");
    m->spot_radius_um = num(opt, "spot_radius_um");
    m->I0 = num(o, "I0");
    m->chi2_red = num(o, "chi2_red");
    m->status = str(o, "status");
    m->noise_model = str(o, "noise_model");
    m->software_version = str(o, "software_version");
    m->by = str(o, "by");
    m->reason = str(o, "reason");
    m->map = str(o, "map");
    m->id = id(o, "id");
    m->sensor_id = id(o, "sensor_id");
    m->scan_id = id(o, "scan_id");
    m->fit_id = id(o, "fit_id");
    m->created_ms = id(o, "created_ms");
    json_t *cur = json_object_get(o, "current");
    if (json_is_boolean(cur)) m->current = json_is_true(cur);
    return 0;
}

/* The kriged map of an `ips fit --krige` document as a map object of its own (*out, a new
 * reference): r its grid, S and S_err, and the recommended r's fit's I0, chi2_red and status.
 * Returns 0, -EINVAL (the document has none) or -ENOMEM. */
static int kriged_of(json_t *doc, json_t **out, err_t *err)
{
    json_t *k = json_object_get(doc, "kriged_map"), *fits = json_object_get(doc, "fits"), *f;
    if (!json_is_array(json_object_get(k, "S")) || id(k, "grid") < 1) {
        const char *why = str(k, "error");
        return err_set(err, -EINVAL, "the fit document has no kriged map (%s)",
                       why ? why : "fit it with `ips fit --krige`");
    }
    json_t *m = json_pack("{s:I, s:O, s:O}", "r", (json_int_t)id(k, "grid"), "S",
                          json_object_get(k, "S"), "S_err", json_object_get(k, "S_err"));
    size_t i;
    json_array_foreach(fits, i, f) if (m && id(f, "r") == id(doc, "recommended_r"))
    {
        const char *keys[] = {"I0", "chi2_red", "status"};
        for (int j = 0; j < 3; j++)
            if (json_object_get(f, keys[j]))
                json_object_set(m, keys[j], json_object_get(f, keys[j]));
    }
    *out = m;
    return m ? 0 : err_set(err, -ENOMEM, "out of memory");
}

/* The fit of r (0: recommended_r, else the best BIC; MAPFILE_SHRUNK: the shrunk map) of an
 * `ips fit` document. */
static json_t *fit_of(json_t *doc, int r, err_t *err)
{
    if (r == MAPFILE_SHRUNK) {
        json_t *sh = json_object_get(doc, "shrunk_map");
        if (json_is_object(sh) && json_is_array(json_object_get(sh, "S"))) return sh;
        err_set(err, -EINVAL, "the fit document has no shrunk map (its recommended r is 1, or r - "
                              "1 has no map)");
        return NULL;
    }
    if (r <= 0) r = (int)id(doc, "recommended_r");
    if (r <= 0) r = (int)id(json_object_get(doc, "best_r"), "bic");
    json_t *fits = json_object_get(doc, "fits"), *f;
    size_t k;
    json_array_foreach(fits, k,
                       f) if (id(f, "r") == r && json_is_array(json_object_get(f, "S"))) return f;
    err_set(err, -EINVAL, "the fit document has no map at r = %d", r);
    return NULL;
}

int mapfile_read(const char *path, int r, mapfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    json_error_t je;
    json_t *doc = json_load_file(path, 0, &je);
    if (!doc) {
        FILE *f = fopen(path, "r");
        if (!f) return err_set(err, -ENOENT, "%s: cannot open", path);
        fclose(f);
        return err_set(err, -EINVAL, "%s: line %d: %s", path, je.line, je.text);
    }
    out->doc = doc;
    json_t *items = json_object_get(doc, "items"), *single = doc, *bare = NULL;
    size_t n = 1;
    if (json_is_array(items)) {
        n = json_array_size(items);
        if (n == 0) return err_set(err, -EINVAL, "%s: items is empty", path);
    } else if (json_is_array(json_object_get(doc, "fits")) && r == MAPFILE_KRIGED) {
        int ret = kriged_of(doc, &bare, err);
        if (ret) return ret;
        single = bare;
    } else if (json_is_array(json_object_get(doc, "fits"))) {
        if (!(single = fit_of(doc, r, err))) return -EINVAL;
    } else if (json_is_array(doc)) {
        bare = json_pack("{s:O}", "S", doc);
        single = bare;
    } else if (!json_is_object(doc)) {
        return err_set(err, -EINVAL, "%s: not a map, calibration or fit document", path);
    }
    out->maps = calloc(n, sizeof *out->maps);
    if (!out->maps) {
        json_decref(bare);
        return err_set(err, -ENOMEM, "out of memory");
    }
    int ret = 0;
    for (size_t k = 0; k < n && !ret; k++) {
        json_t *o = json_is_array(items) ? json_array_get(items, k) : single;
        char what[64] = "map";
        if (json_is_array(items)) snprintf(what, sizeof what, "items[%zu]", k);
        ret = one_map(o, what, &out->maps[k], err);
        if (!ret) out->n++;
    }
    if (!ret && r == MAPFILE_KRIGED && bare) out->maps[0].map = "kriged";
    if (!ret && single != doc && !bare) { /* an `ips fit` document's map: which one */
        out->maps[0].map = r == MAPFILE_SHRUNK                             ? "shrunk"
                           : id(single, "r") == id(doc, "recommended_r") ? "recommended"
                                                                           : NULL;
        /* a fit's own map has the shrunk map's resolution error when they share the grid */
        json_t *sh = json_object_get(doc, "shrunk_map"), *R = json_object_get(sh, "S_res");
        mapfile_map_t *m = &out->maps[0];
        if (!m->S_res && id(sh, "r") == m->r && json_is_array(R) &&
            !(m->S_res = numbers(R, (size_t)m->r * m->r)))
            ret = err_set(err, -EINVAL, "%s: shrunk_map.S_res must be %d numbers", path,
                          m->r * m->r);
    }
    json_decref(bare);
    return ret;
}

void mapfile_free(mapfile_t *mf)
{
    if (!mf) return;
    for (size_t k = 0; k < mf->n; k++) {
        free(mf->maps[k].S);
        free(mf->maps[k].S_err);
        free(mf->maps[k].S_res);
    }
    free(mf->maps);
    json_decref(mf->doc);
    memset(mf, 0, sizeof *mf);
}
