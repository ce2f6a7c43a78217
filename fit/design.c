/* design.c: fast design matrix by shared cumulative wedge sweeps (see design.h and corner.h).
 *
 * Every node (e_i, e_j) of the sub-pixel grid needs, for each spot, two wedge integrals
 * W(w, S) = int_0^S f(w cosh s) / cosh s ds (f = Q or P): one for the vertical line x = e_i
 * (w = a |e_i - xk|, S = asinh(|e_j - yk| / |e_i - xk|)) and one for the horizontal line.
 * For a given w these are prefix integrals of one integrand, so one sweep per distinct w serves
 * all its targets, over all spots: on the paper's 9 x 9 grid the 81 spots share 9 column
 * offsets, and the number of sweeps drops ninefold. Each sweep samples the integrand at m
 * Chebyshev points per segment and integrates the interpolant in closed form (Clenshaw-Curtis
 * style), so any target inside a segment costs one short Clenshaw sum, not a new quadrature.
 *
 * The sweep variable is E = e^s = tan T + sec T (so T = 2 atan E - pi/2): then cosh s =
 * (E + 1/E)/2, ds = dE / E and W = int_1^E f(w (E + 1/E) / 2) * 2 / (1 + E^2) dE, and a target
 * is E = (|v| + hypot(u, v)) / |u|: no exp, log or asinh anywhere in the hot loops. Segments are
 * limited to a ratio e^seg_ds in E (the 1/cosh s scale) and to seg_dv in v = w cosh s (the
 * period pi of the oscillating part of Q). The sweeps themselves (segments, Clenshaw sums, the
 * cache) are wedge_sweep.c's; this file finds which (line, spot) pairs need which targets, and
 * assembles the cells. Memory is bounded by doing spots in batches.
 *
 * A node's wedge along one line depends only on the line's distance from the spot and the
 * spot's coordinate along it, so (spot, line) pairs that agree in both (bit for bit) share one
 * row of wedge values (wedge_pass). A raster symmetric about the pixel centre with the same
 * offsets in x as in y has each row about five times (41 x 41 at r = 16: 57072 pairs, 11316
 * distinct rows; the 9 x 9 reference scan: 3.7 times), so the design matrix costs in proportion
 * to the distinct edge-line * rows, not to spots x nodes. The bookkeeping scales the same way:
 * the pairs are found through the spots' distinct coordinates (a raster's 41 columns, not its
 * 1681 spots, are sorted by distance), a row is found by its along-coordinate's number, and each
 * spot's nodes read their two rows when its matrix row is assembled, so no per-spot array of
 * node values is filled (the 41 x 41 sweep's design matrices: 81 -> 49 ms, with the batch below
 * holding the whole raster). */
#include "fit/design.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fit/airy.h"
#include "corner.h"
#include "radial.h"
#include "wedge_sweep.h"

/* Spots per batch: as many as BATCH_BYTES of node and pair buffers hold (rows of wedges are
 * shared only inside a batch, so a raster is best done in one: the 41 x 41 raster's r = 16 in
 * three batches evaluated 2.1 times the wedges of one), but at least BATCH_MIN. */
#define BATCH_BYTES ((size_t)24 << 20)
#define BATCH_MIN 256

fit_design_opts_t fit_design_opts_for_tol(double tol)
{
    /* calibrated against fit_box_integral on the reference scan positions at r = 7 for
     * R = 1.34 um and R = 30 um (the harder one); `ips bench` prints the table */
    fit_design_opts_t o = {.order = 16, .seg_dv = 2.0, .seg_ds = 0.5, .skip_tol = tol / 100};
    if (tol >= 1e-3) o.order = 6;
    else if (tol >= 1e-5) o.order = 8;
    else if (tol >= 1e-7) o.order = 10;
    else if (tol >= 1e-9) o.order = 12;
    else if (tol >= 1e-11) o.order = 14;
    else if (tol >= 1e-13) o.order = 16;
    else o.order = 20;
    return o;
}

/* ---- the design matrix ---- */

/* A (spot, line) pair of the batch: the line l of direction dir (0: vertical, x = e_l; 1:
 * horizontal) at distance dist from spot k. Its wedges (the n1 nodes on the line) depend only
 * on dist and on the spot's coordinate along the line (y_k for dir 0, x_k for dir 1): pairs
 * that agree in both (bit for bit) share one row of wedge values. */
struct line_pair {
    double dist; /* |e_l - the spot's coordinate across the line| (um) */
    int k, ld;   /* spot; ld = 2 l + dir */
};

/* Sorts p[0..np) stably by dist (>= 0, so its bits order as unsigned integers do), ping-ponging
 * with tmp (np entries); returns the sorted array (p or tmp). An LSD radix sort, one byte a pass,
 * skipping the bytes all keys share (the exponent's, mostly): qsort with its comparison callback
 * was 7 % of the reference fit's instructions (callgrind). */
static struct line_pair *sort_pairs(struct line_pair *p, struct line_pair *tmp, size_t np)
{
    size_t count[8][256] = {{0}};
    if (!np) return p;
    for (size_t q = 0; q < np; q++) {
        uint64_t b;
        memcpy(&b, &p[q].dist, sizeof b);
        for (int d = 0; d < 8; d++) count[d][(b >> (8 * d)) & 255]++;
    }
    for (int d = 0; d < 8; d++) {
        uint64_t b0;
        memcpy(&b0, &p[0].dist, sizeof b0);
        if (count[d][(b0 >> (8 * d)) & 255] == np) continue; /* one byte value: nothing moves */
        size_t at = 0;
        for (int v = 0; v < 256; v++) {
            size_t c = count[d][v];
            count[d][v] = at;
            at += c;
        }
        for (size_t q = 0; q < np; q++) {
            uint64_t b;
            memcpy(&b, &p[q].dist, sizeof b);
            tmp[count[d][(b >> (8 * d)) & 255]++] = p[q];
        }
        struct line_pair *t = p;
        p = tmp;
        tmp = t;
    }
    return p;
}

