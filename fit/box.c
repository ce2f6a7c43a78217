/* box.c: accurate Airy box integral (the reference path; design.c has the fast one).
 *
 * Spot inside the closed box: the sum of the four corner rectangles' F (corner.h), all signs +,
 * so no cancellation. Spot outside: in polar coordinates about the spot the box is
 *     (2/a^2) int [Q(a rho_in(t)) - Q(a rho_out(t))] dt
 * over the angles t it subtends, rho_in/rho_out where the ray enters/leaves the box (numerics
 * note 2: the flux between radii rho1 < rho2 per radian is (2/a^2)(Q(a rho1) - Q(a rho2))). The
 * integrand is smooth between the corner angles, and only the flux near the box enters it, so far
 * boxes keep full relative precision (corner sums would subtract whole half-plane tails). Each
 * piece is integrated by GSL's adaptive Gauss-Kronrod (QAG, 21 points). */
#include "fit/box.h"

#include <errno.h>
#include <float.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_integration.h>
#include <math.h>

#include "fit/airy.h"
#include "corner.h"
#include "fit/gslerr.h"

#define QAG_LIMIT 4000

/* ---- spot inside: corner wedges W(w, S) = int_0^S P(w cosh s) / cosh s ds (corner.h) ---- */

static double wedge_integrand(double s, void *vp)
{
    const double *par = vp; /* w, and 1 to integrate P or 0 to integrate Q */
    double c = cosh(s), q, p;
    fit_radial(par[0] * c, &q, &p);
    return (par[1] != 0 ? p : q) / c;
}

/* F of the corner (|u|, |v|) in units of 2/a^2, each wedge to epsabs; error estimate added.
 * Near a spot (w = a u < 1) the wedge integrates P directly (P is small there); farther out it
 * is gd(S) - int Q, the exact angle minus the small outside flux, so that the many oscillations
 * of P - 1 far from a small spot only enter through the small term (P >= P(1) = 0.2 there, so
 * the subtraction loses at most a factor 5). */
static int corner_f(gsl_integration_workspace *ws, double a, double u, double v, double epsabs,
                    double *f, double *err)
{
    u = fabs(u);
    v = fabs(v);
    *f = 0;
    if (a * u < FIT_CORNER_TINY || a * v < FIT_CORNER_TINY) return GSL_SUCCESS; /* no area */
    int st = 0;
    double side[2][2] = {{a * u, asinh(v / u)}, {a * v, asinh(u / v)}}; /* w and S = asinh(tan T) */
    for (int k = 0; k < 2; k++) {
        double val, e, par[2] = {side[k][0], side[k][0] < 1 ? 1 : 0};
        gsl_function F = {wedge_integrand, par};
        st |= gsl_integration_qag(&F, 0, side[k][1], epsabs, 0, QAG_LIMIT, GSL_INTEG_GAUSS21, ws,
                                  &val, &e);
        *f += par[1] != 0 ? val : atan(sinh(side[k][1])) - val; /* gd(S) = atan(sinh S) */
        *err += e;
    }
    return st;
}

static int box_inside(gsl_integration_workspace *ws, double a, const double u[2], const double v[2],
                      double rel_tol, double *val, double *err)
{
    /* pass 1 at a loose absolute tolerance finds the size of the answer; pass 2 asks each of the
     * eight wedges for the absolute accuracy the answer needs */
    double fp[2][2], mag = 0, tol = 1e-9;
    int st = 0;
    for (int pass = 0; pass < 2; pass++) {
        st = 0;
        *err = 0;
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++) st |= corner_f(ws, a, u[i], v[j], tol, &fp[j][i], err);
        *val = corner_combine(u, v, fp, fp, &mag);
        tol = fmax(rel_tol * *val / 16, 1e-300);
    }
    *err += 4 * DBL_EPSILON * mag;
    return st;
}

/* ---- spot outside: rays from the spot through the box ---- */

struct ray_par {
    double a, u[2], v[2];
};

/* Distances along the ray at angle t where it enters and leaves the box (slab method). */
static void ray_span(const struct ray_par *rp, double t, double *rin, double *rout)
{
    double c = cos(t), s = sin(t), lo = 0, hi = INFINITY;
    const double *e[2] = {rp->u, rp->v};
    double d[2] = {c, s};
    for (int k = 0; k < 2; k++) {
        if (fabs(d[k]) < 1e-300) {
            if (e[k][0] > 0 || e[k][1] < 0) hi = 0; /* parallel to the slab, outside it */
            continue;
        }
        double t0 = e[k][0] / d[k], t1 = e[k][1] / d[k];
        if (t0 > t1) { double tmp = t0; t0 = t1; t1 = tmp; }
        lo = fmax(lo, t0);
        hi = fmin(hi, t1);
    }
    *rin = lo;
    *rout = hi > lo ? hi : lo;
}

