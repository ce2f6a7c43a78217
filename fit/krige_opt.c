/* krige_opt.c: the kriged map's hyperparameters by maximum restricted likelihood (krige_int.h):
 * Fisher scoring with the average information AI in place of the Hessian, s = -AI^-1 g, inside a
 * trust region (a box: each parameter changes by at most the radius, which shrinks after a step
 * the quadratic model mispredicted and grows after one it predicted well), projected on the
 * bounds (a parameter at a bound whose gradient points out of the box is held there; one the
 * step would carry past its bound is put on it and the others solved again). A variance that
 * is already negligible and still falling goes to its bound in one step, as the likelihood is
 * flat there. On the bench's scans this takes 10-30 evaluations per model where BFGS took 50-300
 * (docs/numerics.md "The kriged map's speed"). Written here because GSL's minimisers take no
 * Hessian and no bounds. */
#include <math.h>
#include <string.h>

#include "krige_int.h"

#define MAX_ITER 60
#define STEP_MAX 8.0   /* of any log-parameter in one step */
#define F_TOL 1e-6     /* of -log L: a step that gains less ends the search */
#define DEC_TOL 1e-5   /* the predicted gain below which the search ends */
#define RADIUS_START 2.0 /* the trust region's first radius (largest change of a parameter) */
#define RADIUS_MIN 1e-4
#define NEGLIGIBLE -12.0 /* a log variance (over I0^2) below which a component is all but gone:
                            sd 0.25 % of the mean */

/* Solves (H) x = b for a small symmetric positive definite H (n <= KR_MAX_THETA) by Cholesky in
 * place; -1 when H is not positive definite. */
static int solve_spd(double *H, double *b, int n)
{
    for (int j = 0; j < n; j++) {
        double s = H[j * n + j];
        for (int k = 0; k < j; k++) s -= H[j * n + k] * H[j * n + k];
        if (!(s > 0)) return -1;
        H[j * n + j] = sqrt(s);
        for (int i = j + 1; i < n; i++) {
            double t = H[i * n + j];
            for (int k = 0; k < j; k++) t -= H[i * n + k] * H[j * n + k];
            H[i * n + j] = t / H[j * n + j];
        }
    }
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < i; k++) b[i] -= H[i * n + k] * b[k];
        b[i] /= H[i * n + i];
    }
    for (int i = n - 1; i >= 0; i--) {
        for (int k = i + 1; k < n; k++) b[i] -= H[k * n + i] * b[k];
        b[i] /= H[i * n + i];
    }
    return 0;
}

/* The trust-region step s (np values, 0 for the parameters not free): the scoring step
 * AI^-1 (-g) over the free parameters, each change at most radius; a parameter the step would
 * carry past its bound is put on the bound and the step solved again for the others given that
 * change (AI_ff s_f = -g_f - AI_fb s_b), until none crosses. -1 when AI is singular there. */
static int scoring_step(int np, const double *g, const double *AI, const double *th,
                        const double *lo, const double *hi, const int *isfree,
                        const int *is_var, double radius, int clip, int jumps, double *s)
{
    int fixed[KR_MAX_THETA] = {0};
    for (int i = 0; i < np; i++) s[i] = 0;
    for (int round = 0; round <= np; round++) {
        int fr[KR_MAX_THETA], nf = 0;
        for (int i = 0; i < np; i++)
            if (isfree[i] && !fixed[i]) fr[nf++] = i;
        if (nf == 0) return 0;
        double H[KR_MAX_THETA * KR_MAX_THETA], b[KR_MAX_THETA], dmax = 0, ridge = 1e-12;
        for (int a = 0; a < nf; a++) dmax = fmax(dmax, AI[fr[a] * np + fr[a]]);
        for (;;) {
            for (int a = 0; a < nf; a++) {
                b[a] = -g[fr[a]];
                for (int j = 0; j < np; j++)
                    if (fixed[j]) b[a] -= AI[fr[a] * np + j] * s[j];
                for (int c = 0; c < nf; c++) H[a * nf + c] = AI[fr[a] * np + fr[c]];
                H[a * nf + a] += ridge * dmax;
            }
            if (!solve_spd(H, b, nf)) break;
            if ((ridge *= 100) > 1) return -1;
        }
        double big = 0;
        for (int a = 0; a < nf; a++) big = fmax(big, fabs(b[a]));
        double scale = big > radius && !clip ? radius / big : 1;
        int crossed = 0;
        for (int a = 0; a < nf; a++) {
            int i = fr[a];
            s[i] = fmin(fmax(scale * b[a], -radius), radius);
            double t = th[i] + s[i];
            /* a variance already negligible that the step lowers further goes to its bound at
             * once: the likelihood is flat there, and walking down costs an evaluation a step */
            if (jumps && is_var[i] && th[i] < NEGLIGIBLE && b[a] < 0) t = -INFINITY;
            if (t < lo[i] || t > hi[i]) {
                s[i] = (t < lo[i] ? lo[i] : hi[i]) - th[i];
                fixed[i] = crossed = 1;
            }
        }
        if (!crossed) return 0;
    }
    return 0;
}