/* One row of a run in wedge_pass: its targets tg[t0..t1), their least and largest E, and
 * whether its line's needed nodes all lie on one side of the spot's foot (so the wedges' common
 * prefix from the foot cancels: see sweep_offset_pays). */
struct row_span {
    size_t t0, t1;
    double smin, smax;
    double dmax;           /* the largest target's E - 1 */
    double omin, hmin, d0; /* the least target's distance from the foot along the line, from
                              the spot, and its E - 1 */
    int m0;                /* the least target's node */
    int one_sided;
};

/* The distinct spot coordinates of a batch: an open-addressing table from the bits of a
 * coordinate to its number (spots_by_coordinate). */
struct coord_slot {
    uint64_t key;
    uint32_t id, used;
};

struct work {
    int r, n1;
    const double *e;
    double a;
    double near2;             /* cells nearer than sqrt(near2) to the spot are never left out */
    const double *x, *y;      /* spot positions of the batch */
    uint32_t *krow;           /* [k][dir][l]: the row of wedges of spot k's line l (dir 0:
                                 vertical, x = e_l; 1: horizontal), the n1 nodes along it */
    unsigned char *need, *skip; /* [k][node] wedges needed (1: Q, 2: Q and P), [k][cell] left out */
    unsigned char *full;      /* [k]: every node of spot k needs Q (mark_cells' shortcut), and P
                                 exactly those in the window pwin */
    int *pwin;                /* [k][4]: then the nodes i0..i1, j0..j1 of the cells holding it */
    double *gs;               /* [node]: signed node values of the row being assembled */
    double *axis;             /* [4 n1]: assemble_row's signs and on-axis marks per node line */
    struct target *tg;        /* the targets of one sweep */
    size_t tg_cap;
    struct row_span *span;    /* [row - row0]: the run's rows' targets (wedge_pass) */
    size_t span_cap;
    double *vq;               /* [row][m]: Q wedges of the batch's rows at node m of n1 */
    unsigned char *rneed;     /* [row][m]: what the row's pairs need there (1: Q, 2: Q and P) */
    double *ralong;           /* [row]: the spots' coordinate along the row's line */
    unsigned char *rfull;     /* [row]: rneed is already at least 1 at every node */
    uint32_t *rowp;           /* [row]: its row of P wedges in vp, for the few rows that need P
                                 (a line next to a spot), else UINT32_MAX */
    double *vp;               /* [rowp][m]: P wedges */
    size_t row_cap, prow_cap;
    struct line_pair *pairs;  /* the pairs of one run of equal distance (up to 2 * n1 * batch) */
    struct line_pair *items;  /* (line, distinct coordinate) items, their k the coordinate's
                                 number: 2 * n1 * batch, then as many for sort_pairs */
    uint32_t *ulist[2], *ustart[2], *cid[2]; /* spots_by_coordinate's, per direction: batch,
                                                2 * batch + 1 and batch entries */
    uint32_t *rstamp, *rrow;  /* [coordinate]: the run that last made a row of it, and the row */
    struct coord_slot *slots;   /* at least 4 * batch of them, a power of two */
    size_t nslot;
    size_t batch;
    struct sweep sw;
};

/* The squared distance below which no cell's leave-out bound (its area times the envelope
 * 2.4701 v^(-8/3) at its nearest point, airy.h) can be below the limit: the envelope is
 * non-increasing, so every cell (the smallest of area A) is kept while 2.4701 (a d)^(-8/3) A >= limit,
 * i.e. d <= (2.4701 A / limit)^(3/8) / a; 0.999 of that guards the rounding of pow(). */
static double near_distance2(const fit_design_opts_t *o, double a, const double *e, int r)
{
    double limit = o->skip_tol * fit_airy_total(a), area = INFINITY;
    for (int i = 0; i < r; i++)
        for (int j = 0; j < r; j++) area = fmin(area, (e[i + 1] - e[i]) * (e[j + 1] - e[j]));
    if (!(limit > 0) || area * 0.5 < limit) return 0; /* the cap at 1 could matter: no shortcut */
    double d = 0.999 * pow(2.4701 * area / limit, 3.0 / 8.0) / a;
    return d * d;
}

/* Marks, for spot k of the batch, the cells left out and the nodes needed. */
static void mark_cells(const fit_design_opts_t *o, struct work *wk, int k, fit_design_stats_t *st)
{
    int r = wk->r, n1 = wk->n1;
    const double *e = wk->e;
    unsigned char *need = wk->need + (size_t)k * n1 * n1, *skip = wk->skip + (size_t)k * r * r;
    double xk = wk->x[k], yk = wk->y[k], limit = o->skip_tol * fit_airy_total(wk->a);
    /* Every cell kept when even the pixel's far corner is nearer than near2 (each cell's dx, dy
     * below are at most DX, DY, and rounding keeps the order): all nodes need Q, the corners of
     * the cells holding the spot P too; the same marks as the loop below, without it (the
     * reference tolerance keeps every cell of a 1.34 um spot on a 6 um pixel) */
    double DX = fmax(fmax(e[r] - xk, xk - e[0]), 0), DY = fmax(fmax(e[r] - yk, yk - e[0]), 0);
    int *pwin = wk->pwin + 4 * (size_t)k;
    if (!(limit > 0) || DX * DX + DY * DY < wk->near2) {
        memset(skip, 0, (size_t)r * r);
        memset(need, 1, (size_t)n1 * n1);
        pwin[0] = pwin[2] = n1, pwin[1] = pwin[3] = -1; /* empty */
        for (int j = 0; j < r; j++) {
            if (!(yk >= e[j] && yk <= e[j + 1])) continue;
            for (int i = 0; i < r; i++)
                if (xk >= e[i] && xk <= e[i + 1]) {
                    need[j * n1 + i] = need[j * n1 + i + 1] = need[(j + 1) * n1 + i] =
                        need[(j + 1) * n1 + i + 1] = 2;
                    pwin[0] = i < pwin[0] ? i : pwin[0], pwin[1] = i + 1;
                    pwin[2] = j < pwin[2] ? j : pwin[2], pwin[3] = j + 1;
                }
        }
        wk->full[k] = 1;
        return;
    }
    wk->full[k] = 0;
    memset(need, 0, (size_t)n1 * n1);
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            int left_out = 0;
            if (limit > 0) {
                double dx = e[i] - xk > xk - e[i + 1] ? e[i] - xk : xk - e[i + 1];
                double dy = e[j] - yk > yk - e[j + 1] ? e[j] - yk : yk - e[j + 1];
                dx = dx > 0 ? dx : 0;
                dy = dy > 0 ? dy : 0;
                /* nearer than near2, the bound cannot be below the limit: no pow() */
                double bound = dx * dx + dy * dy < wk->near2
                                   ? limit
                                   : (e[i + 1] - e[i]) * (e[j + 1] - e[j]) *
                                         fit_airy_envelope(wk->a, hypot(dx, dy));
                if (bound < limit) {
                    left_out = 1;
                    st->skipped++;
                    if (bound > st->max_skipped_bound) st->max_skipped_bound = bound;
                }
            }
            skip[j * r + i] = (unsigned char)left_out;
            if (left_out) continue;
            /* 1: the node's Q wedges are needed; 2: its P wedges too (a cell holding the spot) */
            unsigned char mark = (xk >= e[i] && xk <= e[i + 1] && yk >= e[j] && yk <= e[j + 1]) ? 2 : 1;
            int nd[4] = {j * n1 + i, j * n1 + i + 1, (j + 1) * n1 + i, (j + 1) * n1 + i + 1};
            for (int c = 0; c < 4; c++)
                if (need[nd[c]] < mark) need[nd[c]] = mark;
        }
}

