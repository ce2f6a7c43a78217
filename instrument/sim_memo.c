/* sim_memo.c: the memo of the simulator's pixel integrals (sim.h: a pixel's signal depends only
 * on the spot's position relative to the pixel and on its radius), and the integration of what
 * the memo does not hold yet, at the resolution the leave-out rule chose (sim_leaveout.c), by
 * design rows of fit/design.h dotted with the map. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/airy.h"
#include "sim_int.h"

#define QUANTUM_UM 1e-9        /* relative positions are rounded to this before integration */
#define MEMO_MAX (1u << 20)    /* entries before the memo is emptied (~40 MB) */
/* sim.h's SIM_CAPTURE_PX_MAX is the largest ask memo_reserve takes at MEMO_MAX */
_Static_assert(SIM_CAPTURE_PX_MAX * 10ull < MEMO_MAX * 7ull &&
                   (SIM_CAPTURE_PX_MAX + 1) * 10ull >= MEMO_MAX * 7ull,
               "SIM_CAPTURE_PX_MAX matches the memo's limit");
#define BATCH 256              /* design rows per fit_design_build call at most */
#define ROWS_BUDGET (1u << 21) /* doubles of design rows held at once (16 MB) */

int sim_memo_init(sim_t *s)
{
    s->memo.cap = 1024;
    s->memo.e = malloc(sizeof *s->memo.e * s->memo.cap);
    s->memo.used = calloc(s->memo.cap, 1);
    return s->memo.e && s->memo.used ? 0 : -ENOMEM;
}

void sim_memo_free(sim_t *s)
{
    free(s->memo.e);
    free(s->memo.used);
    free(s->asks);
    free(s->abuf);
    free(s->ubuf);
    free(s->vbuf);
    free(s->pslot);
    free(s->lvl_idx);
}