/* The quadratic model's gain for step s: -(g^T s + s^T AI s / 2). */
static double gain_of(int np, const double *g, const double *AI, const double *s)
{
    double pred = 0;
    for (int i = 0; i < np; i++) {
        double as = 0;
        for (int j = 0; j < np; j++) as += AI[i * np + j] * s[j];
        pred -= g[i] * s[i] + 0.5 * s[i] * as;
    }
    return pred;
}

double kr_maximise(kr_prob_t *k, const double *start, double *th)
{
    int np = kr_theta_count(k);
    double lo[KR_MAX_THETA], hi[KR_MAX_THETA];
    int is_var[KR_MAX_THETA];
    for (int i = 0; i < np; i++) {
        is_var[i] = !(k->smooth && i == k->nl + 1);
        kr_theta_bounds(k, i, &lo[i], &hi[i]);
        th[i] = fmin(fmax(start[i], lo[i]), hi[i]);
    }
    double f = kr_value(k, th);
    if (np == 0 || !isfinite(f)) return f;
    double g[KR_MAX_THETA], AI[KR_MAX_THETA * KR_MAX_THETA], radius = RADIUS_START;
    int jumps = 1; /* negligible variances may go to their bound at once (until a step fails) */
    if (kr_derivs(k, th, g, AI)) return HUGE_VAL;
    for (int it = 0; it < MAX_ITER && !k->stopped; it++) {
        int isfree[KR_MAX_THETA], nf = 0; /* held: on a bound, the gradient pointing out */
        for (int i = 0; i < np; i++) {
            isfree[i] = !((th[i] <= lo[i] && g[i] > 0) || (th[i] >= hi[i] && g[i] < 0));
            nf += isfree[i];
        }
        if (nf == 0) break;
        /* each change clipped to the radius (a box); should that leave the model no gain, the
         * whole step scaled into it */
        double s[KR_MAX_THETA], tn[KR_MAX_THETA], pred = 0, slen = 0;
        for (int clip = 1; clip >= 0; clip--) {
            if (scoring_step(np, g, AI, th, lo, hi, isfree, is_var, radius, clip, jumps, s)) break;
            pred = gain_of(np, g, AI, s);
            if (pred > 0) break;
        }
        for (int i = 0; i < np; i++) /* the step's length within the region (no jump) */
            if (fabs(s[i]) <= radius) slen = fmax(slen, fabs(s[i]));
        if (pred < DEC_TOL) break; /* nothing left to gain */
        for (int i = 0; i < np; i++) tn[i] = fmin(fmax(th[i] + s[i], lo[i]), hi[i]);
        double fn = kr_value(k, tn);
        double ratio = isfinite(fn) ? (f - fn) / pred : -1;
        if (ratio < 0.25) radius = fmax(0.25 * fmin(slen > 0 ? slen : radius, radius), RADIUS_MIN);
        else if (ratio > 0.75 && slen > 0.9 * radius) radius = fmin(2 * radius, STEP_MAX);
        if (!(fn < f)) {
            if (radius <= RADIUS_MIN && !jumps) break;
            jumps = 0; /* the next try stays inside the region */
            continue;
        }
        jumps = 1;
        double gain = f - fn;
        f = fn;
        memcpy(th, tn, sizeof(double) * (size_t)np);
        if (kr_derivs(k, th, g, AI)) return HUGE_VAL;
        if (gain < F_TOL) break;
    }
    /* the state must be th's (a rejected trial may have been evaluated last) */
    if (!k->at_valid || memcmp(k->at, th, sizeof(double) * (size_t)np)) {
        f = kr_value(k, th);
        if (isfinite(f) && kr_derivs(k, th, g, AI)) return HUGE_VAL;
    }
    return f;
}
