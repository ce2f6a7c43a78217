/* adapt.c: the greedy batch of adapt.h. G = A Sigma holds Sigma a_i for every candidate i (Sigma
 * is symmetric); after the pick j with g = G_j and den = a_j^T g + s_j^2, every row becomes
 * G_i - (a_i^T g / den) g, its a_i^T Sigma a_i drops by (a_i^T g)^2 / den, and the trace of Sigma
 * by |g|^2 / den. Each pick costs one pass over G. */
#include "fit/adapt.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gemm.h"

static double dot(const double *x, const double *y, size_t m)
{
    double s = 0;
    for (size_t i = 0; i < m; i++) s += x[i] * y[i];
    return s;
}

int fit_adapt_pick(size_t m, const double *Sigma, size_t nc, const double *A, const double *s2,
                   int batch, int *picked, double *mean_var, err_t *err)
{
    if (m == 0 || !Sigma || !A || !s2 || !picked || batch < 0)
        return err_set(err, -EINVAL, "adaptive pick: need cells, Sigma, candidates and batch >= 0");
    if (nc > INT_MAX || (nc > 0 && m > SIZE_MAX / sizeof(double) / nc))
        return err_set(err, -ENOMEM, "adaptive pick: %zu candidates x %zu cells", nc, m);
    double trace = 0;
    for (size_t c = 0; c < m; c++) trace += Sigma[c * m + c];
    for (size_t j = 0; j < nc; j++)
        if (!(s2[j] >= 0) || !isfinite(s2[j]))
            return err_set(err, -EINVAL, "adaptive pick: candidate %zu's noise variance %g", j,
                           s2[j]);
    if (!isfinite(trace) || trace < 0)
        return err_set(err, -EINVAL, "adaptive pick: Sigma's trace is %g", trace);
    if (mean_var) mean_var[0] = trace / (double)m;
    if (nc == 0 || batch == 0) return 0;
    double *G = malloc(sizeof(double) * nc * m), *q = malloc(sizeof(double) * nc),
           *g = malloc(sizeof(double) * m);
    char *used = calloc(nc, 1);
    if (!G || !q || !g || !used) {
        free(G), free(q), free(g), free(used);
        return err_set(err, -ENOMEM, "adaptive pick: out of memory for %zu candidates", nc);
    }
    fit_gemm(A, 0, Sigma, 0, nc, m, m, 1.0, 0.0, G);
    for (size_t i = 0; i < nc; i++) q[i] = dot(A + i * m, G + i * m, m);
    int n = 0;
    for (; n < batch; n++) {
        size_t best = nc;
        double best_gain = 0;
        for (size_t i = 0; i < nc; i++) {
            double den = q[i] + s2[i];
            if (used[i] || !(den > 0)) continue;
            double gain = dot(G + i * m, G + i * m, m) / den;
            if (gain > best_gain) best_gain = gain, best = i;
        }
        if (best == nc || !(best_gain > 1e-15 * trace)) break; /* nothing left to learn */
        double den = q[best] + s2[best];
        memcpy(g, G + best * m, sizeof(double) * m);
        for (size_t i = 0; i < nc; i++) {
            double c = dot(A + i * m, g, m), f = c / den;
            double *Gi = G + i * m;
            for (size_t k = 0; k < m; k++) Gi[k] -= f * g[k];
            q[i] -= c * f;
        }
        trace -= dot(g, g, m) / den;
        used[best] = 1;
        picked[n] = (int)best;
        if (mean_var) mean_var[n + 1] = fmax(trace, 0) / (double)m;
    }
    free(G), free(q), free(g), free(used);
    return n;
}
