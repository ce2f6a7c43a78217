/* jitterjson.c: the jitter-photometry document (jitterjson.h): fit/jitter.h's prediction and
 * correction, as JSON. Non-finite numbers become null (JSON has no NaN). */
#include "json/jitterjson.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static json_t *num(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

const char *jitterjson_psf_name(fit_psf_kind_t kind)
{
    return kind == FIT_PSF_GAUSS ? "gauss" : "airy";
}

int jitterjson_psf_parse(const char *name, fit_psf_kind_t *kind, err_t *err)
{
    if (strcmp(name, "airy") == 0)
        *kind = FIT_PSF_AIRY;
    else if (strcmp(name, "gauss") == 0)
        *kind = FIT_PSF_GAUSS;
    else
        return err_set(err, -EINVAL, "psf must be airy or gauss (got '%s')", name);
    return 0;
}

int jitterjson_run(const fit_jitter_setup_t *s, const double *dx, const double *dy, size_t n,
                   const double *measured, int with_samples, json_t **out, err_t *err)
{
    *out = NULL;
    double *buf = malloc(sizeof(double) * 3 * (n ? n : 1));
    if (!buf) return err_set(err, -ENOMEM, "out of memory for %zu samples", n);
    double *rho = buf, *rel = buf + n, *cor = buf + 2 * n;
    fit_jitter_stats_t st;
    int ret = fit_jitter_run(s, dx, dy, n, rho, rel, &st, err);
    if (!ret && measured) ret = fit_jitter_correct(measured, rho, n, cor, err);
    if (ret) {
        free(buf);
        return ret;
    }
    json_t *pixels = json_array();
    for (size_t p = 0; pixels && p < s->n_pixels; p++) {
        const fit_jitter_pixel_t *px = &s->pixels[p];
        json_array_append_new(pixels,
                              json_pack("{s:i, s:i, s:o}", "dcol", px->dcol, "drow", px->drow, "r",
                                        px->S ? json_integer(px->r) : json_null()));
    }
    json_t *doc = json_pack(
        "{s:{s:s, s:o}, s:o, s:{s:o, s:o}, s:o, s:I, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o}",
        "psf", "kind", jitterjson_psf_name(s->psf.kind), "width_um", num(s->psf.width_um),
        "pitch_um", num(s->pitch_um), "position_um", "x", num(s->x0_um), "y", num(s->y0_um),
        "pixels", pixels ? pixels : json_null(), "n", (json_int_t)n, "rho0", num(st.rho0), "flux0",
        num(st.flux0), "flat0", num(st.flat0), "err_mean", num(st.err_mean), "err_rms",
        num(st.err_rms), "err_max", num(st.err_max), "rho_mean", num(st.rho_mean), "rho_scatter",
        num(st.rho_scatter), "flat_scatter", num(st.flat_scatter));
    if (doc && (with_samples || measured)) {
        json_t *samples = json_array();
        for (size_t k = 0; samples && k < n; k++) {
            json_t *o = json_pack("{s:o, s:o, s:o, s:o}", "dx_um", num(dx[k]), "dy_um", num(dy[k]),
                                  "rho", num(rho[k]), "rel_err", num(rel[k]));
            if (o && measured) {
                json_object_set_new(o, "measured", num(measured[k]));
                json_object_set_new(o, "corrected", num(cor[k]));
            }
            json_array_append_new(samples, o);
        }
        json_object_set_new(doc, "samples", samples ? samples : json_null());
    }
    free(buf);
    if (!doc) return err_set(err, -ENOMEM, "out of memory for the jitter document");
    *out = doc;
    return 0;
}