/* Room for nt targets of one sweep. Returns 0 or -ENOMEM. */
static int targets_reserve(struct work *wk, size_t nt)
{
    if (nt <= wk->tg_cap) return 0;
    struct target *t = realloc(wk->tg, sizeof *t * 2 * nt);
    if (!t) return -ENOMEM;
    wk->tg = t;
    wk->tg_cap = 2 * nt;
    return 0;
}

/* Room for nrow rows of wedges in the batch (their Q values, needs and coordinates) and for
 * nprow rows of P values. Returns 0 or -ENOMEM. */
static int rows_reserve(struct work *wk, size_t nrow, size_t nprow)
{
    size_t n1 = (size_t)wk->n1;
    if (nrow > wk->row_cap) {
        size_t cap = 2 * nrow;
        double *v = realloc(wk->vq, sizeof *v * cap * n1);
        if (v) wk->vq = v;
        unsigned char *rn = v ? realloc(wk->rneed, cap * n1) : NULL;
        if (rn) wk->rneed = rn;
        double *al = rn ? realloc(wk->ralong, sizeof *al * cap) : NULL;
        if (al) wk->ralong = al;
        uint32_t *rp = al ? realloc(wk->rowp, sizeof *rp * cap) : NULL;
        if (rp) wk->rowp = rp;
        unsigned char *rf = rp ? realloc(wk->rfull, cap) : NULL;
        if (!rf) return -ENOMEM;
        wk->rfull = rf;
        wk->row_cap = cap;
    }
    if (nprow > wk->prow_cap) {
        size_t cap = 2 * nprow;
        double *v = realloc(wk->vp, sizeof *v * cap * n1);
        if (!v) return -ENOMEM;
        wk->vp = v;
        wk->prow_cap = cap;
    }
    return 0;
}

/* The distinct coordinates of the batch's spots, x and y together (bit for bit, through the
 * coordinate table): cid[dir][k] numbers spot k's x (dir 0) or y (dir 1) among them, and, per direction,
 * ustart[dir][u]..ustart[dir][u + 1] index ulist[dir], the spots whose coordinate across that
 * direction's lines (x for the vertical ones, dir 0) is the u-th value. Returns their number. */
static size_t spots_by_coordinate(struct work *wk, int nb)
{
    size_t nu = 0, mask = wk->nslot - 1;
    memset(wk->slots, 0, sizeof *wk->slots * wk->nslot);
    for (int dir = 0; dir < 2; dir++)
        for (int k = 0; k < nb; k++) {
            uint64_t bits;
            memcpy(&bits, dir ? &wk->y[k] : &wk->x[k], sizeof bits);
            for (size_t i = (size_t)((bits * 0x9E3779B97F4A7C15ull) >> 24) & mask;;
                 i = (i + 1) & mask) {
                struct coord_slot *sl = &wk->slots[i];
                if (!sl->used) {
                    *sl = (struct coord_slot){bits, (uint32_t)nu++, 1};
                    wk->cid[dir][k] = sl->id;
                    break;
                }
                if (sl->key == bits) {
                    wk->cid[dir][k] = sl->id;
                    break;
                }
            }
        }
    for (int dir = 0; dir < 2; dir++) { /* a counting sort of the spots by cid */
        uint32_t *start = wk->ustart[dir];
        memset(start, 0, sizeof *start * (nu + 1));
        for (int k = 0; k < nb; k++) start[wk->cid[dir][k] + 1]++;
        for (size_t u = 0; u < nu; u++) start[u + 1] += start[u];
        for (int k = 0; k < nb; k++) wk->ulist[dir][start[wk->cid[dir][k]]++] = (uint32_t)k;
        for (size_t u = nu; u > 0; u--) start[u] = start[u - 1]; /* back to the starts */
        start[0] = 0;
    }
    memset(wk->rstamp, 0, sizeof *wk->rstamp * nu);
    return nu;
}

/* An upper estimate of the segments of a sweep at w from E0 to E1 (each advances E by e^seg_ds
 * or v = w (E + 1/E) / 2 by seg_dv, and with near_foot the offset from E0 by seg_dv / w twice,
 * then by e^seg_ds: sweep_extend; fit_design_cost's count). */
static double sweep_segments(const fit_design_opts_t *o, int near_foot, double w, double E0,
                             double E1)
{
    if (!(E1 > E0)) return 0;
    double dv = w * 0.5 * ((E1 + 1 / E1) - (E0 + 1 / E0)), grow = exp(o->seg_ds) - 1;
    double near = near_foot ? 2 + ceil(log(fmax(1, grow * w * (E1 - E0) / o->seg_dv)) / o->seg_ds)
                            : 0;
    return ceil(log(E1 / E0) / o->seg_ds) + ceil(dv / o->seg_dv) + 1 + near;
}

