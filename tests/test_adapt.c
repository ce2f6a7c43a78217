/* test_adapt.c: the adaptive scan's greedy batch (fit/adapt.h) against independent results.
 *   - Independent cells (Sigma diagonal) seen one by one: the gain of cell c is v_c^2 / (v_c + s^2),
 *     rising with v_c, so the picks are the cells in order of falling variance, and each picked
 *     cell's variance becomes v s^2 / (v + s^2) (the scalar Kalman update): the mean variances
 *     after each pick follow in closed form.
 *   - Correlated cells: the expected mean variance after the batch equals the trace of the
 *     posterior in information form, (Sigma^-1 + sum_k a_k a_k^T / s_k^2)^-1 (LAPACK), one batch
 *     at once where the code updates pick by pick; and every pick is the best single candidate
 *     of the posterior before it (each candidate's gain from that dense posterior).
 *   - A measurement twice: after an exact (s^2 = 0) measurement, a second candidate with the same
 *     design row has nothing to add and is not picked.
 *   - Bad input: a negative noise variance, a non-finite one: -EINVAL with a message. */
#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/adapt.h"

static double urand(unsigned long long *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

static void diagonal_cells(void)
{
    enum { M = 6 };
    const double v[M] = {0.5, 2.0, 0.1, 3.0, 1.0, 0.7}, s2 = 0.25;
    double Sigma[M * M] = {0}, A[M * M] = {0}, noise[M], mv[4];
    for (int c = 0; c < M; c++) Sigma[c * M + c] = v[c], A[c * M + c] = 1, noise[c] = s2;
    int picked[3];
    err_t err = {{0}};
    CHECK(fit_adapt_pick(M, Sigma, M, A, noise, 3, picked, mv, &err) == 3);
    CHECK(picked[0] == 3 && picked[1] == 1 && picked[2] == 4); /* variances 3, 2, 1 */
    double tr = 0;
    for (int c = 0; c < M; c++) tr += v[c];
    CHECK(fabs(mv[0] - tr / M) < 1e-15);
    const int order[3] = {3, 1, 4};
    for (int k = 0; k < 3; k++) {
        double vc = v[order[k]];
        tr += vc * s2 / (vc + s2) - vc;
        CHECK(fabs(mv[k + 1] - tr / M) < 1e-14);
    }
}

/* The trace of (Sigma^-1 + sum over picked of a a^T / s2)^-1, by Cholesky inverses. */
static double information_form_trace(int m, const double *Sigma, const double *A,
                                     const double *s2, const int *picked, int n)
{
    double *P = malloc(sizeof(double) * m * m);
    memcpy(P, Sigma, sizeof(double) * m * m);
    if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', m, P, m) ||
        LAPACKE_dpotri(LAPACK_ROW_MAJOR, 'L', m, P, m)) {
        free(P);
        return NAN;
    }
    for (int i = 0; i < m; i++)
        for (int j = 0; j < i; j++) P[j * m + i] = P[i * m + j];
    for (int k = 0; k < n; k++) {
        const double *a = A + (size_t)picked[k] * m;
        for (int i = 0; i < m; i++)
            for (int j = 0; j < m; j++) P[i * m + j] += a[i] * a[j] / s2[picked[k]];
    }
    double tr = NAN;
    if (!LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', m, P, m) &&
        !LAPACKE_dpotri(LAPACK_ROW_MAJOR, 'L', m, P, m)) {
        tr = 0;
        for (int i = 0; i < m; i++) tr += P[i * m + i];
    }
    free(P);
    return tr;
}

static void correlated_cells(void)
{
    enum { M = 12, NC = 30, BATCH = 5 };
    unsigned long long seed = 7;
    double L[M * M], Sigma[M * M], A[NC * M], s2[NC], mv[BATCH + 1];
    for (int i = 0; i < M * M; i++) L[i] = urand(&seed) - 0.5;
    for (int i = 0; i < M; i++) /* Sigma = L L^T + 0.1 I: symmetric positive definite */
        for (int j = 0; j < M; j++) {
            double s = i == j ? 0.1 : 0;
            for (int k = 0; k < M; k++) s += L[i * M + k] * L[j * M + k];
            Sigma[i * M + j] = s;
        }
    for (int i = 0; i < NC * M; i++) A[i] = urand(&seed);
    for (int j = 0; j < NC; j++) s2[j] = 0.05 + urand(&seed);
    int picked[BATCH];
    err_t err = {{0}};
    CHECK(fit_adapt_pick(M, Sigma, NC, A, s2, BATCH, picked, mv, &err) == BATCH);
    for (int k = 1; k <= BATCH; k++) {
        double tr = information_form_trace(M, Sigma, A, s2, picked, k);
        CHECK(fabs(mv[k] * M - tr) < 1e-10 * tr);
        CHECK(mv[k] < mv[k - 1]);
    }
    /* each pick the best single candidate of the dense posterior before it */
    double *S = malloc(sizeof(double) * M * M), g[M];
    memcpy(S, Sigma, sizeof(double) * M * M);
    for (int k = 0; k < BATCH; k++) {
        int best = -1;
        double best_gain = -1;
        for (int j = 0; j < NC; j++) {
            int used = 0;
            for (int u = 0; u < k; u++) used |= picked[u] == j;
            if (used) continue;
            double q = 0, nn = 0;
            for (int i = 0; i < M; i++) {
                g[i] = 0;
                for (int c = 0; c < M; c++) g[i] += S[i * M + c] * A[j * M + c];
                q += A[j * M + i] * g[i];
                nn += g[i] * g[i];
            }
            if (nn / (q + s2[j]) > best_gain) best_gain = nn / (q + s2[j]), best = j;
        }
        CHECK(best == picked[k]);
        double q = 0;
        for (int i = 0; i < M; i++) {
            g[i] = 0;
            for (int c = 0; c < M; c++) g[i] += S[i * M + c] * A[picked[k] * M + c];
            q += A[picked[k] * M + i] * g[i];
        }
        for (int i = 0; i < M; i++)
            for (int j = 0; j < M; j++) S[i * M + j] -= g[i] * g[j] / (q + s2[picked[k]]);
    }
    free(S);
}

static void measured_twice(void)
{
    enum { M = 4, NC = 3 };
    const double Sigma[M * M] = {1, 0.5, 0, 0, 0.5, 1, 0, 0, 0, 0, 0.2, 0, 0, 0, 0, 0.1};
    /* candidates 0 and 1 the same row, exact; candidate 2 another cell */
    const double A[NC * M] = {1, 1, 0, 0, 1, 1, 0, 0, 0, 0, 1, 0}, s2[NC] = {0, 0, 0.01};
    int picked[3];
    err_t err = {{0}};
    int n = fit_adapt_pick(M, Sigma, NC, A, s2, 3, picked, NULL, &err);
    CHECK(n == 2 && picked[0] == 0 && picked[1] == 2);
}

static void bad_input(void)
{
    const double Sigma[1] = {1}, A[2] = {1, 1}, neg[2] = {0.1, -1}, inf[2] = {INFINITY, 0.1};
    int picked[2];
    err_t err = {{0}};
    CHECK(fit_adapt_pick(1, Sigma, 2, A, neg, 1, picked, NULL, &err) == -EINVAL);
    CHECK(strstr(err.msg, "candidate 1") != NULL);
    CHECK(fit_adapt_pick(1, Sigma, 2, A, inf, 1, picked, NULL, &err) == -EINVAL);
    CHECK(strstr(err.msg, "candidate 0") != NULL);
}

int main(void)
{
    diagonal_cells();
    correlated_cells();
    measured_twice();
    bad_input();
    CHECK_DONE();
}
