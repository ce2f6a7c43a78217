/* geometry.c: the spot radius and the scan-grid offset fitted with the map by variable projection
 * (geometry.h): LM over (R, dx, dy) on the residuals of the linear solution for T, then the
 * whole-problem covariance at the optimum.
 *
 * Why LM on the projected residual vector and not a simplex on chi2: the residual vector is
 * smooth in (R, dx, dy) (the design entries are integrals of a smooth kernel), so Gauss-Newton
 * steps converge in a handful of iterations of 7 design matrices each (one residual, six for the
 * central-difference Jacobian), where Nelder-Mead needs tens of chi2 values and gives no curvature.
 * The Jacobian is our own central difference with steps fixed in micrometres rather than GSL's
 * built-in one, whose step is proportional to the parameter and collapses for an offset near 0. */
#include "fit/geometry.h"

#include <errno.h>
#include <gsl/gsl_blas.h>
#include <gsl/gsl_cdf.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_linalg.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/design.h"
#include "fit/gslerr.h"
#include "fit/noise.h"
#include "points.h"
#include "wls.h"

#define MAX_ITER 100
#define BOUND_FRAC 0.99   /* |tanh u| beyond: the parameter sits on its bound */
#define RANK_TOL 1e-12    /* singular values of the balanced Jacobian below this times the largest */
#define STEP_REL 1e-4     /* central-difference steps: R * STEP_REL, offsets pitch * STEP_REL */

const char *fit_geometry_status(unsigned flags)
{
    if (flags & FIT_GEOMETRY_NOT_CONVERGED) return "not_converged";
    if (flags & FIT_GEOMETRY_AT_BOUND) return "at_bound";
    if (flags & FIT_GEOMETRY_ILL_CONDITIONED) return "ill_conditioned";
    if (flags & FIT_GEOMETRY_POOR_FIT) return "poor_fit";
    return "ok";
}

/* The problem: the usable points and the work buffers. */
struct geo {
    int r;
    size_t n, m;
    double *x, *y, *d, *sw;  /* positions, signal - bias, sqrt of the weight 1/sigma^2 */
    double *xs, *ys, *A, *T; /* shifted positions, design (n x m), linear solution (m) */
    double pitch;
    fit_design_opts_t dopt;
    double c[3], h[3];       /* p_i = c_i + h_i tanh(u_i): R, dx, dy */
    double step[3];          /* central-difference steps in R, dx, dy (um) */
    int evals;
    int rc;                  /* first failure inside a GSL callback */
    err_t err;
};

static void geo_free(struct geo *g)
{
    free(g->x);
    free(g->xs);
    free(g->A);
    free(g->T);
}

/* The usable points, selected and weighted exactly as fit_map does (points.h: finite, below full
 * scale, sigma from the noise model floored at the rounding of whole DN). */
static int geo_init(const fit_scan_t *scan, int r, const fit_options_t *o, struct geo *g)
{
    size_t nn = scan->n ? scan->n : 1;
    memset(g, 0, sizeof *g);
    g->r = r;
    g->m = (size_t)r * r;
    g->pitch = scan->pitch_um;
    g->x = malloc(sizeof(double) * 4 * nn);
    g->xs = malloc(sizeof(double) * 2 * nn);
    g->A = malloc(sizeof(double) * nn * g->m);
    g->T = malloc(sizeof(double) * g->m);
    if (!g->x || !g->xs || !g->A || !g->T) return -ENOMEM;
    g->y = g->x + nn;
    g->d = g->y + nn;
    g->sw = g->d + nn;
    g->ys = g->xs + nn;
    fit_points_t p;
    size_t nonfinite, saturated;
    if (fit_points_select(scan, o->noise, &p, &nonfinite, &saturated)) {
        fit_points_free(&p);
        return -ENOMEM;
    }
    for (size_t k = 0; k < p.n; k++) {
        g->x[k] = p.x[k];
        g->y[k] = p.y[k];
        g->d[k] = p.d[k];
        g->sw[k] = 1 / p.sigma[k];
    }
    g->n = p.n;
    fit_points_free(&p);
    g->dopt = fit_design_opts_for_tol(o->design_tol > 0 ? o->design_tol : 1e-12);
    g->dopt.stop = o->stop; /* every residual builds a design matrix: it polls the stop */
    double R = scan->spot_radius_um;
    g->c[0] = 1.25 * R, g->h[0] = 0.75 * R; /* R in [R/2, 2R] */
    g->c[1] = g->c[2] = 0, g->h[1] = g->h[2] = scan->pitch_um; /* |dx|, |dy| <= pitch */
    g->step[0] = STEP_REL * R;
    g->step[1] = g->step[2] = STEP_REL * scan->pitch_um;
    return 0;
}

