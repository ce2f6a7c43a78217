/* wedge_sweep.c: the spectral cumulative integration of one wedge sweep (design.c's prefix
 * integrals along an edge line, wedge_sweep.h) and the cross-call cache of sweeps (design.h). */
#include "wedge_sweep.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "radial.h"

/* The cross-call cache (design.h): sweeps by w in an open-addressing table. */
struct fit_design_cache {
    int order; /* the options the cached sweeps were built with (order 0: none yet) */
    int near_foot;
    double seg_dv, seg_ds;
    size_t bytes, budget; /* segment memory held, and the most it may hold */
    size_t n, cap;        /* sweeps held */
    struct sweep *sw;
    size_t *slot, nslot; /* index + 1 into sw, 0 empty; nslot a power of two */
    fit_design_cache_stats_t st;
};

/* Antiderivative (zero at t = -1) of sum_j c_j T_j, j < m, scaled by the half-length h. */
static void antiderivative(const double *c, int m, double h, double *C)
{
    memset(C, 0, sizeof(double) * (size_t)(m + 1));
    C[1] += c[0];                 /* int T0 = T1 */
    if (m > 1) C[2] += c[1] / 4;  /* int T1 = T2 / 4 + const */
    for (int j = 2; j < m; j++) { /* int Tj = T(j+1)/(2(j+1)) - T(j-1)/(2(j-1)) */
        C[j + 1] += c[j] / (2.0 * (j + 1));
        C[j - 1] -= c[j] / (2.0 * (j - 1));
    }
    double at_minus1 = 0;
    for (int j = 1; j <= m; j++)
        at_minus1 += (j % 2 ? -C[j] : C[j]);
    C[0] = -at_minus1;
    for (int j = 0; j <= m; j++)
        C[j] *= h;
}

/* Starts sw afresh for the line at scaled distance w > 0 (keeps its buffer). */
void sweep_reset(struct sweep *sw, double w)
{
    sw->w = w;
    sw->E0 = 1;
    sw->E = 0;
    sw->cq = sw->cp = 0;
    sw->nseg = 0;
}

/* Appends segments to sw until they cover E - E0 up to emax. Segments and targets are offsets
 * from the origin E0, not E itself: far from a spot its line's nodes lie at E = 1 + O(1e-3) and
 * their spacing would otherwise be a few hundred ulps of E. With ch->near_foot the segments
 * near the origin are no longer than the larger of seg_dv / w (a * dv <= seg_dv along the line,
 * for E near 1) and (e^seg_ds - 1) times the offset (growing geometrically, O(log w) more
 * segments), so that nodes a few cells apart near the foot of a far line are not points of one
 * long segment whose Clenshaw sum loses digits in proportion to its length over their spacing.
 * *added_bytes (may be NULL) grows by the memory newly allocated. Returns the number of radial
 * evaluations, or (size_t)-1 when out of memory. */
size_t sweep_extend(const struct cheb *ch, const fit_design_opts_t *o, struct sweep *sw,
                    double emax, size_t *added_bytes)
{
    int m = ch->m, stride = SEG_STRIDE(m);
    size_t evals = 0;
    double w = sw->w, E0 = sw->E0, d = sw->E, cq = sw->cq, cp = sw->cp, ratio = exp(o->seg_ds);
    while (d < emax) {
        double E = E0 + d, next = E * ratio;
        /* v = w (E + 1/E)/2 may grow by at most seg_dv: solve E' + 1/E' = 2 vnext / w */
        double vnext = w * 0.5 * (E + 1 / E) + o->seg_dv, c = vnext / w;
        if (w * 0.5 * (next + 1 / next) > vnext) next = c + sqrt((c - 1) * (c + 1));
        double span = next - E;
        if (ch->near_foot) span = fmin(span, fmax((ratio - 1) * d, o->seg_dv / w));
        double dnext = d + span;
        if (!(dnext > d)) dnext = emax; /* rounding guard */
        if (sw->nseg == sw->cap) {
            int cap = sw->cap ? 2 * sw->cap : 16;
            double *ns = realloc(sw->seg, sizeof(double) * (size_t)stride * (size_t)cap);
            if (!ns) return (size_t)-1;
            if (added_bytes)
                *added_bytes += sizeof(double) * (size_t)stride * (size_t)(cap - sw->cap);
            sw->seg = ns;
            sw->cap = cap;
        }
        double *g = sw->seg + (size_t)stride * (size_t)sw->nseg++;
        double mid = 0.5 * (dnext + d), h = 0.5 * (dnext - d), fq[MAX_ORDER], fp[MAX_ORDER];
        for (int k = 0; k < m; k++) {
            double x = E0 + (mid + h * ch->t[k]), x2 = x * x + 1.0, q, p;
            radial_eval(w * 0.5 * x2 / x, &q, &p); /* v = w cosh s = w (x + 1/x) / 2 */
            fq[k] = q * 2.0 / x2;                  /* dT/dE = 2 / (1 + E^2) */
            fp[k] = p * 2.0 / x2;
        }
        evals += (size_t)m;
        double c1[MAX_ORDER] = {0}, c2[MAX_ORDER] = {0};
        for (int j = 0; j < m; j++) {
            double aq = 0, ap = 0;
            for (int k = 0; k < m; k++) {
                aq += fq[k] * ch->cosm[j][k];
                ap += fp[k] * ch->cosm[j][k];
            }
            c1[j] = aq * 2.0 / m;
            c2[j] = ap * 2.0 / m;
        }
        c1[0] /= 2;
        c2[0] /= 2;
        double *Cq = g + SEG_CQ, *Cp = g + SEG_CP(m);
        antiderivative(c1, m, h, Cq);
        antiderivative(c2, m, h, Cp);
        g[0] = d;
        g[1] = dnext;
        g[2] = cq;
        g[3] = cp;
        g[SEG_TQ] = 0;
        for (int j = 0; j <= m; j++) { /* T_j(1) = 1 */
            cq += Cq[j];
            cp += Cp[j];
            g[SEG_TQ] += Cq[j];
        }
        d = dnext;
    }
    sw->E = d;
    sw->cq = cq;
    sw->cp = cp;
    return evals;
}