/* Whether any spot lies outside the pixel [0, pitch]^2 (cells then come as small differences of
 * wedges: the sweeps start near_foot). */
static int any_outside(double pitch, const double *x, const double *y, size_t n)
{
    for (size_t k = 0; k < n; k++)
        if (!(x[k] >= 0 && x[k] <= pitch && y[k] >= 0 && y[k] <= pitch)) return 1;
    return 0;
}

/* Whether the run's one-sided rows are cheaper each with a sweep of its own, from its least
 * target, than all rows with one sweep from the foot (E = 1). Such a row's wedges then lack the
 * same prefix (the sweep from 1 to its start), and that constant cancels in every cell: a cell
 * not holding the spot is a mixed second difference of its corners' signed values, which for the
 * two nodes of one line on the same side of the foot is a difference of that line's wedges with
 * one sign (design.c's assemble_row; the row's nodes on the other side, or at the foot, or any
 * corner of a cell holding the spot, which takes absolute values, make it not one-sided). For a
 * small spot far from the pixel the sweep from the foot crosses thousands of Airy rings the pixel
 * never sees (R = 0.012 um 500 um away: 33,000 segments for a 6 um pixel's 700); from its nodes
 * it crosses only those between them, and its wedges no longer come as differences of two large
 * prefixes (fewer digits lost). Estimates by sweep_segments; 1 when the one-sided rows' sweeps
 * are fewer segments in all. */
static int sweep_offset_pays(const fit_design_opts_t *o, int near_foot, double w,
                             const struct row_span *sp, size_t nrows)
{
    double smax = 1, rest = 1, own = 0;
    int any = 0;
    for (size_t q = 0; q < nrows; q++) {
        if (sp[q].t1 == sp[q].t0) continue;
        smax = fmax(smax, sp[q].smax);
        if (sp[q].one_sided) {
            own += sweep_segments(o, near_foot, w, sp[q].smin, sp[q].smax);
            any = 1;
        } else {
            rest = fmax(rest, sp[q].smax);
        }
    }
    return any && sweep_segments(o, near_foot, w, 1, rest) + own <
                      sweep_segments(o, near_foot, w, 1, smax);
}

/* The wedges of targets tg[0..nt) from sweep sw: Q into wk->vq, and P too (into wk->vp) at the
 * corners of a cell holding the spot (need 2, rare). */
static void eval_targets(const struct sweep *sw, int m, const struct target *tg, size_t nt,
                         struct work *wk)
{
    size_t t = 0, n1 = (size_t)wk->n1;
    for (; t + 8 <= nt; t += 8) sweep_eval8(sw, m, tg + t, wk->vq);
    for (; t + 4 <= nt; t += 4) sweep_eval4(sw, m, tg + t, wk->vq);
    for (; t < nt; t++) sweep_eval(sw, m, tg[t].s, &wk->vq[tg[t].at], NULL);
    for (t = 0; t < nt; t++)
        if (tg[t].need == 2) {
            size_t at = tg[t].at;
            sweep_eval(sw, m, tg[t].s, &wk->vq[at],
                       &wk->vp[(size_t)wk->rowp[at / n1] * n1 + at % n1]);
        }
}

/* A one-sided row's targets as E less the least target's E, from the nodes' distance along the
 * line (exact) rather than as the difference of two E, each rounded to ulp(E) (far from the
 * pixel the nodes of a line are ~1e-3 apart in E, and a cell is a second difference of them):
 * E - E0 = ((o - o0) + (h - h0)) / dist, h - h0 = (o - o0)(o + o0) / (h + h0), with o the
 * distance of a node from the foot along the line and h its distance from the spot. */
static void one_sided_offsets(struct work *wk, const struct row_span *sp, double dist)
{
    size_t n1 = (size_t)wk->n1;
    for (size_t t = sp->t0; t < sp->t1; t++) {
        struct target *p = &wk->tg[t];
        double dd = fabs(wk->e[p->at % n1] - wk->e[sp->m0]);
        p->s = dd * (1 + (p->o + sp->omin) / (p->h + sp->hmin)) / dist;
    }
}

/* The wedges of the run's rows from the foot's sweep, the targets eight at a time across rows.
 * A one-sided row's wedges are each less the wedge at the row's least target (a constant that
 * cancels in its cells), summed from the segments between them rather than taken as a
 * difference of two prefixes from the foot, which for a line far from its spot's foot are nearly
 * equal and large (the flux of the whole wedge) against the cells: first each target's integral
 * from its segment's start (its offset added to d0 - mid, not d0 to it, so that it keeps its
 * digits), then, row by row in order of offset (a one-sided row's nodes are in order along the
 * line; any other order would only start the sum again), the whole segments up to it, each
 * segment's stored integral once. */
