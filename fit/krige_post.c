/* krige_post.c: the kriged map's posterior (krige_int.h) at the chosen hyperparameters: the mean
 * T of the fine cells' sensitivity times I0 and its covariance C (universal kriging: mu's own
 * uncertainty included), normalised to S = T / mean T through J = (I - S 1^T / m) / mean T, of
 * whose covariance J C J^T only the diagonal is needed (C's diagonal, row sums and total).
 *   points' space: T = mu 1 + I0^2 Z^T P d, C = I0^2 K - I0^4 Z^T V^-1 Z + c c^T / a,
 *                  Z = A K / I0^2 (n x m), c = 1 - I0^2 Z^T V^-1 1_A, a = 1_A^T V^-1 1_A;
 *   cells' space:  T = L c^, C = L C^-1 L^T, L = [1, I0 I, I0 B_j] (the fine cells' value from
 *                  the mean, the smooth part and each grid's cells), c^ = C^-1 h.
 * kr_posterior_cov forms the whole of C (m x m, for an adaptive scan's planner, adapt.h) by the
 * same formulas with dense products, and the whole of J C J^T. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gemm.h"
#include "krige_int.h"

/* S and S_err from T, C's diagonal Cd, row sums Cr (m each). */
static int normalise(size_t m, const double *T, const double *Cd, const double *Cr, double *S,
                     double *S_err)
{
    double mean = 0, tot = 0;
    for (size_t i = 0; i < m; i++) mean += T[i] / (double)m, tot += Cr[i];
    if (!(mean > 0)) return -EDOM;
    for (size_t i = 0; i < m; i++) {
        double s = T[i] / mean;
        double v = Cd[i] - 2 * s * Cr[i] / (double)m + s * s * tot / ((double)m * m);
        S[i] = s;
        S_err[i] = sqrt(fmax(v, 0)) / mean;
    }
    return 0;
}

/* Z = Cov(T, d) / I0^2 without the points' noise, n x m: the smooth part a^2 K a_p (through
 * the kernel's factor) and each grid's t_j A_j B_j^T, in that order. */
static void points_Z(kr_prob_t *k, const double *th, const double *const *Bq, double *Z)
{
    size_t n = k->n, m = k->m;
    double a2 = k->smooth ? exp(th[k->nl]) : 0;
    for (size_t p = 0; p < n; p++) {
        if (k->smooth) {
            kr_kernel_cov(&k->ker, k->A + p * m, Z + p * m, 0);
            for (size_t i = 0; i < m; i++) Z[p * m + i] *= a2;
        } else {
            memset(Z + p * m, 0, sizeof(double) * m);
        }
    }
    for (int j = 0; j < k->nl; j++) {
        size_t qq = (size_t)k->q[j] * k->q[j];
        fit_gemm(k->Aq[j], 0, Bq[j], 1, n, qq, m, exp(th[j]), 1, Z);
    }
}

static int post_points(kr_prob_t *k, const double *th, const double *const *Bq, double *T,
                       double *Cd, double *Cr)
{
    size_t n = k->n, m = k->m, F = (size_t)k->F;
    int nl = k->nl;
    double I2 = k->I0 * k->I0;
    double *Z = malloc(sizeof(double) * n * m), *Q = malloc(sizeof(double) * n * m);
    double *c = malloc(sizeof(double) * m), *Zone = malloc(sizeof(double) * n);
    double *Qone = malloc(sizeof(double) * n);
    int rc = 0;
    if (!Z || !Q || !c || !Zone || !Qone) {
        rc = -ENOMEM;
        goto out;
    }
    double a2 = k->smooth ? exp(th[nl]) : 0, r1[KR_KERNEL_MAX_F] = {0};
    points_Z(k, th, Bq, Z);
    for (size_t i = 0; i < F && k->smooth; i++)
        for (size_t j = 0; j < F; j++) r1[i] += k->ker.K1[i * F + j];
    for (size_t y = 0; y < F; y++)
        for (size_t x = 0; x < F; x++) Cd[y * F + x] = a2, Cr[y * F + x] = a2 * r1[y] * r1[x];
    for (int j = 0; j < nl; j++) { /* K's diagonal and row sums */
        size_t qq = (size_t)k->q[j] * k->q[j];
        double t = exp(th[j]), area = (double)(F * F) / (double)qq;
        for (size_t i = 0; i < m; i++) {
            double b2 = 0;
            for (size_t e = 0; e < qq; e++) b2 += Bq[j][i * qq + e] * Bq[j][i * qq + e];
            Cd[i] += t * b2;
            Cr[i] += t * area;
        }
    }
    fit_gemm(Z, 1, k->Py, 0, m, n, 1, I2, 0, T);
    for (size_t i = 0; i < m; i++) T[i] += k->mu;
    fit_gemm(k->Vi, 0, Z, 0, n, n, m, 1, 0, Q);
    fit_gemm(Z, 1, k->Vone, 0, m, n, 1, -I2, 0, c);
    double csum = 0;
    for (size_t i = 0; i < m; i++) c[i] += 1, csum += c[i];
    for (size_t p = 0; p < n; p++) {
        Zone[p] = 0;
        for (size_t i = 0; i < m; i++) Zone[p] += Z[p * m + i];
    }
    fit_gemm(k->Vi, 0, Zone, 0, n, n, 1, 1, 0, Qone);
    for (size_t i = 0; i < m; i++) {
        double zq = 0, zr = 0;
        for (size_t p = 0; p < n; p++) zq += Z[p * m + i] * Q[p * m + i], zr += Z[p * m + i] * Qone[p];
        Cd[i] = I2 * Cd[i] - I2 * I2 * zq + c[i] * c[i] / k->a;
        Cr[i] = I2 * Cr[i] - I2 * I2 * zr + c[i] * csum / k->a;
    }
out:
    free(Z), free(Q), free(c), free(Zone), free(Qone);
    return rc;
}

