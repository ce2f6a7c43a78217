/* ftest.c: the paper's F-test (section IV): is the structure in the pixel centre real?
 * H1 is the full r x r model (p1 = r*r + 1); H0 keeps a free S_ij for each sub-pixel on the named
 * edges and one shared S0 for all others (p0 = edge sub-pixels + 2). Both are linear in their
 * parameters, so both chi2 are exact global minima. F = ((chi2_0 - chi2_1) / chi2_1)
 * ((N - p1) / (p1 - p0)) (eq. 6), p-value = upper tail of F(p1 - p0, N - p1) from GSL. */
#include <errno.h>
#include <gsl/gsl_cdf.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/model.h"
#include "fit/gslerr.h"
#include "wls.h"

static const struct {
    const char *name;
    unsigned bit;
} edge_names[] = {{"top", FIT_EDGE_TOP}, {"left", FIT_EDGE_LEFT},
                  {"bottom", FIT_EDGE_BOTTOM}, {"right", FIT_EDGE_RIGHT}};

int fit_edges_parse(const char *list, unsigned *mask, err_t *err)
{
    *mask = 0;
    if (!list || !*list) return err_set(err, -EINVAL, "F-test edges are empty (want e.g. top,left,bottom)");
    const char *s = list;
    while (*s) {
        size_t len = strcspn(s, ",");
        unsigned bit = 0;
        for (size_t i = 0; i < sizeof edge_names / sizeof edge_names[0]; i++)
            if (strlen(edge_names[i].name) == len && strncmp(s, edge_names[i].name, len) == 0)
                bit = edge_names[i].bit;
        if (!bit)
            return err_set(err, -EINVAL, "unknown edge '%.*s' (edges are top, left, bottom, right)",
                           (int)len, s);
        *mask |= bit;
        s += len;
        if (*s == ',') s++;
    }
    return 0;
}

/* 1 if sub-pixel (i, j) (column i, row j; row 0 at the top) touches a named edge */
static int on_edge(int i, int j, int r, unsigned edges)
{
    return ((edges & FIT_EDGE_TOP) && j == 0) || ((edges & FIT_EDGE_BOTTOM) && j == r - 1) ||
           ((edges & FIT_EDGE_LEFT) && i == 0) || ((edges & FIT_EDGE_RIGHT) && i == r - 1);
}

/* chi2 of H0: columns of the edge sub-pixels kept, all others summed into the S0 column. */
static int chi2_h0(const fit_scan_t *scan, const fit_result_t *h1, int r, unsigned edges,
                   const fit_options_t *o, double *chi2, int *p0, err_t *err)
{
    size_t m = (size_t)r * r, n = 0, m0 = 0;
    int *col = malloc(sizeof(int) * m);
    double *X = NULL, *w = NULL, *y = NULL, *c = NULL, *A = NULL;
    int rc = -ENOMEM;
    if (!col) goto out;
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) col[j * r + i] = on_edge(i, j, r, edges) ? (int)m0++ : -1;
    size_t s0 = m0++; /* the shared column */
    for (size_t j = 0; j < m; j++)
        if (col[j] < 0) col[j] = (int)s0;
    *p0 = (int)m0 + 1;
    size_t nn = scan->n ? scan->n : 1;
    A = malloc(sizeof(double) * nn * m);
    X = calloc(nn * m0, sizeof(double));
    w = malloc(sizeof(double) * nn);
    y = malloc(sizeof(double) * nn);
    c = malloc(sizeof(double) * m0);
    double *xs = malloc(sizeof(double) * 2 * nn);
    if (!A || !X || !w || !y || !c || !xs) {
        free(xs);
        goto out;
    }
    for (size_t k = 0; k < scan->n; k++) { /* the points H1 used: those with a model value */
        if (!isfinite(h1->model_dn[k])) continue;
        double sg = fit_noise_sigma(o->noise, scan, scan->signal_dn[k]);
        sg = fmax(sg, sqrt(1.0 / 12 / scan->frames));
        xs[n] = scan->x_um[k];
        xs[nn + n] = scan->y_um[k];
        w[n] = 1 / (sg * sg);
        y[n] = scan->signal_dn[k] - scan->bias_dn;
        n++;
    }
    fit_design_opts_t d = fit_design_opts_for_tol(o->design_tol > 0 ? o->design_tol : 1e-12);
    d.cache = o->design_cache; /* the sweep's sweeps at this r: only the assembly is left */
    d.stop = o->stop;
    rc = fit_design_build(scan->spot_radius_um, scan->pitch_um, r, xs, xs + nn, n, &d, A, NULL, err);
    free(xs);
    if (rc) goto out;
    for (size_t k = 0; k < n; k++)
        for (size_t j = 0; j < m; j++) X[k * m0 + (size_t)col[j]] += A[k * m + j];
    wls_result_t res;
    if ((rc = wls_solve(X, w, y, n, m0, o->nonneg, c, NULL, &o->stop, &res)) == 0)
        *chi2 = res.chi2;
    else if (rc == -ECANCELED)
        err_set(err, rc, "fit stopped in the F-test's solve");