static void eval_from_foot(const struct sweep *sw, int m, struct work *wk,
                           const struct row_span *span, size_t nrows)
{
    int stride = SEG_STRIDE(m);
    struct target plain[8];
    struct target *side[8];
    const double *c[8];
    double tt[8], out[8];
    int np = 0, ns = 0;
    for (size_t q = 0; q < nrows; q++) {
        const struct row_span *sp = &span[q];
        for (size_t t = sp->t0; t < sp->t1; t++) {
            struct target *p = &wk->tg[t];
            if (!sp->one_sided) {
                plain[np++] = *p;
                if (np == 8) eval_targets(sw, m, plain, 8, wk), np = 0;
                continue;
            }
            const double *g = sweep_find_from(sw, stride, sp->d0, p->s, &tt[ns]);
            c[ns] = g + SEG_CQ;
            p->seg = (uint32_t)((g - sw->seg) / stride);
            side[ns++] = p;
            if (ns == 8) {
                clenshaw8(c, tt, m, out);
                for (int l = 0; l < 8; l++) wk->vq[side[l]->at] = out[l];
                ns = 0;
            }
        }
    }
    if (np) eval_targets(sw, m, plain, (size_t)np, wk);
    for (int l = 0; l < ns; l++) wk->vq[side[l]->at] = radial_clenshaw(c[l], m, tt[l]);
    for (size_t q = 0; q < nrows; q++) {
        const struct row_span *sp = &span[q];
        if (!sp->one_sided || sp->t1 == sp->t0) continue;
        double ta, run = 0;
        const double *ga = sweep_find_from(sw, stride, sp->d0, 0, &ta), *g = ga;
        double pa = radial_clenshaw(ga + SEG_CQ, m, ta);
        size_t nt = sp->t1 - sp->t0;
        const struct target *tg = wk->tg + sp->t0;
        int back = nt > 1 && tg[nt - 1].s < tg[0].s;
        for (size_t k = 0; k < nt; k++) {
            const struct target *p = &tg[back ? nt - 1 - k : k];
            const double *gb = sw->seg + (size_t)p->seg * stride;
            if (gb < g) g = ga, run = 0;
            for (; g < gb; g += stride) run += g[SEG_TQ];
            wk->vq[p->at] = (wk->vq[p->at] - pa) + run;
        }
    }
}

/* All wedges of the batch, both directions at once. The pairs are grouped by line distance (one
 * sweep per w) and, inside a group, by the spot's coordinate along the line: pairs equal in both
 * have the same targets, so each such row of n1 wedges is evaluated once, and krow tells every
 * pair's spot which row its line's wedges are in (assemble_row reads them there). The values
 * are those of evaluating every pair on its own, bit for bit (the same arithmetic on the same
 * numbers), and the Q wedges of a node's two lines are summed by assemble_row (one + the other:
 * the same sum in either order, as the earlier 0 + one + the other was for these non-negative
 * integrals). */