static uint64_t mix(uint64_t x)
{ /* splitmix64's finaliser */
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

static size_t slot_of(const struct sim_memo *mo, int64_t ku, int64_t kv, uint64_t kr)
{
    size_t h = (size_t)mix((uint64_t)ku * 0x9e3779b97f4a7c15ULL ^ mix((uint64_t)kv) ^ (kr >> 7));
    size_t i = h & (mo->cap - 1);
    while (mo->used[i] && !(mo->e[i].ku == ku && mo->e[i].kv == kv && mo->e[i].kr == kr))
        i = (i + 1) & (mo->cap - 1);
    return i;
}

/* Makes room for `more` entries: doubles the table, or empties it at MEMO_MAX. */
static int memo_reserve(struct sim_memo *mo, size_t more)
{
    if ((mo->n + more) * 10 < mo->cap * 7) return 0;
    size_t cap = mo->cap;
    while ((mo->n + more) * 10 >= cap * 7 && cap < MEMO_MAX)
        cap *= 2;
    if ((mo->n + more) * 10 >= cap * 7) { /* full: forget everything */
        memset(mo->used, 0, mo->cap);
        mo->n = 0;
        return more * 10 < mo->cap * 7 ? 0 : -ENOMEM;
    }
    struct sim_memo_entry *e = malloc(sizeof *e * cap);
    unsigned char *used = calloc(cap, 1);
    if (!e || !used) {
        free(e);
        free(used);
        return -ENOMEM;
    }
    struct sim_memo old = *mo;
    mo->e = e;
    mo->used = used;
    mo->cap = cap;
    for (size_t i = 0; i < old.cap; i++)
        if (old.used[i]) {
            size_t j = slot_of(mo, old.e[i].ku, old.e[i].kv, old.e[i].kr);
            mo->used[j] = 1;
            mo->e[j] = old.e[i];
        }
    free(old.e);
    free(old.used);
    return 0;
}

/* Room for n asks (and n pixel slots). */
static int grow(sim_t *s, size_t n)
{
    if (n <= s->ask_cap) return 0;
    size_t cap = n > 2 * s->ask_cap ? n : 2 * s->ask_cap;
    struct sim_ask *a = realloc(s->asks, sizeof *a * cap);
    if (a) s->asks = a;
    size_t *ps = realloc(s->pslot, sizeof(size_t) * cap);
    if (ps) s->pslot = ps;
    size_t *li = realloc(s->lvl_idx, sizeof(size_t) * cap);
    if (li) s->lvl_idx = li;
    if (!a || !ps || !li) return -ENOMEM;
    s->ask_cap = cap;
    return 0;
}

/* Integrates the asks of level l (the k x k design row dotted with the block-mean map P_k S)
 * into their memo slots. */
static int integrate_level(sim_t *s, double R, int l, err_t *err)
{
    const struct sim_level *L = &s->lv[l];
    size_t kk = (size_t)L->k * L->k, n = 0;
    for (size_t q = 0; q < s->n_asks; q++)
        if (s->asks[q].level == l) s->lvl_idx[n++] = q;
    if (n == 0) return 0;
    size_t mm = (size_t)s->m * s->m, batch = ROWS_BUDGET / mm;
    batch = batch < 1 ? 1 : batch > BATCH ? BATCH : batch;
    if (!s->abuf) s->abuf = malloc(sizeof(double) * batch * mm);
    if (!s->ubuf) s->ubuf = malloc(sizeof(double) * batch);
    if (!s->vbuf) s->vbuf = malloc(sizeof(double) * batch);
    if (!s->abuf || !s->ubuf || !s->vbuf)
        return err_set(err, -ENOMEM, "out of memory for the design rows");
    for (size_t k0 = 0; k0 < n; k0 += batch) {
        size_t nb = n - k0 < batch ? n - k0 : batch;
        for (size_t b = 0; b < nb; b++) {
            s->ubuf[b] = s->asks[s->lvl_idx[k0 + b]].u;
            s->vbuf[b] = s->asks[s->lvl_idx[k0 + b]].v;
        }
        int rc = fit_design_build(R, s->cfg.sensor.pitch_um, L->k, s->ubuf, s->vbuf, nb, &s->opts,
                                  s->abuf, NULL, err);
        if (rc) return rc;
        for (size_t b = 0; b < nb; b++) {
            const double *row = s->abuf + b * kk;
            double acc = 0;
            for (size_t c = 0; c < kk; c++)
                acc += row[c] * L->map[c];
            s->memo.e[s->asks[s->lvl_idx[k0 + b]].slot].value = acc;
        }
    }
    if (L->k == s->m)
        s->stats.full += n;
    else if (L->k == 1)
        s->stats.uniform += n;
    else
        s->stats.coarse += n;
    return 0;
}

int sim_memo_integrate(sim_t *s, double xs, double ys, double R, const cam_roi_t *roi,
                       double *integ, double *bnd, err_t *err)
{
    double p = s->cfg.sensor.pitch_um, a = fit_airy_a(R), total = fit_airy_total(a);
    double tol = s->cfg.leave_out_tol * total;
    size_t npx = (size_t)roi->width * roi->height, nmiss = 0;
    uint64_t kr;
    memcpy(&kr, &R, sizeof kr);
    /* room for every pixel up front: no rehash while slots are held */
    if (grow(s, npx) || memo_reserve(&s->memo, npx))
        return err_set(err, -ENOMEM, "out of memory for the pixel memo");
    for (size_t idx = 0; idx < npx; idx++) {
        int col = roi->col + (int)(idx % (size_t)roi->width);
        int row = roi->row + (int)(idx / (size_t)roi->width);
        int64_t ku = llround((xs - col * p) / QUANTUM_UM);
        int64_t kv = llround((ys - row * p) / QUANTUM_UM);
        size_t slot = slot_of(&s->memo, ku, kv, kr);
        s->pslot[idx] = slot;
        s->stats.lookups++;
        if (s->memo.used[slot]) { /* known, or asked earlier in this roi */
            s->stats.hits++;
            continue;
        }
        double u = ku * QUANTUM_UM, v = kv * QUANTUM_UM, bound;
        struct sim_ask *q = &s->asks[nmiss++];
        *q = (struct sim_ask){.u = u, .v = v, .slot = slot};
        q->level = sim_leaveout_choose(s, a, total, tol, u, v, &bound);
        s->stats.left_out += q->level == SIM_LEFT_OUT;
        s->memo.used[slot] = 1;
        s->memo.n++;
        s->memo.e[slot] = (struct sim_memo_entry){ku, kv, kr, 0.0, bound};
    }
    s->n_asks = nmiss;
    int rc = 0;
    for (int l = 0; l < s->nlv && rc == 0; l++)
        rc = integrate_level(s, R, l, err);
    if (rc) { /* drop the half-filled entries */
        memset(s->memo.used, 0, s->memo.cap);
        s->memo.n = 0;
        return rc;
    }
    for (size_t idx = 0; idx < npx; idx++) {
        integ[idx] = s->memo.e[s->pslot[idx]].value;
        bnd[idx] = s->memo.e[s->pslot[idx]].bound;
    }
    return 0;
}