static int post_cells(kr_prob_t *k, const double *const *Bq, double *T, double *Cd, double *Cr)
{
    size_t p = k->p, m = k->m;
    int nl = k->nl;
    double I0 = k->I0;
    double *G = malloc(sizeof(double) * p), *Lt1 = calloc(p, sizeof(double));
    if (!G || !Lt1) {
        free(G), free(Lt1);
        return -ENOMEM;
    }
    Lt1[0] = (double)m;
    for (size_t c = 0; c < m && k->smooth; c++) Lt1[k->off_s + c] = I0;
    for (int j = 0; j < nl; j++) {
        size_t qq = (size_t)k->q[j] * k->q[j];
        for (size_t c = 0; c < m; c++)
            for (size_t e = 0; e < qq; e++) Lt1[k->off_q[j] + e] += I0 * Bq[j][c * qq + e];
    }
    for (size_t c = 0; c < m; c++) {
        /* G = L_c C^-1 (row c of L C^-1) and T_c = L_c c^ */
        memcpy(G, k->Ci, sizeof(double) * p);
        double t = k->chat[0];
        if (k->smooth) {
            const double *row = k->Ci + (k->off_s + c) * p;
            for (size_t i = 0; i < p; i++) G[i] += I0 * row[i];
            t += I0 * k->chat[k->off_s + c];
        }
        for (int j = 0; j < nl; j++) {
            size_t qq = (size_t)k->q[j] * k->q[j];
            for (size_t e = 0; e < qq; e++) {
                double b = Bq[j][c * qq + e];
                if (b == 0) continue;
                const double *row = k->Ci + (k->off_q[j] + e) * p;
                for (size_t i = 0; i < p; i++) G[i] += I0 * b * row[i];
                t += I0 * b * k->chat[k->off_q[j] + e];
            }
        }
        double d = G[0], r = 0;
        if (k->smooth) d += I0 * G[k->off_s + c];
        for (int j = 0; j < nl; j++) {
            size_t qq = (size_t)k->q[j] * k->q[j];
            for (size_t e = 0; e < qq; e++) d += I0 * Bq[j][c * qq + e] * G[k->off_q[j] + e];
        }
        for (size_t i = 0; i < p; i++) r += G[i] * Lt1[i];
        T[c] = t, Cd[c] = d, Cr[c] = r;
    }
    free(G), free(Lt1);
    return 0;
}

int kr_posterior(kr_prob_t *k, const double *th, const double *const *Bq, double *S,
                 double *S_err)
{
    size_t m = k->m;
    double *T = malloc(sizeof(double) * m), *Cd = malloc(sizeof(double) * m);
    double *Cr = malloc(sizeof(double) * m);
    int rc = -ENOMEM;
    if (T && Cd && Cr) {
        rc = k->cells ? post_cells(k, Bq, T, Cd, Cr) : post_points(k, th, Bq, T, Cd, Cr);
        if (!rc) rc = normalise(m, T, Cd, Cr, S, S_err);
    }
    free(T), free(Cd), free(Cr);
    return rc;
}

/* The whole covariance C (m x m) and the mean T in the points' space:
 * C = I0^2 K - I0^4 Z^T V^-1 Z + c c^T / a, K = a^2 K1 (x) K1 + sum_j t_j B_j B_j^T. */