/* The stop poll of the geometry fit's own loops (stop.h's site "geometry"; the design matrix
 * polls inside its batches, the solve after itself). */
static int geo_stop(struct geo *g)
{
    return fit_stop_at(&g->dopt.stop, FIT_STOP_SITE_GEOMETRY);
}

/* The design matrix at geometry p = (R, dx, dy) into g->A. */
static int geo_design(struct geo *g, const double p[3])
{
    for (size_t k = 0; k < g->n; k++) {
        g->xs[k] = g->x[k] + p[1];
        g->ys[k] = g->y[k] + p[2];
    }
    g->evals++;
    return fit_design_build(p[0], g->pitch, g->r, g->xs, g->ys, g->n, &g->dopt, g->A, NULL,
                            &g->err);
}

/* The projected residuals f_k = (d_k - (A T)_k) / sigma_k at p, T the weighted least-squares
 * solution (numerics note 1); f may be NULL. Leaves A and T of p in g. */
static int geo_residual(struct geo *g, const double p[3], double *f, double *chi2)
{
    int rc = geo_design(g, p);
    if (rc) return rc;
    double *w = malloc(sizeof(double) * (g->n ? g->n : 1));
    if (!w) return err_set(&g->err, -ENOMEM, "geometry fit: out of memory");
    for (size_t k = 0; k < g->n; k++) w[k] = g->sw[k] * g->sw[k];
    wls_result_t res;
    rc = wls_solve(g->A, w, g->d, g->n, g->m, 0, g->T, NULL, &g->dopt.stop, &res);
    free(w);
    if (rc == -ECANCELED || (rc == 0 && geo_stop(g)))
        return err_set(&g->err, -ECANCELED, "geometry fit: stopped");
    if (rc) return err_set(&g->err, rc, "geometry fit: the linear solve failed at R %g um", p[0]);
    double sum = 0;
    for (size_t k = 0; k < g->n; k++) {
        double mk = 0;
        for (size_t j = 0; j < g->m; j++) mk += g->A[k * g->m + j] * g->T[j];
        double fk = (g->d[k] - mk) * g->sw[k];
        if (f) f[k] = fk;
        sum += fk * fk;
    }
    if (chi2) *chi2 = sum;
    return 0;
}

static void to_params(const struct geo *g, const gsl_vector *u, double p[3])
{
    for (int i = 0; i < 3; i++) p[i] = g->c[i] + g->h[i] * tanh(gsl_vector_get(u, i));
}

/* GSL callbacks: residuals, and their Jacobian in u by central differences in p. */
static int geo_f(const gsl_vector *u, void *vg, gsl_vector *f)
{
    struct geo *g = vg;
    double p[3];
    to_params(g, u, p);
    int rc = geo_residual(g, p, f->data, NULL);
    if (rc && !g->rc) g->rc = rc;
    return rc ? GSL_EDOM : GSL_SUCCESS;
}