/* Prefix integrals of Q (and of P when wp is not NULL) up to offset s (0 <= s <= the sweep's
 * end) from the sweep's origin. */
void sweep_eval(const struct sweep *sw, int m, double s, double *wq, double *wp)
{
    double t;
    const double *g = sweep_find(sw, SEG_STRIDE(m), s, &t);
    *wq = g[2] + radial_clenshaw(g + SEG_CQ, m, t);
    if (wp) *wp = g[3] + radial_clenshaw(g + SEG_CP(m), m, t);
}

/* sweep_eval's Q part for four targets at once: the four Clenshaw recurrences are independent,
 * so interleaving them hides the latency of each step's dependent multiply-add (the recurrence
 * is the hot loop of the whole matrix); each lane does exactly sweep_eval's arithmetic. */
void sweep_eval4(const struct sweep *sw, int m, const struct target *tg, double *wq)
{
    const double *c[4];
    double t[4], t2[4], base[4], b1[4] = {0, 0, 0, 0}, b2[4] = {0, 0, 0, 0};
    for (int l = 0; l < 4; l++) {
        const double *g = sweep_find(sw, SEG_STRIDE(m), tg[l].s, &t[l]);
        t2[l] = 2 * t[l];
        c[l] = g + SEG_CQ;
        base[l] = g[2];
    }
    for (int k = m; k >= 1; k--)
        for (int l = 0; l < 4; l++) {
            double b0 = t2[l] * b1[l] + (c[l][k] - b2[l]);
            b2[l] = b1[l];
            b1[l] = b0;
        }
    for (int l = 0; l < 4; l++)
        wq[tg[l].at] = base[l] + (t[l] * b1[l] + (c[l][0] - b2[l]));
}

/* The Clenshaw sums of eight series c[l] at t[l] (sweep_eval4's recurrence for eight targets),
 * two to an SSE2 register (x86-64's baseline): with four
 * recurrences in flight a step still waited on the multiply-add of the one before, eight fill the
 * pipeline. Packed multiplies, adds and subtractions round exactly as the scalar ones (no fused
 * multiply-add: ISO C mode does not contract), so each lane is still sweep_eval's arithmetic. */
void clenshaw8(const double *const c[8], const double t[8], int m, double out[8])
{
#if defined(__SSE2__)
    double b1s[8], b2s[8];
    __m128d t2[4], b1[4], b2[4];
    for (int v = 0; v < 4; v++) {
        t2[v] = _mm_set_pd(2 * t[2 * v + 1], 2 * t[2 * v]);
        b1[v] = b2[v] = _mm_setzero_pd();
    }
    for (int k = m; k >= 1; k--)
        for (int v = 0; v < 4; v++) {
            __m128d ck = _mm_loadh_pd(_mm_load_sd(&c[2 * v][k]), &c[2 * v + 1][k]);
            __m128d b0 = _mm_add_pd(_mm_mul_pd(t2[v], b1[v]), _mm_sub_pd(ck, b2[v]));
            b2[v] = b1[v];
            b1[v] = b0;
        }
    for (int v = 0; v < 4; v++) {
        _mm_storeu_pd(b1s + 2 * v, b1[v]);
        _mm_storeu_pd(b2s + 2 * v, b2[v]);
    }
    for (int l = 0; l < 8; l++)
        out[l] = t[l] * b1s[l] + (c[l][0] - b2s[l]);
#else
    for (int l = 0; l < 8; l++)
        out[l] = radial_clenshaw(c[l], m, t[l]);
#endif
}

void sweep_eval8(const struct sweep *sw, int m, const struct target *tg, double *wq)
{
    const double *c[8];
    double t[8], base[8], out[8];
    for (int l = 0; l < 8; l++) {
        const double *g = sweep_find(sw, SEG_STRIDE(m), tg[l].s, &t[l]);
        c[l] = g + SEG_CQ;
        base[l] = g[2];
    }
    clenshaw8(c, t, m, out);
    for (int l = 0; l < 8; l++)
        wq[tg[l].at] = base[l] + out[l];
}