static int cov_points(kr_prob_t *k, const double *th, const double *const *Bq, double *T,
                      double *C)
{
    size_t n = k->n, m = k->m, F = (size_t)k->F;
    int nl = k->nl;
    double I2 = k->I0 * k->I0;
    double *Z = malloc(sizeof(double) * n * m), *Q = malloc(sizeof(double) * n * m);
    double *c = malloc(sizeof(double) * m);
    int rc = 0;
    if (!Z || !Q || !c) {
        rc = -ENOMEM;
        goto out;
    }
    double a2 = k->smooth ? exp(th[nl]) : 0;
    points_Z(k, th, Bq, Z);
    for (size_t y = 0; y < F; y++) /* C = I0^2 K, its smooth part first */
        for (size_t x = 0; x < F; x++)
            for (size_t y2 = 0; y2 < F; y2++)
                for (size_t x2 = 0; x2 < F; x2++)
                    C[(y * F + x) * m + y2 * F + x2] =
                        k->smooth ? I2 * a2 * k->ker.K1[y * F + y2] * k->ker.K1[x * F + x2] : 0;
    for (int j = 0; j < nl; j++) {
        size_t qq = (size_t)k->q[j] * k->q[j];
        fit_gemm(Bq[j], 0, Bq[j], 1, m, qq, m, I2 * exp(th[j]), 1, C);
    }
    fit_gemm(Z, 1, k->Py, 0, m, n, 1, I2, 0, T);
    for (size_t i = 0; i < m; i++) T[i] += k->mu;
    fit_gemm(k->Vi, 0, Z, 0, n, n, m, 1, 0, Q);
    fit_gemm(Z, 1, Q, 0, m, n, m, -I2 * I2, 1, C);
    fit_gemm(Z, 1, k->Vone, 0, m, n, 1, -I2, 0, c);
    for (size_t i = 0; i < m; i++) c[i] += 1;
    for (size_t i = 0; i < m; i++)
        for (size_t j = 0; j < m; j++) C[i * m + j] += c[i] * c[j] / k->a;
out:
    free(Z), free(Q), free(c);
    return rc;
}

/* The same in the cells' space: C = L C^-1 L^T, T = L c^. */
static int cov_cells(kr_prob_t *k, const double *const *Bq, double *T, double *C)
{
    size_t p = k->p, m = k->m;
    double I0 = k->I0;
    double *L = calloc(m * p, sizeof(double)), *LC = malloc(sizeof(double) * m * p);
    if (!L || !LC) {
        free(L), free(LC);
        return -ENOMEM;
    }
    for (size_t c = 0; c < m; c++) {
        double *row = L + c * p;
        row[0] = 1;
        if (k->smooth) row[k->off_s + c] = I0;
        for (int j = 0; j < k->nl; j++) {
            size_t qq = (size_t)k->q[j] * k->q[j];
            for (size_t e = 0; e < qq; e++) row[k->off_q[j] + e] += I0 * Bq[j][c * qq + e];
        }
    }
    fit_gemm(L, 0, k->chat, 0, m, p, 1, 1, 0, T);
    fit_gemm(L, 0, k->Ci, 0, m, p, p, 1, 0, LC);
    fit_gemm(LC, 0, L, 1, m, p, m, 1, 0, C);
    free(L), free(LC);
    return 0;
}

int kr_posterior_cov(kr_prob_t *k, const double *th, const double *const *Bq, double *S,
                     double *S_cov)
{
    size_t m = k->m;
    double *T = malloc(sizeof(double) * m), *r = malloc(sizeof(double) * m);
    int rc = -ENOMEM;
    if (T && r) {
        rc = k->cells ? cov_cells(k, Bq, T, S_cov) : cov_points(k, th, Bq, T, S_cov);
        /* C's two triangles differ by the rounding of its products' cancellation (the prior's
         * variance less what the points explain): the mean of the two is kept */
        for (size_t i = 0; !rc && i < m; i++)
            for (size_t j = 0; j < i; j++) {
                double v = 0.5 * (S_cov[i * m + j] + S_cov[j * m + i]);
                S_cov[i * m + j] = S_cov[j * m + i] = v;
            }
        double mean = 0, tot = 0;
        for (size_t i = 0; !rc && i < m; i++) {
            mean += T[i] / (double)m;
            r[i] = 0;
            for (size_t j = 0; j < m; j++) r[i] += S_cov[i * m + j];
            tot += r[i];
        }
        if (!rc && !(mean > 0)) rc = -EDOM;
        for (size_t i = 0; !rc && i < m; i++) S[i] = T[i] / mean;
        /* J C J^T, J = (I - S 1^T / m) / mean */
        for (size_t i = 0; !rc && i < m; i++)
            for (size_t j = 0; j < m; j++)
                S_cov[i * m + j] = (S_cov[i * m + j] - S[i] * r[j] / (double)m -
                                    S[j] * r[i] / (double)m + S[i] * S[j] * tot / ((double)m * m)) /
                                   (mean * mean);
    }
    free(T), free(r);
    return rc;
}