static int geo_df(const gsl_vector *u, void *vg, gsl_matrix *J)
{
    struct geo *g = vg;
    double p[3];
    to_params(g, u, p);
    double *fp = malloc(sizeof(double) * 2 * (g->n ? g->n : 1)), *fm = fp ? fp + g->n : NULL;
    int rc = fp ? 0 : -ENOMEM;
    for (int i = 0; i < 3 && !rc; i++) {
        double q[3] = {p[0], p[1], p[2]}, hi = g->step[i];
        double t = tanh(gsl_vector_get(u, i)), dpdu = g->h[i] * (1 - t * t);
        q[i] = p[i] + hi;
        if ((rc = geo_residual(g, q, fp, NULL))) break;
        q[i] = p[i] - hi;
        if ((rc = geo_residual(g, q, fm, NULL))) break;
        for (size_t k = 0; k < g->n; k++)
            gsl_matrix_set(J, k, (size_t)i, (fp[k] - fm[k]) / (2 * hi) * dpdu);
    }
    free(fp);
    if (rc == -ENOMEM) err_set(&g->err, rc, "geometry fit: out of memory");
    if (rc && !g->rc) g->rc = rc;
    return rc ? GSL_EDOM : GSL_SUCCESS;
}

/* gsl_multifit_nlinear_driver(MAX_ITER, 1e-9, 1e-12, 0, ...)'s loop (GSL 2.x,
 * multifit_nlinear/fdf.c), which also ends when the stop answered: GSL's driver ignores an
 * iteration's error, so a stop seen inside a residual (g->rc) would not end it; this loop polls
 * before each iteration and ends on g->rc. The same statuses as the driver otherwise. */
static int geo_drive(struct geo *g, gsl_multifit_nlinear_workspace *ws, int *info)
{
    int st = GSL_CONTINUE;
    for (size_t iter = 0; st == GSL_CONTINUE && iter < MAX_ITER;) {
        if (geo_stop(g) && !g->rc) g->rc = err_set(&g->err, -ECANCELED, "geometry fit: stopped");
        if (g->rc) return GSL_EBADFUNC; /* the caller reports g->rc */
        st = gsl_multifit_nlinear_iterate(ws);
        if (st == GSL_ENOPROG && iter == 0) {
            *info = st;
            return GSL_EMAXITER;
        }
        ++iter;
        st = gsl_multifit_nlinear_test(1e-9, 1e-12, 0, info, ws);
        if (st == GSL_ETOLF || st == GSL_ETOLX || st == GSL_ETOLG) {
            *info = st;
            st = GSL_SUCCESS;
        }
        if (iter >= MAX_ITER && st != GSL_SUCCESS) st = GSL_EMAXITER;
    }
    return st;
}

/* LM in u from the written geometry; p gets the optimum. */
static int geo_minimise(struct geo *g, const fit_scan_t *scan, double p[3], fit_geometry_t *out)
{
    gsl_multifit_nlinear_parameters par = gsl_multifit_nlinear_default_parameters();
    par.trs = gsl_multifit_nlinear_trs_lm;
    par.solver = gsl_multifit_nlinear_solver_svd;
    gsl_multifit_nlinear_workspace *ws =
        gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &par, g->n, 3);
    gsl_vector *u0 = gsl_vector_alloc(3);
    int rc = 0, info = 0;
    if (!ws || !u0) {
        rc = err_set(&g->err, -ENOMEM, "geometry fit: out of memory");
        goto out;
    }
    double start[3] = {scan->spot_radius_um, 0, 0};
    for (int i = 0; i < 3; i++) gsl_vector_set(u0, i, atanh((start[i] - g->c[i]) / g->h[i]));
    gsl_multifit_nlinear_fdf fdf = {.f = geo_f, .df = geo_df, .n = g->n, .p = 3, .params = g};
    int st = gsl_multifit_nlinear_init(u0, &fdf, ws);
    if (st == GSL_SUCCESS) st = geo_drive(g, ws, &info);
    if (g->rc) { /* a design matrix or solve failed inside: its message is in g->err */
        rc = g->rc;
        goto out;
    }
    /* ENOPROG: no step lowers chi2 any more, at the resolution of the design matrix: a minimum */
    if (st != GSL_SUCCESS && st != GSL_EMAXITER && st != GSL_ENOPROG) {
        rc = err_set(&g->err, -EDOM, "geometry fit: GSL's solver failed (%s)", gsl_strerror(st));
        goto out;
    }
    if (st == GSL_EMAXITER) out->flags |= FIT_GEOMETRY_NOT_CONVERGED;
    const gsl_vector *u = gsl_multifit_nlinear_position(ws);
    to_params(g, u, p);
    for (int i = 0; i < 3; i++)
        if (fabs(tanh(gsl_vector_get(u, i))) > BOUND_FRAC) out->flags |= FIT_GEOMETRY_AT_BOUND;
    out->iterations = (int)gsl_multifit_nlinear_niter(ws);