static double ray_integrand(double t, void *vp)
{
    const struct ray_par *rp = vp;
    double rin, rout, qi, pi_, qo, po;
    ray_span(rp, t, &rin, &rout);
    if (rout <= rin) return 0;
    fit_radial(rp->a * rin, &qi, &pi_);
    fit_radial(rp->a * rout, &qo, &po);
    /* Q(in) - Q(out) = P(out) - P(in); take the form of the smaller numbers */
    return rp->a * rin < 2 ? po - pi_ : qi - qo;
}

static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

static int box_outside(gsl_integration_workspace *ws, double a, double u[2], double v[2],
                       double rel_tol, double *val, double *err)
{
    /* reflect (the Airy is symmetric) so the box lies right of or above the spot, keeping the
     * corner angles inside (-pi/2, pi] without wrap-around */
    if (u[1] <= 0) { double t = -u[0]; u[0] = -u[1]; u[1] = t; }
    if (v[1] <= 0) { double t = -v[0]; v[0] = -v[1]; v[1] = t; }
    struct ray_par rp = {a, {u[0], u[1]}, {v[0], v[1]}};
    double ang[4];
    for (int j = 0, n = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) ang[n++] = atan2(v[j], u[i]);
    qsort(ang, 4, sizeof ang[0], cmp_double);
    gsl_function F = {ray_integrand, &rp};
    /* the nearest point of the box bounds Q along every ray: the rounding scale */
    double dx = fmax(0, u[0]), dy = fmax(0, v[0]), qn, pn;
    fit_radial(a * hypot(dx, dy), &qn, &pn);
    int st = 0;
    double eps = 0;
    for (int pass = 0; pass < 2; pass++) {
        double sum = 0, e = 0;
        for (int k = 0; k < 3; k++) {
            if (!(ang[k + 1] > ang[k])) continue;
            double r, re;
            st |= gsl_integration_qag(&F, ang[k], ang[k + 1], pass ? eps : 1e-9 * qn, 0,
                                      QAG_LIMIT, GSL_INTEG_GAUSS21, ws, &r, &re);
            sum += r;
            e += re;
        }
        *val = sum;
        *err = e + 8 * DBL_EPSILON * (ang[3] - ang[0]) * fmin(qn, 1);
        eps = fmax(rel_tol * fabs(sum) / 4, 1e-300);
        if (pass == 0) st = 0;
    }
    return st;
}

int fit_box_integral(double R_um, const fit_rect_t *rect, double xk, double yk, double rel_tol,
                     double *value, double *err_bound, err_t *err)
{
    fit_gsl_policy();
    if (!(R_um > 0) || !isfinite(R_um))
        return err_set(err, -EINVAL, "spot radius must be a positive finite number (got %g)", R_um);
    if (!isfinite(rect->x0) || !isfinite(rect->x1) || !isfinite(rect->y0) ||
        !isfinite(rect->y1) || !isfinite(xk) || !isfinite(yk))
        return err_set(err, -EINVAL, "box edges and spot position must be finite numbers");
    if (!(rel_tol > 0)) rel_tol = 1e-13;
    if (rel_tol < 1e-15) rel_tol = 1e-15;
    double sign = 1;
    double u[2] = {rect->x0 - xk, rect->x1 - xk}, v[2] = {rect->y0 - yk, rect->y1 - yk};
    if (u[0] > u[1]) { double t = u[0]; u[0] = u[1]; u[1] = t; sign = -sign; }
    if (v[0] > v[1]) { double t = v[0]; v[0] = v[1]; v[1] = t; sign = -sign; }
    double a = fit_airy_a(R_um), unit = 2 / (a * a), val = 0, bound = 0;
    if (u[1] > u[0] && v[1] > v[0]) {
        gsl_integration_workspace *ws = gsl_integration_workspace_alloc(QAG_LIMIT);
        if (!ws) return err_set(err, -ENOMEM, "out of memory");
        int inside = u[0] <= 0 && u[1] >= 0 && v[0] <= 0 && v[1] >= 0;
        int st = inside ? box_inside(ws, a, u, v, rel_tol, &val, &bound)
                        : box_outside(ws, a, u, v, rel_tol, &val, &bound);
        gsl_integration_workspace_free(ws);
        *value = sign * unit * val;
        if (err_bound) *err_bound = unit * bound;
        if (st != GSL_SUCCESS && bound > rel_tol * fabs(val))
            return err_set(err, -ERANGE, "tolerance %g not reached: error bound %.3g", rel_tol,
                           unit * bound);
        return 0;
    }
    *value = 0; /* a box of zero width */
    if (err_bound) *err_bound = 0;
    return 0;
}