static int wedge_pass(const struct cheb *ch, const fit_design_opts_t *o, struct work *wk, int nb,
                      size_t *evals)
{
    int n1 = wk->n1;
    size_t ni = 0, nodes = (size_t)n1 * n1;
    /* the pair of spot k and line l has distance |e_l - across_k|: one item per line and
     * distinct across-coordinate, sorted by distance, stands for all the spots at that coordinate
     * (a raster's 41 columns, not its 1681 spots) */
    size_t nu = spots_by_coordinate(wk, nb);
    for (int dir = 0; dir < 2; dir++) {
        const double *across = dir ? wk->y : wk->x;
        for (size_t u = 0; u < nu; u++) {
            if (wk->ustart[dir][u] == wk->ustart[dir][u + 1]) continue; /* the other's only */
            for (int l = 0; l < n1; l++) {
                double dist = fabs(wk->e[l] - across[wk->ulist[dir][wk->ustart[dir][u]]]);
                if (wk->a * dist < FIT_CORNER_TINY) continue; /* its nodes are axis corners */
                wk->items[ni++] = (struct line_pair){dist, (int)u, 2 * l + dir};
            }
        }
    }
    const struct line_pair *it = sort_pairs(wk->items, wk->items + 2 * (size_t)n1 * wk->batch, ni);
    uint32_t stamp = 0; /* rstamp: 0 none, else the run that made the row */
    size_t nrow = 0, nprow = 0; /* rows of the batch so far, and those with P */
    for (size_t i0 = 0; i0 < ni;) { /* runs of equal dist (inside runs of equal w) */
        double dist = it[i0].dist, w = wk->a * dist, smax = 0, dmax = 0;
        size_t i1 = i0, nt = 0, row0 = nrow, np = 0;
        while (i1 < ni && it[i1].dist == dist) i1++;
        for (size_t i = i0; i < i1; i++) { /* the run's pairs: its items' spots */
            int dir = it[i].ld & 1;
            const uint32_t *k = wk->ulist[dir], *start = wk->ustart[dir];
            for (uint32_t q = start[it[i].k]; q < start[it[i].k + 1]; q++)
                wk->pairs[np++] = (struct line_pair){dist, (int)k[q], it[i].ld};
        }
        const struct line_pair *pr = wk->pairs;
        if (rows_reserve(wk, nrow + np, 0)) return -ENOMEM;
        stamp++; /* unique per run within a batch */
        for (size_t q = 0; q < np; q++) { /* rows, and what any pair of each needs */
            int k = pr[q].k, l = pr[q].ld >> 1, dir = pr[q].ld & 1;
            uint32_t along = wk->cid[!dir][k], row; /* rows: the run's distinct along-coordinates */
            if (wk->rstamp[along] != stamp) {
                wk->rstamp[along] = stamp;
                wk->rrow[along] = row = (uint32_t)nrow++;
                wk->ralong[row] = dir ? wk->x[k] : wk->y[k];
                memset(wk->rneed + row * (size_t)n1, 0, (size_t)n1);
                wk->rfull[row] = 0;
            } else
                row = wk->rrow[along];
            wk->krow[((size_t)k * 2 + (size_t)dir) * (size_t)n1 + (size_t)l] = row;
            unsigned char *rn = wk->rneed + row * (size_t)n1;
            const unsigned char *need = wk->need + (size_t)k * nodes;
            int m0 = 0, m1 = n1 - 1; /* the nodes along the line whose need can raise rn */
            if (wk->full[k]) { /* 1 everywhere, 2 only inside the window */
                const int *pw = wk->pwin + 4 * (size_t)k;
                if (!wk->rfull[row]) {
                    for (int m = 0; m < n1; m++) rn[m] = rn[m] ? rn[m] : 1;
                    wk->rfull[row] = 1;
                }
                int across_in = dir ? l >= pw[2] && l <= pw[3] : l >= pw[0] && l <= pw[1];
                m0 = across_in ? (dir ? pw[0] : pw[2]) : n1;
                m1 = dir ? pw[1] : pw[3];
            }
            for (int m = m0; m <= m1; m++) {
                unsigned char nd = need[dir ? l * n1 + m : m * n1 + l];
                if (nd > rn[m]) rn[m] = nd;
            }
        }
        if (targets_reserve(wk, (nrow - row0) * (size_t)n1)) return -ENOMEM;
        if (nrow - row0 > wk->span_cap) {
            struct row_span *sp = realloc(wk->span, sizeof *sp * 2 * (nrow - row0));
            if (!sp) return -ENOMEM;
            wk->span = sp;
            wk->span_cap = 2 * (nrow - row0);
        }
        int offsets = 0; /* any row that may start its own sweep */
        for (size_t row = row0; row < nrow; row++) { /* the targets of the run's rows */
            unsigned char *rn = wk->rneed + row * (size_t)n1;
            struct row_span *sp = &wk->span[row - row0];
            int below = 0, above = 0, foot = 0; /* needed nodes before, after, at the foot */
            *sp = (struct row_span){.t0 = nt, .smin = INFINITY, .smax = 1};
            wk->rowp[row] = UINT32_MAX;
            for (int m = 0; m < n1; m++) {
                double at = wk->e[m] - wk->ralong[row], other = fabs(at);
                if (!rn[m] || wk->a * other < FIT_CORNER_TINY) {
                    foot |= rn[m] != 0;
                    rn[m] = 0;
                    continue;
                }
                below |= at < 0, above |= at > 0;
                /* E, and the target E - 1 without the cancellation of 1 + 0.001 - 1 */
                double hy = sqrt(other * other + dist * dist),
                       df = (other + other * other / (hy + dist)) / dist, s = 1 + df;
                if (s > smax) smax = s;
                if (s < sp->smin) sp->omin = other, sp->hmin = hy, sp->d0 = df, sp->m0 = m;
                sp->smin = fmin(sp->smin, s), sp->smax = fmax(sp->smax, s);
                sp->dmax = fmax(sp->dmax, df);
                wk->tg[nt++] = (struct target){df, row * (size_t)n1 + (size_t)m, rn[m], 0, other, hy};
                if (rn[m] == 2 && wk->rowp[row] == UINT32_MAX) {
                    if (rows_reserve(wk, 0, nprow + 1)) return -ENOMEM;
                    wk->rowp[row] = (uint32_t)nprow++;
                }
            }
            sp->t1 = nt;
            sp->one_sided = !foot && below != above && wk->rowp[row] == UINT32_MAX;
            offsets |= sp->one_sided;
            dmax = fmax(dmax, sp->dmax);
            if (sp->one_sided) one_sided_offsets(wk, sp, dist);
        }
        if (smax > 1 && offsets && sweep_offset_pays(o, ch->near_foot, w, wk->span, nrow - row0)) {
            /* the rows that straddle the foot share one sweep from it; each one-sided row has
             * its own from its least target (sweep_offset_pays) */
            double rest = 0;
            for (size_t q = 0; q < nrow - row0; q++)
                if (!wk->span[q].one_sided) rest = fmax(rest, wk->span[q].dmax);
            const struct sweep *sw = NULL;
            if (rest > 0 && !(sw = sweep_get(o->cache, ch, o, &wk->sw, w, rest, evals)))
                return -ENOMEM;
            for (size_t q = 0; q < nrow - row0; q++) {
                const struct row_span *sp = &wk->span[q];
                if (sp->one_sided || sp->t1 == sp->t0) continue;
                eval_targets(sw, ch->m, wk->tg + sp->t0, sp->t1 - sp->t0, wk);
            }
            for (size_t q = 0; q < nrow - row0; q++) { /* (the scratch sweep is free now) */
                const struct row_span *sp = &wk->span[q];
                if (!sp->one_sided || sp->t1 == sp->t0) continue;
                if (!(sp->smax > sp->smin)) { /* one node: its wedge is all constant */
                    for (size_t t = sp->t0; t < sp->t1; t++) wk->vq[wk->tg[t].at] = 0;
                    continue;
                }
                sweep_reset(&wk->sw, w);
                wk->sw.E0 = sp->smin; /* the prefix from here: the line's constant left out */
                double dm = 0;
                for (size_t t = sp->t0; t < sp->t1; t++) dm = fmax(dm, wk->tg[t].s);
                size_t ev = sweep_extend(ch, o, &wk->sw, dm, NULL);
                if (ev == (size_t)-1) return -ENOMEM;
                *evals += ev;
                eval_targets(&wk->sw, ch->m, wk->tg + sp->t0, sp->t1 - sp->t0, wk);
            }
        } else if (smax > 1) { /* some targets: one sweep from the foot */
            const struct sweep *sw = sweep_get(o->cache, ch, o, &wk->sw, w, dmax, evals);
            if (!sw) return -ENOMEM;
            if (!offsets) eval_targets(sw, ch->m, wk->tg, nt, wk); /* eight at a time */
            else eval_from_foot(sw, ch->m, wk, wk->span, nrow - row0);
        }
        i0 = i1;
    }
    return 0;
}

/* Cells of spot k from its node values (the sums of the wedges of each node's two lines, from
 * the rows wedge_pass left), into row (r*r). A cell that does not hold the spot is
 * minus the signed sum of its corners' G (corner.h), and the sign of a corner is that of its
 * quadrant, sgn(u) sgn(v), times the corner's place in the cell: so with the signed node values
 * g = sgn(u) sgn(v) G, computed once per node rather than once per cell corner, the cell is the
 * mixed second difference -(g[j+1][i+1] - g[j+1][i] - g[j][i+1] + g[j][i]) (added in
 * corner_combine's order). Cells holding the spot go through corner_combine with F. */
