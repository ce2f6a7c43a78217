/* geometry_krige.c: the spot radius and the scan-grid offset refined under the kriged model
 * (geometry.h, fit_geometry_krige): the geometry g = (R, dx, dy) that maximises the kriged map's
 * likelihood with mu integrated out (flat prior) and the hyperparameters theta profiled,
 *     -log L_p(g) = min_theta -log L(theta; g),   -2 log L = log|V| + log(1_A^T V^-1 1_A) + d^T P d
 * (krige_int.h), V = D + A(g) K(theta) A(g)^T. With mu's flat prior the same for every g (mu is
 * the pixel's mean level whatever the geometry), L is the marginal density of the data, so values
 * at different g compare as likelihoods do; the r x r map's chi2 cannot, on a pixel whose
 * structure no r x r map holds (its discretisation error is charged to R, dx, dy). The search
 * starts at the r x r fit's geometry (fit_geometry_pick or _run) with the prior of its r's divisor
 * grids. Newton's method with central-difference derivatives (each value is an inner maximisation
 * whose gradient in g is not at hand), falling back to a simplex (GSL's nmsimplex2) where the
 * Hessian is not positive definite; each theta starts from the last optimum's.
 * Uncertainties: the inverse of the profile's Hessian in g by central differences at the optimum
 * (the profile likelihood's curvature, which counts the map and theta as nuisance parameters).
 * Pure numerics: no I/O, no globals, thread-safe. */
#include <errno.h>
#include <gsl/gsl_cdf.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_multimin.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/geometry.h"
#include "fit/gslerr.h"
#include "krige_int.h"

#define KG_MAX_ITER 150      /* simplex iterations */
#define KG_SIZE_TOL 2e-4     /* um: the simplex's size at which the search ends */
#define KG_STEP0 0.02        /* um: the first simplex's size */
#define KG_HESS_STEP 0.006   /* um: central-difference step of the profile's Hessian */
#define KG_NEWTON_MAX_ITER 8
#define KG_NEWTON_MAX_STEP 0.15 /* um: the longest Newton step in any of R, dx, dy */
#define KG_NEWTON_TOL 0.05   /* of a parameter's sigma: a Newton step this short ends the search */
#define KG_NEWTON_HALVINGS 6

struct kg {
    const fit_scan_t *scan;
    const fit_krige_prior_t *pr;
    const fit_options_t *o;
    double *x, *y;           /* shifted positions */
    double th[KR_MAX_THETA]; /* warm start: the last optimum's hyperparameters */
    int have_th, evals, rc;
    double dPd;              /* d^T P d at the last value */
    size_t n_used;
    double Rlo, Rhi, dmax;
    err_t err;
};

/* -log L_p at g (HUGE_VAL outside the bounds or where the likelihood fails). th_from: start theta
 * (NULL: krige.c's starts). */
static double profile(struct kg *s, const double g[3], const double *th_from, double *th_out)
{
    if (!(g[0] >= s->Rlo && g[0] <= s->Rhi && fabs(g[1]) <= s->dmax && fabs(g[2]) <= s->dmax))
        return HUGE_VAL;
    const fit_scan_t *sc = s->scan;
    for (size_t k = 0; k < sc->n; k++) s->x[k] = sc->x_um[k] + g[1], s->y[k] = sc->y_um[k] + g[2];
    fit_scan_t moved = *sc;
    moved.x_um = s->x, moved.y_um = s->y, moved.spot_radius_um = g[0];
    kr_work_t *w;
    err_t e;
    int rc = kr_work_new(&moved, s->pr, s->o, -1, &w, &e);
    if (rc) {
        if (!s->rc) s->rc = rc, s->err = e;
        return HUGE_VAL;
    }
    kr_prob_t *k = kr_work_model(w, 1);
    double th[KR_MAX_THETA], f = th_from ? kr_maximise(k, th_from, th) : kr_best_of_starts(k, 2, th);
    s->dPd = k->dPd, s->n_used = k->n;
    if (k->stopped && !s->rc) s->rc = -ECANCELED, err_set(&s->err, -ECANCELED, "geometry fit stopped");
    if (isfinite(f) && th_out) memcpy(th_out, th, sizeof th);
    kr_work_free(w);
    s->evals++;
    return isfinite(f) ? f : HUGE_VAL;
}

