/* region.c: selecting a scan's points by region (see region.h). */
#include "fit/region.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define EDGE_REL_TOL 1e-6 /* of the pitch: as scan_pixel_coords (instrument/scan.h) */

const char *fit_region_name(fit_region_kind_t kind)
{
    switch (kind) {
    case FIT_REGION_INSIDE: return "inside";
    case FIT_REGION_ALL: return "all";
    case FIT_REGION_MARGIN: return "margin";
    }
    return "unknown";
}

int fit_region_parse(const char *name, double margin_um, fit_region_t *out, err_t *err)
{
    *out = (fit_region_t){FIT_REGION_INSIDE, 0};
    if (!name) return err_set(err, -EINVAL, "region must be inside, all or margin (got nothing)");
    if (strcmp(name, "inside") == 0) return 0;
    if (strcmp(name, "all") == 0) {
        out->kind = FIT_REGION_ALL;
        return 0;
    }
    if (strcmp(name, "margin") != 0)
        return err_set(err, -EINVAL, "region must be inside, all or margin (got '%s')", name);
    if (!isfinite(margin_um) || margin_um < 0 || margin_um > FIT_REGION_MARGIN_MAX)
        return err_set(err, -EINVAL, "region margin must be between 0 and %g um (got %g)",
                       FIT_REGION_MARGIN_MAX, margin_um);
    *out = (fit_region_t){FIT_REGION_MARGIN, margin_um};
    return 0;
}

int fit_region_contains(const fit_region_t *rg, double p, double x, double y)
{
    double eps = EDGE_REL_TOL * p;
    if (!isfinite(x) || !isfinite(y)) return 1; /* the fit counts them (region.h) */
    switch (rg ? rg->kind : FIT_REGION_INSIDE) {
    case FIT_REGION_ALL: return 1;
    case FIT_REGION_MARGIN: {
        double lo = -rg->margin_um - eps, hi = p + rg->margin_um + eps;
        return x >= lo && x <= hi && y >= lo && y <= hi;
    }
    case FIT_REGION_INSIDE: break;
    }
    return x > eps && x < p - eps && y > eps && y < p - eps;
}

void fit_scan_sel_free(fit_scan_sel_t *sel)
{
    if (!sel) return;
    free(sel->x);
    free(sel->y);
    free(sel->s);
    memset(sel, 0, sizeof *sel);
}

int fit_region_select(const fit_scan_t *in, const fit_region_t *rg, fit_scan_sel_t *out,
                      err_t *err)
{
    memset(out, 0, sizeof *out);
    if (!in || (in->n && (!in->x_um || !in->y_um || !in->signal_dn)))
        return err_set(err, -EINVAL, "region: no scan data");
    if (rg && (unsigned)rg->kind > FIT_REGION_MARGIN)
        return err_set(err, -EINVAL, "region: unknown kind %d", (int)rg->kind);
    size_t n = 0, cap = in->n ? in->n : 1;
    out->x = malloc(sizeof(double) * cap);
    out->y = malloc(sizeof(double) * cap);
    out->s = malloc(sizeof(double) * cap);
    if (!out->x || !out->y || !out->s) {
        fit_scan_sel_free(out);
        return err_set(err, -ENOMEM, "region: out of memory for %zu points", in->n);
    }
    for (size_t k = 0; k < in->n; k++) {
        if (!fit_region_contains(rg, in->pitch_um, in->x_um[k], in->y_um[k])) continue;
        out->x[n] = in->x_um[k];
        out->y[n] = in->y_um[k];
        out->s[n++] = in->signal_dn[k];
    }
    out->scan = *in;
    out->scan.n = n;
    out->scan.x_um = out->x;
    out->scan.y_um = out->y;
    out->scan.signal_dn = out->s;
    return 0;
}