static void assemble_row(struct work *wk, int k, double *row)
{
    int r = wk->r, n1 = wk->n1;
    const double *e = wk->e;
    double xk = wk->x[k], yk = wk->y[k], unit = 2 / (wk->a * wk->a), *g = wk->gs;
    size_t base = (size_t)k * n1 * n1;
    const unsigned char *skip = wk->skip + (size_t)k * r * r, *need = wk->need + base;
    /* node (i, j) lies on the vertical line i (at m = j along it) and the horizontal line j (at
     * m = i): its Q wedges are in those two rows, whose sum is the node's (corner.h) */
    const uint32_t *rv = wk->krow + (size_t)k * 2 * n1, *rh = rv + n1;
    /* per node column i and row j: the sign of u = e_i - x_k (v = e_j - y_k) and whether the
     * node is on the axis through the spot */
    double *su = wk->axis, *sv = su + n1;
    unsigned char *tu = (unsigned char *)(sv + n1), *tv = tu + n1;
    for (int i = 0; i < n1; i++) {
        double u = e[i] - xk, v = e[i] - yk;
        su[i] = corner_sgn(u), tu[i] = wk->a * fabs(u) < FIT_CORNER_TINY;
        sv[i] = corner_sgn(v), tv[i] = wk->a * fabs(v) < FIT_CORNER_TINY;
    }
    for (int i = 0; i < n1; i++) { /* the vertical line's wedges, a row of them in vq */
        if (tu[i]) continue;          /* (a line through the spot has no row) */
        const double *w = wk->vq + (size_t)rv[i] * n1;
        /* only the nodes this spot needs: the row's other entries may never have been
         * evaluated (no other spot of the batch needed them) */
        for (int j = 0; j < n1; j++)
            if (need[j * n1 + i]) g[j * n1 + i] = w[j];
    }
    for (int j = 0; j < n1; j++) { /* plus the horizontal one's: the node's sum */
        /* (a line through the spot has no row: its nodes are on an axis) */
        const double *w = tv[j] ? NULL : wk->vq + (size_t)rh[j] * n1;
        for (int i = 0; i < n1; i++) {
            double sg = su[i] * sv[j];
            if (!need[j * n1 + i] || sg == 0) g[j * n1 + i] = 0;
            else if (tu[i] || tv[j]) g[j * n1 + i] = sg * (M_PI / 2); /* on an axis */
            else g[j * n1 + i] = sg * (g[j * n1 + i] + w[i]);
        }
    }
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            if (skip[j * r + i]) {
                row[j * r + i] = 0;
                continue;
            }
            if (!(su[i] <= 0 && su[i + 1] >= 0 && sv[j] <= 0 && sv[j + 1] >= 0)) {
                const double *g0 = g + j * n1 + i, *g1 = g0 + n1;
                row[j * r + i] = unit * (((-g0[0] + g0[1]) + g1[0]) - g1[1]);
                continue;
            }
            double uu[2] = {e[i] - xk, e[i + 1] - xk}, vv[2] = {e[j] - yk, e[j + 1] - yk};
            double fq[2][2], fp[2][2];
            for (int b = 0; b < 2; b++)
                for (int c = 0; c < 2; c++) {
                    size_t at0 = (size_t)rv[i + c] * n1 + (size_t)(j + b),
                           at1 = (size_t)rh[j + b] * n1 + (size_t)(i + c);
                    if (wk->a * fabs(uu[c]) < FIT_CORNER_TINY ||
                        wk->a * fabs(vv[b]) < FIT_CORNER_TINY) {
                        fq[b][c] = M_PI / 2; /* corner on an axis through the spot */
                        fp[b][c] = 0;
                    } else {
                        fq[b][c] = wk->vq[at0] + wk->vq[at1];
                        fp[b][c] = wk->vp[(size_t)wk->rowp[rv[i + c]] * n1 + (size_t)(j + b)] +
                                   wk->vp[(size_t)wk->rowp[rh[j + b]] * n1 + (size_t)(i + c)];
                    }
                }
            row[j * r + i] = unit * corner_combine(uu, vv, fq, fp, NULL);
        }
}

/* Node and pair buffers for batches of up to `batch` spots (freed by the caller). */
static int work_alloc(struct work *wk, size_t batch)
{
    size_t nodes = (size_t)wk->n1 * wk->n1, cells = (size_t)wk->r * wk->r;
    wk->gs = malloc(sizeof(double) * (nodes + 4 * (size_t)wk->n1));
    wk->axis = wk->gs ? wk->gs + nodes : NULL;
    wk->krow = malloc(sizeof *wk->krow * 2 * (size_t)wk->n1 * batch);
    wk->need = malloc((nodes + cells + 1) * batch);
    wk->pwin = malloc(sizeof *wk->pwin * 4 * batch);
    wk->batch = batch;
    wk->pairs = malloc(sizeof *wk->pairs * (size_t)wk->n1 * batch * 2);
    wk->items = malloc(sizeof *wk->items * (size_t)wk->n1 * batch * 4); /* and sort_pairs' */
    uint32_t *u = malloc(sizeof(uint32_t) * (12 * batch + 2));
    wk->ulist[0] = u;
    if (u) {
        wk->ulist[1] = u + batch;
        wk->cid[0] = u + 2 * batch;
        wk->cid[1] = u + 3 * batch;
        wk->rstamp = u + 4 * batch;
        wk->rrow = u + 6 * batch;
        wk->ustart[0] = u + 8 * batch;
        wk->ustart[1] = u + 10 * batch + 1;
    }
    for (wk->nslot = 16; wk->nslot < 4 * batch;) wk->nslot *= 2; /* 2 * batch coordinates */
    wk->slots = malloc(sizeof *wk->slots * wk->nslot);
    if (!wk->gs || !wk->krow || !wk->need || !wk->pwin || !wk->pairs || !wk->items || !wk->ulist[0] ||
        !wk->slots)
        return -ENOMEM;
    wk->skip = wk->need + nodes * batch;
    wk->full = wk->skip + cells * batch;
    return 0;
}


static int check_args(double R_um, double pitch, int r, const double *x, const double *y,
                      size_t n, const fit_design_opts_t *o, err_t *err)
{
    if (!(R_um > 0) || !isfinite(R_um))
        return err_set(err, -EINVAL, "spot radius must be a positive finite number (got %g)", R_um);
    if (!(pitch > 0) || !isfinite(pitch))
        return err_set(err, -EINVAL, "pixel pitch must be a positive finite number (got %g)", pitch);
    if (r < 1 || r > 256) return err_set(err, -EINVAL, "r must be in 1..256 (got %d)", r);
    for (size_t k = 0; k < n; k++)
        if (!isfinite(x[k]) || !isfinite(y[k]))
            return err_set(err, -EINVAL, "spot position %zu is not finite", k);
    if (o->order < 2 || o->order > MAX_ORDER)
        return err_set(err, -EINVAL, "quadrature order must be in 2..%d (got %d)", MAX_ORDER,
                       o->order);
    if (!(o->seg_dv > 0) || !(o->seg_ds > 0))
        return err_set(err, -EINVAL, "segment spans must be positive");
    return 0;
}