/* ---- the cross-call sweep cache ---- */

#define CACHE_BUDGET ((size_t)64 << 20) /* bytes of segments a cache may hold */

fit_design_cache_t *fit_design_cache_new(void)
{
    fit_design_cache_t *c = calloc(1, sizeof *c);
    if (c) c->budget = CACHE_BUDGET;
    return c;
}

void fit_design_cache_free(fit_design_cache_t *c)
{
    if (!c) return;
    for (size_t i = 0; i < c->n; i++)
        free(c->sw[i].seg);
    free(c->sw);
    free(c->slot);
    free(c);
}

fit_design_cache_stats_t fit_design_cache_stats(const fit_design_cache_t *c)
{
    fit_design_cache_stats_t st = {0};
    if (c) st = c->st, st.sweeps = c->n, st.bytes = c->bytes;
    return st;
}

/* The table slot of w (w > 0, so its bits are a fine key; Fibonacci hashing of the bits). */
static size_t cache_slot(const fit_design_cache_t *c, double w)
{
    uint64_t bits;
    memcpy(&bits, &w, sizeof bits);
    size_t mask = c->nslot - 1, i = (size_t)((bits * 0x9E3779B97F4A7C15ull) >> 20) & mask;
    while (c->slot[i] && c->sw[c->slot[i] - 1].w != w)
        i = (i + 1) & mask;
    return i;
}

/* Doubles the table (rehashing every sweep). Returns 0 or -ENOMEM. */
static int cache_grow(fit_design_cache_t *c)
{
    size_t nslot = c->nslot ? 2 * c->nslot : 1024, *old = c->slot, oldn = c->nslot;
    size_t *slot = calloc(nslot, sizeof *slot);
    struct sweep *sw = realloc(c->sw, sizeof *sw * nslot / 2);
    if (!slot || !sw) {
        free(slot);
        if (sw) c->sw = sw;
        return -ENOMEM;
    }
    c->sw = sw;
    c->cap = nslot / 2;
    c->slot = slot;
    c->nslot = nslot;
    for (size_t i = 0; i < oldn; i++)
        if (old[i]) c->slot[cache_slot(c, c->sw[old[i] - 1].w)] = old[i];
    free(old);
    return 0;
}

/* The sweep for w covering E up to emax: the cache's (built or extended as needed) when there is
 * a cache for these options with room, else the scratch sweep built afresh. NULL when out of
 * memory. *evals grows by the radial evaluations done. */
const struct sweep *sweep_get(fit_design_cache_t *c, const struct cheb *ch,
                              const fit_design_opts_t *o, struct sweep *scratch, double w,
                              double emax, size_t *evals)
{
    struct sweep *sw = NULL;
    if (c && c->order == ch->m && c->near_foot == ch->near_foot && c->seg_dv == o->seg_dv &&
        c->seg_ds == o->seg_ds) {
        size_t i = cache_slot(c, w);
        if (c->slot[i]) {
            sw = &c->sw[c->slot[i] - 1];
            c->st.hits++;
        } else if (c->bytes < c->budget && (c->n < c->nslot / 2 || cache_grow(c) == 0)) {
            i = cache_slot(c, w); /* the table may have grown */
            sw = &c->sw[c->n];
            *sw = (struct sweep){.seg = NULL};
            sweep_reset(sw, w);
            c->slot[i] = ++c->n;
            c->st.misses++;
        }
    }
    size_t ev;
    if (sw) {
        ev = sweep_extend(ch, o, sw, emax, &c->bytes);
    } else {
        sweep_reset(scratch, w);
        ev = sweep_extend(ch, o, scratch, emax, NULL);
        sw = scratch;
    }
    if (ev == (size_t)-1) return NULL;
    /* the cost counted is the segments up to emax, those with a start below it (a fresh sweep
     * builds exactly these), whether built now or found in the cache: a fit reports the same
     * count whatever ran before it on its cache (the sweep's r on threads, pipeline.h) */
    size_t lo = 0, hi = (size_t)sw->nseg, stride = SEG_STRIDE(ch->m);
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (sw->seg[mid * stride] < emax)
            lo = mid + 1;
        else
            hi = mid;
    }
    *evals += lo * (size_t)ch->m;
    return sw;
}

/* Makes the cache serve these options when it serves none yet (it keeps its first options'). */
void cache_claim(fit_design_cache_t *c, const struct cheb *ch, const fit_design_opts_t *o)
{
    if (c && c->order == 0 && cache_grow(c) == 0) {
        c->order = o->order;
        c->seg_dv = o->seg_dv;
        c->seg_ds = o->seg_ds;
        c->near_foot = ch->near_foot;
    }
}

/* Chebyshev points of the first kind and the DCT matrix for m points per segment. */
void cheb_init(struct cheb *ch, int m)
{
    ch->m = m;
    for (int k = 0; k < m; k++) {
        ch->t[k] = cos(M_PI * (k + 0.5) / m);
        for (int j = 0; j < m; j++)
            ch->cosm[j][k] = cos(M_PI * j * (k + 0.5) / m);
    }
}
