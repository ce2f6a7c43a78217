/* wedge_sweep.h: one sweep of design.c, the prefix integrals W(w, S) = int_0^S f(w cosh s) /
 * cosh s ds (f = Q or P) along an edge line at scaled distance w from a spot, in the variable
 * E = e^s, as Chebyshev segments that any target evaluates by one Clenshaw sum; and the
 * cross-call cache of sweeps (design.h). Internal to fit/: design.c builds the matrix from
 * these. A sweep or a cache belongs to one thread at a time; no I/O. */
#ifndef IPSD_FIT_WEDGE_SWEEP_H
#define IPSD_FIT_WEDGE_SWEEP_H

#include <stddef.h>
#include <stdint.h>

#include "fit/design.h"

#define MAX_ORDER 64

/* The Chebyshev rule of a build's sweeps (cheb_init), and their shape. */
struct cheb {
    int m;
    int near_foot;       /* sweeps start with segments that grow from a*dv = seg_dv along the line
                            (sweep_extend): on when any spot of the build is outside the pixel */
    double t[MAX_ORDER]; /* Chebyshev points of the first kind on [-1, 1] */
    double cosm[MAX_ORDER][MAX_ORDER]; /* cos(pi j (k + 1/2) / m): the DCT */
};

/* A sweep's segments are stored flat, SEG_STRIDE(m) doubles each: [sa, sb, cq, cp, tq, Cq[0..m],
 * Cp[0..m]]: the ends (offsets from the sweep's origin), the prefix integrals of Q and P at sa,
 * the integral of Q over the segment, and the antiderivative coefficients (in E units). Flat and
 * sized by the order in use, so that a cached sweep costs 39 doubles per segment at order 16,
 * not MAX_ORDER's. */
#define SEG_STRIDE(m) (5 + 2 * ((m) + 1))
#define SEG_TQ 4
#define SEG_CQ 5
#define SEG_CP(m) (6 + (m))

/* One sweep: the segments built so far for the line at scaled distance w, and where the next one
 * starts (E, with the prefix integrals cq, cp there), so that it can be extended. Segments are
 * never cut short at the farthest target: a sweep's segments depend only on w and the options,
 * so extending a cached sweep gives exactly the segments a fresh one would have. */
struct sweep {
    double w, E0, E, cq, cp; /* E0 the origin (1: the foot), E the end so far less E0 */
    int nseg, cap;
    double *seg;
};

/* One target of a sweep: its offset s from the sweep's origin (E - 1 on a sweep from the foot;
 * on a one-sided row, E less its least target's), the node's place in the wedge arrays, what it
 * needs (need[]). */
struct target {
    double s;
    size_t at;
    unsigned char need;
    uint32_t seg; /* a one-sided row's target on the foot's sweep: its segment (eval_from_foot) */
    double o, h;  /* its distance from the foot along the line and from the spot (wedge_pass) */
};

/* The segment holding offset s (the last one with sa <= s: branch-free halving) and s's place
 * in it, t in [-1, 1]. */
static inline const double *sweep_find(const struct sweep *sw, int stride, double s, double *t)
{
    const double *g = sw->seg;
    for (int len = sw->nseg; len > 1;) {
        int half = len / 2;
        g = g[(size_t)half * stride] <= s ? g + (size_t)half * stride : g;
        len -= half;
    }
    double h = 0.5 * (g[1] - g[0]), tt = h > 0 ? (s - 0.5 * (g[0] + g[1])) / h : 1.0;
    *t = tt > 1 ? 1 : tt;
    return g;
}

/* The segment holding offset d0 + s and its place in it, t = ((d0 - mid) + s) / half-length:
 * the small offset s of a one-sided row's node from its least target (at d0 on a sweep from the
 * foot) is added to d0 - mid, not to d0, so that it keeps its digits. */
static inline const double *sweep_find_from(const struct sweep *sw, int stride, double d0,
                                            double s, double *t)
{
    double unused;
    const double *g = sweep_find(sw, stride, d0 + s, &unused);
    *t = ((d0 - 0.5 * (g[0] + g[1])) + s) / (0.5 * (g[1] - g[0]));
    return g;
}

/* Starts sw afresh for the line at scaled distance w > 0, origin E0 = 1 (keeps its buffer). */
void sweep_reset(struct sweep *sw, double w);
/* Appends segments to sw until they cover E - E0 up to emax (wedge_sweep.c has the rules). */
size_t sweep_extend(const struct cheb *ch, const fit_design_opts_t *o, struct sweep *sw,
                    double emax, size_t *added_bytes);
/* Prefix integrals of Q (and of P when wp is not NULL) up to offset s from the origin. */
void sweep_eval(const struct sweep *sw, int m, double s, double *wq, double *wp);
/* sweep_eval's Q part for four / eight targets at once, into wq[tg[l].at]. */
void sweep_eval4(const struct sweep *sw, int m, const struct target *tg, double *wq);
void sweep_eval8(const struct sweep *sw, int m, const struct target *tg, double *wq);
/* The Clenshaw sums of eight series c[l] at t[l], each lane sweep_eval's arithmetic. */
void clenshaw8(const double *const c[8], const double t[8], int m, double out[8]);
/* The sweep at w for these options: from cache c when it serves them (built and kept there),
 * else the scratch sweep built afresh; extended to emax. NULL when out of memory. *evals grows
 * by the radial evaluations a fresh sweep to emax takes. */
const struct sweep *sweep_get(fit_design_cache_t *c, const struct cheb *ch,
                              const fit_design_opts_t *o, struct sweep *scratch, double w,
                              double emax, size_t *evals);
/* Makes the cache serve these options when it serves none yet (it keeps its first options'). */
void cache_claim(fit_design_cache_t *c, const struct cheb *ch, const fit_design_opts_t *o);
/* Chebyshev points of the first kind and the DCT matrix for m points per segment. */
void cheb_init(struct cheb *ch, int m);

#endif