out:
    free(col);
    free(A);
    free(X);
    free(w);
    free(y);
    free(c);
    return rc;
}

int fit_ftest_with_h1(const fit_scan_t *scan, const fit_result_t *h1, unsigned edges,
                      const fit_options_t *opts, fit_ftest_t *out, err_t *err)
{
    fit_gsl_policy();
    memset(out, 0, sizeof *out);
    out->r = h1->r;
    out->edges = edges;
    out->F = out->p_value = out->chi2_h0 = NAN;
    fit_options_t o = opts ? *opts : fit_options_default();
    o.method = FIT_LINEAR; /* both hypotheses at their exact minima */
    if (!edges) return err_set(err, -EINVAL, "the F-test needs at least one edge");
    out->flags = h1->flags;
    out->n = h1->n_used;
    out->params_h1 = h1->params;
    out->chi2_h1 = h1->chi2;
    if (!h1->S || !h1->model_dn)
        return err_set(err, -EDOM, "the F-test needs a full r = %d fit, which has status %s",
                       h1->r, fit_status_name(h1->flags));
    int rc = chi2_h0(scan, h1, h1->r, edges, &o, &out->chi2_h0, &out->params_h0, err);
    if (rc) return rc;
    int d1 = out->params_h1 - out->params_h0, d2 = (int)out->n - out->params_h1;
    if (d1 < 1 || d2 < 1)
        return err_set(err, -EDOM, "the F-test needs N > p1 > p0 (N = %zu, p1 = %d, p0 = %d)",
                       out->n, out->params_h1, out->params_h0);
    out->F = ((out->chi2_h0 - out->chi2_h1) / out->chi2_h1) * ((double)d2 / d1); /* eq. 6 */
    out->p_value = fit_ftest_p_value(out->F, d1, d2);
    return 0;
}

double fit_ftest_p_value(double F, int d1, int d2)
{
    fit_gsl_policy();
    if (isnan(F) || d1 < 1 || d2 < 1) return NAN;
    return gsl_cdf_fdist_Q(F, d1, d2);
}

int fit_ftest_run(const fit_scan_t *scan, int r, unsigned edges, const fit_options_t *opts,
                  fit_ftest_t *out, err_t *err)
{
    fit_gsl_policy();
    fit_options_t o = opts ? *opts : fit_options_default();
    o.method = FIT_LINEAR;
    memset(out, 0, sizeof *out);
    out->r = r;
    out->edges = edges;
    out->F = out->p_value = out->chi2_h0 = out->chi2_h1 = NAN;
    if (!edges) return err_set(err, -EINVAL, "the F-test needs at least one edge");
    fit_result_t h1;
    int rc = fit_map(scan, r, &o, &h1, err);
    if (rc) return rc;
    rc = fit_ftest_with_h1(scan, &h1, edges, &o, out, err);
    fit_result_free(&h1);
    return rc;
}