static double simplex_f(const gsl_vector *v, void *p)
{
    struct kg *s = p;
    if (s->rc) return HUGE_VAL;
    double g[3] = {gsl_vector_get(v, 0), gsl_vector_get(v, 1), gsl_vector_get(v, 2)}, th[KR_MAX_THETA];
    double f = profile(s, g, s->have_th ? s->th : NULL, th);
    if (isfinite(f) && f < HUGE_VAL) memcpy(s->th, th, sizeof th), s->have_th = 1;
    return f;
}

/* The profile's gradient G and Hessian H at g0 (value f0, hyperparameters th0) by central
 * differences (19 values with f0); 0 or -1. */
static int hessian(struct kg *s, const double g0[3], double f0, const double *th0, double G[3],
                   double H[9])
{
    double h = KG_HESS_STEP;
    for (int i = 0; i < 3; i++) {
        double gp[3], gm[3];
        memcpy(gp, g0, sizeof gp), memcpy(gm, g0, sizeof gm);
        gp[i] += h, gm[i] -= h;
        double fp = profile(s, gp, th0, NULL), fm = profile(s, gm, th0, NULL);
        if (!(fp < HUGE_VAL && fm < HUGE_VAL)) return -1;
        H[i * 3 + i] = (fp - 2 * f0 + fm) / (h * h);
        G[i] = (fp - fm) / (2 * h);
        for (int j = 0; j < i; j++) {
            double c[4];
            for (int q = 0; q < 4; q++) {
                double gq[3];
                memcpy(gq, g0, sizeof gq);
                gq[i] += q & 1 ? -h : h;
                gq[j] += q & 2 ? -h : h;
                if (!((c[q] = profile(s, gq, th0, NULL)) < HUGE_VAL)) return -1;
            }
            H[i * 3 + j] = H[j * 3 + i] = (c[0] - c[1] - c[2] + c[3]) / (4 * h * h);
        }
    }
    return 0;
}

/* Inverts the symmetric 3 x 3 H into C; -1 when H is not positive definite. */
static int invert3(const double H[9], double C[9])
{
    double a = H[0], b = H[1], c = H[2], d = H[4], e = H[5], f = H[8];
    double A = d * f - e * e, B = c * e - b * f, Cc = b * e - c * d;
    double det = a * A + b * B + c * Cc;
    if (!(a > 0) || !(a * d - b * b > 0) || !(det > 0)) return -1;
    C[0] = A / det, C[1] = C[3] = B / det, C[2] = C[6] = Cc / det;
    C[4] = (a * f - c * c) / det, C[5] = C[7] = (b * c - a * e) / det, C[8] = (a * d - b * b) / det;
    return 0;
}

/* Newton's method on the profile from g0, with the central-difference gradient and Hessian: the
 * profile is close to quadratic about its optimum (on a paper-like 13 x 13 scan within 20 % of it
 * out to four sigma), and the r x r fit's geometry starts within a few sigma of it, so one to three
 * steps reach it in ~40-60 values where the simplex took ~75-110. A step is cut to
 * KG_NEWTON_MAX_STEP and halved until the value falls. Ends when the step is under KG_NEWTON_TOL
 * of its sigma, or when a full step of at most one sigma fell as the quadratic predicted (the
 * Hessian at its start then stands for the optimum's). g, th, f, H, C: the optimum, its
 * hyperparameters and value, the Hessian and its inverse there. 0 (also when no step falls: g is
 * then the optimum as far as the differences tell), or -1 where the Hessian is not positive
 * definite or the steps ran out (the caller falls back to the simplex). */