out:
    gsl_multifit_nlinear_free(ws);
    gsl_vector_free(u0);
    return rc;
}

/* Marginal sigmas of (R, dx, dy) from the whole problem's Jacobian at p: columns sigma^-1 A
 * (the T) and sigma^-1 dA/dp T (the geometry, central differences at the fitted T), column-
 * balanced, through its SVD: cov = D V diag(1/s^2) V^T D (numerics note on the geometry fit). */
static int geo_covariance(struct geo *g, const double p[3], fit_geometry_t *out)
{
    size_t n = g->n, m = g->m, np = m + 3;
    gsl_matrix *J = gsl_matrix_alloc(n, np), *V = gsl_matrix_alloc(np, np);
    gsl_vector *s = gsl_vector_alloc(np), *work = gsl_vector_alloc(np), *D = gsl_vector_alloc(np);
    double *Tp = malloc(sizeof(double) * m), *mp = malloc(sizeof(double) * 2 * n);
    int rc = 0;
    if (!J || !V || !s || !work || !D || !Tp || !mp) {
        rc = err_set(&g->err, -ENOMEM, "geometry fit: out of memory");
        goto out;
    }
    if ((rc = geo_residual(g, p, NULL, &out->chi2_fitted))) goto out;
    memcpy(Tp, g->T, sizeof(double) * m);
    for (size_t k = 0; k < n; k++)
        for (size_t j = 0; j < m; j++) gsl_matrix_set(J, k, j, g->sw[k] * g->A[k * m + j]);
    for (int i = 0; i < 3; i++) {
        if (geo_stop(g)) {
            rc = err_set(&g->err, -ECANCELED, "geometry fit: stopped");
            goto out;
        }
        for (int sgn = 0; sgn < 2; sgn++) {
            double q[3] = {p[0], p[1], p[2]};
            q[i] += sgn ? -g->step[i] : g->step[i];
            if ((rc = geo_design(g, q))) goto out;
            for (size_t k = 0; k < n; k++) { /* the model at q with T held at the optimum */
                double mk = 0;
                for (size_t j = 0; j < m; j++) mk += g->A[k * m + j] * Tp[j];
                mp[sgn * n + k] = mk;
            }
        }
        for (size_t k = 0; k < n; k++)
            gsl_matrix_set(J, k, m + (size_t)i,
                           g->sw[k] * (mp[k] - mp[n + k]) / (2 * g->step[i]));
    }
    for (size_t j = 0; j < np; j++) { /* unit columns: the rank test is then scale-free */
        gsl_vector_view col = gsl_matrix_column(J, j);
        double norm = gsl_blas_dnrm2(&col.vector);
        gsl_vector_set(D, j, norm > 0 ? 1 / norm : 1);
        gsl_vector_scale(&col.vector, gsl_vector_get(D, j));
    }
    if (gsl_linalg_SV_decomp(J, V, s, work) != GSL_SUCCESS) {
        rc = err_set(&g->err, -EDOM, "geometry fit: the SVD of the Jacobian failed");
        goto out;
    }
    double smax = gsl_vector_get(s, 0), cov[3][3] = {{0}};
    for (size_t l = 0; l < np; l++) {
        double sl = gsl_vector_get(s, l);
        if (!(sl > RANK_TOL * smax)) {
            out->flags |= FIT_GEOMETRY_ILL_CONDITIONED;
            continue;
        }
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                cov[a][b] += gsl_matrix_get(V, m + a, l) * gsl_matrix_get(V, m + b, l) / (sl * sl);
    }
    double sig[3];
    for (int a = 0; a < 3; a++) {
        double da = gsl_vector_get(D, m + a);
        sig[a] = out->flags & FIT_GEOMETRY_ILL_CONDITIONED ? NAN : sqrt(cov[a][a]) * da;
    }
    out->R_err_um = sig[0], out->dx_err_um = sig[1], out->dy_err_um = sig[2];
    out->corr[0] = cov[0][1] / sqrt(cov[0][0] * cov[1][1]);
    out->corr[1] = cov[0][2] / sqrt(cov[0][0] * cov[2][2]);
    out->corr[2] = cov[1][2] / sqrt(cov[1][1] * cov[2][2]);
out:
    gsl_matrix_free(J);
    gsl_matrix_free(V);
    gsl_vector_free(s);
    gsl_vector_free(work);
    gsl_vector_free(D);
    free(Tp);
    free(mp);
    return rc;
}

