/* krige_mix.c: the kriged map's expected error under the neighbouring priors (krige.h,
 * fit_krige_mix). The map kept was made with the prior of the recommended r, one r among
 * neighbours the data hardly tell apart: the recommendation moves between them from one batch of
 * an adaptive scan to the next, and the posterior under one prior does not see the error of
 * having picked it (a 6 x 6 grid's prior holds a soft edge's cells so well that the smooth part
 * is dropped, and S_err falls 5x while the map gets worse; docs/numerics.md "The expected error
 * under the neighbouring priors"). With the maps m_k and errors S_err_k of the priors of r - 1
 * (when >= 1), r and r + 1 made from the same points, the expected squared error of the map
 * kept, m, under an equal mixture of the K priors in Occam's window (those whose restricted
 * likelihood is within e^FIT_KRIGE_MIX_WINDOW of the best's) is its second moment about m:
 *     e^2 = (1/K) sum_k [ <S_err_k^2> + <(m_k - m)^2> ],
 * <.> the mean over the pixel. Each m_k lies on its own fine grid; <(m_k - m)^2> is exact over
 * the common refinement of the two grids (both maps piecewise constant). Equal weights within
 * the window: the likelihoods, which would weigh the priors, favour the one whose error bar
 * collapses (docs/numerics.md "The expected error under the neighbouring priors"); the window
 * leaves out a prior the data reject outright (a dead corner on r = 3's grid, which r = 2's and
 * r = 4's priors cannot hold, where their spread would make e a hundred times the error). */
#include "fit/krige.h"

#include <errno.h>
#include <math.h>
#include <string.h>

/* Cuts of [0, 1] at i / fa and j / fb, in units of 1 / (fa fb), into cut (at most fa + fb + 1
 * values, increasing); returns their count. */
static int refine(int fa, int fb, long *cut)
{
    int n = 0, i = 0, j = 0;
    while (i <= fa || j <= fb) {
        long a = i <= fa ? (long)i * fb : -1, b = j <= fb ? (long)j * fa : -1;
        long c = a < 0 ? b : b < 0 ? a : a < b ? a : b;
        cut[n++] = c;
        if (a == c) i++;
        if (b == c) j++;
    }
    return n;
}

double fit_map_ms_between(const double *a, int fa, const double *b, int fb)
{
    if (fa < 1 || fb < 1 || fa > FIT_KRIGE_MIX_GRID_MAX || fb > FIT_KRIGE_MIX_GRID_MAX) return NAN;
    long cut[2 * FIT_KRIGE_MIX_GRID_MAX + 2], span = (long)fa * fb;
    int n = refine(fa, fb, cut);
    double acc = 0;
    for (int y = 0; y + 1 < n; y++) {
        long my = cut[y] + cut[y + 1]; /* twice the segment's middle */
        int ay = (int)(my * fa / (2 * span)), by = (int)(my * fb / (2 * span));
        double wy = (double)(cut[y + 1] - cut[y]) / (double)span;
        for (int x = 0; x + 1 < n; x++) {
            long mx = cut[x] + cut[x + 1];
            int ax = (int)(mx * fa / (2 * span)), bx = (int)(mx * fb / (2 * span));
            double d = a[ay * fa + ax] - b[by * fb + bx];
            acc += wy * (double)(cut[x + 1] - cut[x]) / (double)span * d * d;
        }
    }
    return acc;
}

static double mean_square(const double *v, size_t m)
{
    double s = 0;
    for (size_t i = 0; i < m; i++) s += v[i] * v[i];
    return s / (double)m;
}

int fit_krige_mix(const fit_scan_t *scan, fit_kriged_t *map, const fit_options_t *opts,
                  err_t *err)
{
    map->mix_n = 0;
    map->mix_err = NAN;
    if (!map->S || !map->S_err || map->grid < 1 || map->grid > FIT_KRIGE_MIX_GRID_MAX)
        return err_set(err, -EINVAL, "the mixture needs a kriged map");
    size_t m = (size_t)map->grid * map->grid;
    int rs[3] = {map->r - 1, map->r, map->r + 1};
    for (int i = 0; i < 3; i++) {
        int r = rs[i];
        if (r < 1 || r > 32) continue;
        double ms_err, spread, ll = map->log_lik;
        if (r == map->r) {
            ms_err = mean_square(map->S_err, m), spread = 0;
        } else {
            fit_kriged_t k;
            err_t e = {0};
            int rc = fit_krige(scan, r, opts, &k, &e);
            if (rc == -ENOMEM || rc == -ECANCELED) return err_set(err, rc, "%s", e.msg);
            if (rc) continue; /* a neighbour whose map cannot be had is left out */
            ms_err = mean_square(k.S_err, (size_t)k.grid * k.grid);
            spread = fit_map_ms_between(k.S, k.grid, map->S, map->grid);
            ll = k.log_lik;
            fit_kriged_free(&k);
            if (!isfinite(spread)) continue;
        }
        map->mix_r[map->mix_n] = r;
        map->mix_map_err[map->mix_n] = sqrt(ms_err);
        map->mix_spread[map->mix_n] = sqrt(spread);
        map->mix_log_lik[map->mix_n] = ll;
        map->mix_n++;
    }
    /* Occam's window: a prior the data reject decisively against the best says nothing of the
     * map's error */
    double best = -INFINITY, sum = 0;
    int in = 0;
    for (int i = 0; i < map->mix_n; i++) best = fmax(best, map->mix_log_lik[i]);
    for (int i = 0; i < map->mix_n; i++) in += !(map->mix_log_lik[i] < best - FIT_KRIGE_MIX_WINDOW);
    for (int i = 0; i < map->mix_n; i++) {
        int keep = !(map->mix_log_lik[i] < best - FIT_KRIGE_MIX_WINDOW);
        map->mix_weight[i] = keep ? 1.0 / in : 0;
        sum += map->mix_weight[i] * (map->mix_map_err[i] * map->mix_map_err[i] +
                                     map->mix_spread[i] * map->mix_spread[i]);
    }
    map->mix_err = sqrt(sum);
    return 0;
}