static int newton_search(struct kg *s, const double g0[3], double g[3], double *th, double *f,
                         double H[9], double C[9], int *iter)
{
    double G[3], thn[KR_MAX_THETA];
    memcpy(g, g0, sizeof(double) * 3);
    *f = profile(s, g, NULL, th);
    if (!(*f < HUGE_VAL)) return -1;
    for (*iter = 1; *iter <= KG_NEWTON_MAX_ITER && !s->rc; ++*iter) {
        if (hessian(s, g, *f, th, G, H) || invert3(H, C)) return -1;
        double st[3], big = 0;
        int tiny = 1, within_sigma = 1;
        for (int i = 0; i < 3; i++) {
            st[i] = -(C[i * 3] * G[0] + C[i * 3 + 1] * G[1] + C[i * 3 + 2] * G[2]);
            double sig = sqrt(C[i * 4]);
            big = fmax(big, fabs(st[i]) / KG_NEWTON_MAX_STEP);
            tiny &= fabs(st[i]) <= fmax(KG_NEWTON_TOL * sig, KG_SIZE_TOL);
            within_sigma &= fabs(st[i]) <= sig;
        }
        if (tiny) return 0;
        double scale = big > 1 ? 1 / big : 1, t = scale;
        double pred = 0.5 * (st[0] * G[0] + st[1] * G[1] + st[2] * G[2]); /* -(1/2) G^T C G */
        int took = 0;
        for (int half = 0; half < KG_NEWTON_HALVINGS && !s->rc; half++, t /= 2) {
            double gn[3] = {g[0] + t * st[0], g[1] + t * st[1], g[2] + t * st[2]};
            double fn = profile(s, gn, th, thn);
            if (fn < *f) {
                int full = t == 1;
                double fell = *f - fn;
                memcpy(g, gn, sizeof gn), memcpy(th, thn, sizeof thn), *f = fn, took = 1;
                /* a full step within a sigma, whose fall the quadratic foretold: at the optimum */
                if (full && within_sigma && fabs(fell + pred) <= 0.1 * fabs(pred) + 0.01) return 0;
                break;
            }
        }
        if (!took) return s->rc ? -1 : 0; /* no step falls: g is the optimum as far as it goes */
    }
    return -1;
}

