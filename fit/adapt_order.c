/* adapt_order.c: the travel order of an adaptive scan's batch (adapt_plan.h, fit_adapt_order): an
 * open path from the stage's position through every position of the batch, its length
 *     L = sum_k |v_k - v_(k-1)|,  v_0 the start,
 * made short by the nearest neighbour, then local moves while one shortens it: or-opt (one
 * position moved elsewhere in the path; up to OR_OPT_MAX positions) and 2-opt (reversing the
 * stretch v_i..v_j replaces the edges (v_(i-1), v_i) and (v_j, v_(j+1)) by (v_(i-1), v_j) and
 * (v_i, v_(j+1)); the last position has no edge after it); never longer than the positions' own
 * order. A batch is a few dozen positions, so the passes (n^3 and n^2) cost nothing beside the
 * map's fit. */
#include "fit/adapt_plan.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define OR_OPT_MAX 64 /* or-opt costs n^3 a pass: a batch of more is left to 2-opt */

static double dist(const double *x, const double *y, size_t a, size_t b)
{
    return hypot(x[a] - x[b], y[a] - y[b]);
}

/* The path's length through perm from the start (index n of x, y). */
static double path_length(size_t n, const double *x, const double *y, const size_t *perm)
{
    double L = 0;
    size_t prev = n;
    for (size_t k = 0; k < n; k++) L += dist(x, y, prev, perm[k]), prev = perm[k];
    return L;
}

/* Reverses perm[i..j]. */
static void reverse(size_t *perm, size_t i, size_t j)
{
    for (; i < j; i++, j--) {
        size_t t = perm[i];
        perm[i] = perm[j], perm[j] = t;
    }
}

/* Or-opt: moves one position to the place in the path where it shortens the path most; 1 when
 * one was moved. tmp: n entries. */
static int or_opt(size_t n, const double *x, const double *y, size_t *perm, size_t *tmp)
{
    double L = path_length(n, x, y, perm), best = L;
    size_t bi = 0, bj = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t j = 0; j < n; j++) {
            if (j == i) continue;
            /* perm without entry i, then entry i put back at index j */
            size_t k = 0;
            for (size_t q = 0; q < n; q++)
                if (q != i) tmp[k++] = perm[q];
            memmove(tmp + j + 1, tmp + j, sizeof(size_t) * (n - 1 - j));
            tmp[j] = perm[i];
            double Lm = path_length(n, x, y, tmp);
            if (Lm < best - 1e-12 * (best + 1)) best = Lm, bi = i, bj = j;
        }
    if (!(best < L)) return 0;
    size_t v = perm[bi], k = 0;
    for (size_t q = 0; q < n; q++)
        if (q != bi) tmp[k++] = perm[q];
    memmove(tmp + bj + 1, tmp + bj, sizeof(size_t) * (n - 1 - bj));
    tmp[bj] = v;
    memcpy(perm, tmp, sizeof(size_t) * n);
    return 1;
}

/* 2-opt and or-opt over the open path until no move shortens it by more than rounding. */
static void local_search(size_t n, const double *x, const double *y, size_t *perm, size_t *tmp)
{
    for (int improved = 1, passes = 0; improved && passes < 100; passes++) {
        improved = n <= OR_OPT_MAX && or_opt(n, x, y, perm, tmp);
        for (size_t i = 0; i + 1 < n; i++)
            for (size_t j = i + 1; j < n; j++) {
                size_t a = i ? perm[i - 1] : n, b = perm[i], c = perm[j];
                double before = dist(x, y, a, b), after = dist(x, y, a, c);
                if (j + 1 < n) {
                    size_t d = perm[j + 1];
                    before += dist(x, y, c, d);
                    after += dist(x, y, b, d);
                }
                if (after < before - 1e-12 * (before + 1)) reverse(perm, i, j), improved = 1;
            }
    }
}

double fit_adapt_order(size_t n, const double *x_in, const double *y_in, double x0, double y0,
                       size_t *perm)
{
    if (!isfinite(x0) || !isfinite(y0)) return NAN;
    for (size_t k = 0; k < n; k++)
        if (!isfinite(x_in[k]) || !isfinite(y_in[k])) return NAN;
    /* the positions with the start appended at index n */
    double *x = malloc(sizeof(double) * (n + 1)), *y = malloc(sizeof(double) * (n + 1));
    size_t *nn = malloc(sizeof(size_t) * (n ? n : 1)), *tmp = malloc(sizeof(size_t) * (n ? n : 1));
    char *used = calloc(n ? n : 1, 1);
    if (!x || !y || !nn || !tmp || !used) {
        free(x), free(y), free(nn), free(tmp), free(used);
        for (size_t k = 0; k < n; k++) perm[k] = k; /* out of memory: the positions' own order */
        return NAN;
    }
    memcpy(x, x_in, sizeof(double) * n), memcpy(y, y_in, sizeof(double) * n);
    x[n] = x0, y[n] = y0;
    size_t at = n;
    for (size_t k = 0; k < n; k++) { /* nearest neighbour; ties to the lower index */
        size_t best = n;
        double bd = INFINITY;
        for (size_t i = 0; i < n; i++)
            if (!used[i] && dist(x, y, at, i) < bd) bd = dist(x, y, at, i), best = i;
        used[best] = 1;
        nn[k] = at = best;
    }
    local_search(n, x, y, nn, tmp);
    for (size_t k = 0; k < n; k++) perm[k] = k;
    double L_own = path_length(n, x, y, perm), L = path_length(n, x, y, nn);
    if (L < L_own) memcpy(perm, nn, sizeof(size_t) * n);
    else L = L_own;
    free(x), free(y), free(nn), free(tmp), free(used);
    return L;
}