double fit_design_cost(double R_um, double pitch, int r, const double *x, const double *y,
                       size_t n, const fit_design_opts_t *opts, double *far)
{
    fit_design_opts_t o = opts ? *opts : fit_design_opts_for_tol(1e-12);
    if (far) *far = 0;
    if (check_args(R_um, pitch, r, x, y, n, &o, NULL)) return 0;
    double a = fit_airy_a(R_um), segs = 0, far_segs = 0;
    int near_foot = any_outside(pitch, x, y, n);
    for (size_t k = 0; k < n; k++)
        for (int dir = 0; dir < 2; dir++) {
            double across = dir ? y[k] : x[k], along = dir ? x[k] : y[k];
            /* the farthest node along any line: one of the pixel's two edges; when the spot is
             * beyond one edge (every node on one side of its foot), the sweep may start at the
             * nearest node instead of the foot (sweep_offset_pays): the build never takes more
             * than this span or the foot's, whichever is less */
            double other = fmax(fabs(along), fabs(pitch - along)),
                   near = fmin(fabs(along), fabs(pitch - along));
            int one_sided = (along < 0 || along > pitch) && a * near >= FIT_CORNER_TINY;
            for (int l = 0; l <= r; l++) {
                double dist = fabs(pitch * l / r - across), w = a * dist;
                if (w < FIT_CORNER_TINY) continue;
                double E = (other + sqrt(other * other + dist * dist)) / dist;
                if (!(E > 1)) continue;
                double E0 = one_sided ? (near + sqrt(near * near + dist * dist)) / dist : 1;
                double v0 = w * (E0 + 1 / E0) / 2, vend = w * (E + 1 / E) / 2; /* v = w cosh s */
                segs += sweep_segments(&o, near_foot, w, E0, E);
                if (vend > RADIAL_Q_VMAX)
                    far_segs += ceil((vend - fmax(v0, RADIAL_Q_VMAX)) / o.seg_dv);
            }
        }
    if (far) *far = far_segs * o.order;
    return segs * o.order;
}

int fit_design_build(double R_um, double pitch, int r, const double *x, const double *y, size_t n,
                     const fit_design_opts_t *opts, double *A, fit_design_stats_t *stats,
                     err_t *err)
{
    fit_design_opts_t o = opts ? *opts : fit_design_opts_for_tol(1e-12);
    int rc = check_args(R_um, pitch, r, x, y, n, &o, err);
    if (rc) return rc;
    fit_design_stats_t st = {.entries = n * (size_t)r * r};
    size_t n1 = (size_t)r + 1,
           /* the rows of wedges at most (no two pairs share one): 2 n1 rows of n1 Q values and
            * needs, each with its coordinate and P row, and 6 rows of P (the lines next to the
            * spot); then the node marks, cell marks, rows of the lines, the coordinates' tables,
            * the pairs and the (line, coordinate) items with sort_pairs' copy */
           per_spot = 2 * n1 * (n1 * (sizeof(double) + 1) + sizeof(double) + sizeof(uint32_t) + 1) +
                      6 * n1 * sizeof(double) + n1 * n1 + (size_t)r * r + 1 + 4 * sizeof(int) +
                      2 * n1 * sizeof(uint32_t) + 12 * sizeof(uint32_t) +
                      8 * sizeof(struct coord_slot) + n1 * 6 * sizeof(struct line_pair);
    size_t batch = BATCH_BYTES / per_spot > BATCH_MIN ? BATCH_BYTES / per_spot : BATCH_MIN;
    if (batch > n) batch = n;
    struct work wk = {.r = r, .n1 = r + 1, .a = fit_airy_a(R_um)};
    struct cheb *ch = malloc(sizeof *ch);
    double *e = malloc(sizeof(double) * (size_t)(r + 1));
    wk.e = e;
    if (!ch || !e || work_alloc(&wk, batch ? batch : 1)) {
        rc = err_set(err, -ENOMEM, "out of memory for the design matrix (r = %d)", r);
        goto out;
    }
    cheb_init(ch, o.order);
    ch->near_foot = any_outside(pitch, x, y, n);
    cache_claim(o.cache, ch, &o);
    for (int i = 0; i <= r; i++) e[i] = pitch * i / r; /* exact at 0 and at pitch */
    wk.near2 = near_distance2(&o, wk.a, e, r);
    for (size_t k0 = 0; k0 < n; k0 += batch) {
        if (fit_stop_now(&o.stop) && (rc = err_set(err, -ECANCELED, "fit stopped"))) goto out;
        int nb = (int)(n - k0 < batch ? n - k0 : batch);
        wk.x = x + k0;
        wk.y = y + k0;
        for (int k = 0; k < nb; k++) mark_cells(&o, &wk, k, &st);
        rc = wedge_pass(ch, &o, &wk, nb, &st.radial_evals);
        if (rc) {
            rc = err_set(err, rc, "out of memory for the design matrix (r = %d)", r);
            goto out;
        }
        for (int k = 0; k < nb; k++) assemble_row(&wk, k, A + (k0 + (size_t)k) * r * r);
    }
out:
    if (stats) *stats = st;
    free(wk.sw.seg);
    free(ch);
    free(e);
    free(wk.gs);
    free(wk.krow);
    free(wk.need);
    free(wk.pwin);
    free(wk.pairs);
    free(wk.items);
    free(wk.ulist[0]);
    free(wk.tg);
    free(wk.span);
    free(wk.vq);
    free(wk.vp);
    free(wk.rowp);
    free(wk.rfull);
    free(wk.rneed);
    free(wk.ralong);
    free(wk.slots);
    return rc;
}