int fit_geometry_krige(const fit_scan_t *scan, const fit_geometry_t *start,
                       const fit_options_t *opts, fit_geometry_t *out, err_t *err)
{
    *out = *start;
    if (start->r < 1 || start->r > 32)
        return err_set(err, -EINVAL, "the kriged geometry needs the r x r fit's r (got %d)", start->r);
    fit_gsl_policy();
    fit_options_t o = opts ? *opts : fit_options_default();
    fit_krige_prior_t pr = fit_krige_prior_divisors(start->r);
    struct kg s = {.scan = scan, .pr = &pr, .o = &o};
    double Rw = start->R_written_um > 0 ? start->R_written_um : scan->spot_radius_um;
    s.Rlo = Rw / 2, s.Rhi = Rw * 2, s.dmax = scan->pitch_um;
    s.x = malloc(sizeof(double) * (scan->n ? scan->n : 1));
    s.y = malloc(sizeof(double) * (scan->n ? scan->n : 1));
    gsl_multimin_fminimizer *mz = gsl_multimin_fminimizer_alloc(gsl_multimin_fminimizer_nmsimplex2, 3);
    gsl_vector *x0 = gsl_vector_alloc(3), *step = gsl_vector_alloc(3);
    int rc = 0;
    if (!s.x || !s.y || !mz || !x0 || !step) {
        rc = err_set(err, -ENOMEM, "out of memory for the kriged geometry");
        goto out;
    }
    double g0[3] = {start->R_um, start->dx_um, start->dy_um};
    if (start->flags & FIT_GEOMETRY_UNUSABLE) /* from the written geometry */
        g0[0] = Rw, g0[1] = g0[2] = 0;
    double g[3], th[KR_MAX_THETA], H[9], C[9], G[3], f;
    int iter = 0, status = GSL_CONTINUE;
    int newton = newton_search(&s, g0, g, th, &f, H, C, &iter);
    if (s.rc) {
        rc = err_set(err, s.rc, "%s", s.err.msg);
        goto out;
    }
    if (newton == 0) {
        status = GSL_SUCCESS;
        goto found;
    }
    for (int i = 0; i < 3; i++) gsl_vector_set(x0, i, g0[i]), gsl_vector_set(step, i, KG_STEP0);
    gsl_multimin_function fn = {.f = simplex_f, .n = 3, .params = &s};
    if (gsl_multimin_fminimizer_set(mz, &fn, x0, step) || s.rc) {
        rc = s.rc ? err_set(err, s.rc, "%s", s.err.msg)
                  : err_set(err, -EDOM, "the kriged geometry's likelihood could not be evaluated");
        goto out;
    }
    while (status == GSL_CONTINUE && iter < KG_MAX_ITER) {
        iter++;
        if (gsl_multimin_fminimizer_iterate(mz) || s.rc) break;
        status = gsl_multimin_test_size(gsl_multimin_fminimizer_size(mz), KG_SIZE_TOL);
    }
    if (s.rc) {
        rc = err_set(err, s.rc, "%s", s.err.msg);
        goto out;
    }
    for (int i = 0; i < 3; i++) g[i] = gsl_vector_get(mz->x, i);
    f = profile(&s, g, s.have_th ? s.th : NULL, th);
    if (!(f < HUGE_VAL) || hessian(&s, g, f, th, G, H) || invert3(H, C)) newton = -1;
    else newton = 0;
found:
    f = profile(&s, g, th, th); /* the optimum's own d^T P d */
    if (!(f < HUGE_VAL)) {
        rc = err_set(err, -EDOM, "the kriged geometry's likelihood could not be evaluated");
        goto out;
    }
    out->flags = status == GSL_SUCCESS ? 0 : FIT_GEOMETRY_NOT_CONVERGED;
    out->kriged = 1;
    out->R_um = g[0], out->dx_um = g[1], out->dy_um = g[2];
    out->iterations = iter;
    /* the model's own goodness of fit: d^T P d against chi-square(n - 1) (krige_int.h) */
    double dof = (double)s.n_used - 1;
    out->kriged_chi2 = s.dPd;
    out->kriged_chi2_red = dof > 0 ? s.dPd / dof : NAN;
    out->kriged_chi2_p = dof > 0 ? gsl_cdf_chisq_Q(s.dPd, dof) : NAN;
    if (out->kriged_chi2_p < FIT_POOR_FIT_P) out->flags |= FIT_GEOMETRY_POOR_FIT;
    if (newton) {
        out->flags |= FIT_GEOMETRY_ILL_CONDITIONED;
        out->R_err_um = out->dx_err_um = out->dy_err_um = NAN;
    } else {
        out->R_err_um = sqrt(C[0]), out->dx_err_um = sqrt(C[4]), out->dy_err_um = sqrt(C[8]);
        out->corr[0] = C[1] / sqrt(C[0] * C[4]);
        out->corr[1] = C[2] / sqrt(C[0] * C[8]);
        out->corr[2] = C[5] / sqrt(C[4] * C[8]);
    }
    if (g[0] - s.Rlo < 0.01 * Rw || s.Rhi - g[0] < 0.01 * Rw || s.dmax - fabs(g[1]) < 0.01 * s.dmax ||
        s.dmax - fabs(g[2]) < 0.01 * s.dmax)
        out->flags |= FIT_GEOMETRY_AT_BOUND;
    out->evaluations = start->evaluations + s.evals;
out:
    gsl_multimin_fminimizer_free(mz);
    gsl_vector_free(x0);
    gsl_vector_free(step);
    free(s.x), free(s.y);
    return rc;
}