int fit_geometry_run(const fit_scan_t *scan, int r, const fit_options_t *opts,
                     fit_geometry_t *out, err_t *err)
{
    fit_gsl_policy();
    memset(out, 0, sizeof *out);
    out->r = r;
    out->params = r * r + 3;
    out->R_um = out->R_err_um = out->dx_um = out->dx_err_um = out->dy_um = out->dy_err_um = NAN;
    out->chi2_fixed = out->chi2_fitted = out->chi2_red = out->chi2_p = out->bic = NAN;
    for (int i = 0; i < 3; i++) out->corr[i] = NAN;
    fit_options_t o = opts ? *opts : fit_options_default();
    if (r < 1 || r > 32) return err_set(err, -EINVAL, "geometry r must be between 1 and 32 (got %d)", r);
    int rc = fit_scan_check(scan, err);
    if (rc) return rc;
    out->R_written_um = scan->spot_radius_um;
    struct geo g;
    if ((rc = geo_init(scan, r, &o, &g))) {
        geo_free(&g);
        return err_set(err, rc, "geometry fit: out of memory");
    }
    out->n_used = g.n;
    if (g.n < (size_t)out->params + 1) {
        geo_free(&g);
        return err_set(err, -ERANGE,
                       "geometry fit at r = %d needs more than %d usable points (has %zu)", r,
                       out->params, g.n);
    }
    double p0[3] = {scan->spot_radius_um, 0, 0}, p[3];
    rc = geo_residual(&g, p0, NULL, &out->chi2_fixed);
    if (rc == 0) rc = geo_minimise(&g, scan, p, out);
    if (rc == 0) rc = geo_covariance(&g, p, out);
    if (rc == 0) {
        out->R_um = p[0], out->dx_um = p[1], out->dy_um = p[2];
        double dof = (double)(g.n - (size_t)out->params), nn = (double)g.n;
        out->chi2_red = out->chi2_fitted / dof;
        out->chi2_p = gsl_cdf_chisq_Q(out->chi2_fitted, dof);
        if (out->chi2_p < FIT_POOR_FIT_P) out->flags |= FIT_GEOMETRY_POOR_FIT;
        out->bic = nn * log(out->chi2_fitted / nn) + out->params * log(nn);
    }
    out->evaluations = g.evals;
    if (rc) err_set(err, rc, "%s", g.err.msg);
    geo_free(&g);
    return rc;
}

void fit_geometry_apply(const fit_scan_t *scan, const fit_geometry_t *g, double *x, double *y,
                        fit_scan_t *out)
{
    *out = *scan;
    for (size_t k = 0; k < scan->n; k++) {
        x[k] = scan->x_um[k] + g->dx_um;
        y[k] = scan->y_um[k] + g->dy_um;
    }
    out->x_um = x;
    out->y_um = y;
    out->spot_radius_um = g->R_um;
}
