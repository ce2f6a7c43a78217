/* krige_lik.c: the kriged map's restricted likelihood (krige_int.h), its gradient and average
 * information, in the points' space (one n x n factorisation) or the fine cells' space (the
 * mixed-model equations, one p x p factorisation however many points). For a variance component
 * c with dV/dth_c = V_c,
 *     d(-log L)/d th_c = (1/2) (tr(P V_c) - (P d)^T V_c (P d)),
 *     AI_cd = (1/2) (V_c P d)^T P (V_d P d)   (the average information, Gilmour et al. 1995),
 *     P = V^-1 - V^-1 1_A (1_A^T V^-1 1_A)^-1 1_A^T V^-1;
 * in the cells' space the same through C^-1 (tr(P V_c) = dim_c - e^-th_c tr(R_c^-1 C^cc), and
 * V_c P d = W y_c with y_c from the BLUP c^ = C^-1 h). Written here: no Gaussian-process
 * regression in GSL or LAPACK; the algebra is LAPACK's Cholesky and the BLAS (gemm.h). */
#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gemm.h"
#include "krige_int.h"

#define LOGVAR_LO -30.0 /* log of a variance over I0^2: the search's bounds */
#define LOGVAR_HI 3.0
#define LEN_LO 0.01     /* correlation length, pitches */
#define LEN_HI 5.0

int kr_theta_count(const kr_prob_t *k)
{
    return k->nl + (k->smooth ? 2 : 0);
}

void kr_theta_bounds(const kr_prob_t *k, int i, double *lo, double *hi)
{
    if (k->smooth && i == k->nl + 1) *lo = log(LEN_LO), *hi = log(LEN_HI);
    else *lo = LOGVAR_LO, *hi = LOGVAR_HI;
}

static void *zalloc(size_t count)
{
    return calloc(count ? count : 1, sizeof(double));
}

/* H = W^T D^-1 W and h = W^T D^-1 d for W = [1_A, I0 A (smooth), I0 A_j]: the scaled columns
 * are gathered n x p, then one symmetric product. */
static int build_cells(kr_prob_t *k)
{
    size_t n = k->n, p = k->p;
    double *X = calloc(n * p, sizeof(double));
    if (!X) return -ENOMEM;
    k->dDd = k->logdetD = 0;
    for (size_t i = 0; i < n; i++) {
        double w = 1 / sqrt(k->s2[i]), *row = X + i * p;
        row[0] = w * k->one[i];
        if (k->smooth)
            for (size_t c = 0; c < k->m; c++) row[k->off_s + c] = w * k->I0 * k->A[i * k->m + c];
        for (int j = 0; j < k->nl; j++) {
            size_t qq = (size_t)k->q[j] * k->q[j];
            for (size_t c = 0; c < qq; c++) row[k->off_q[j] + c] = w * k->I0 * k->Aq[j][i * qq + c];
        }
        k->dDd += k->d[i] * k->d[i] / k->s2[i];
        k->logdetD += log(k->s2[i]);
    }
    fit_gemm(X, 1, X, 0, p, n, p, 1, 0, k->H);
    for (size_t c = 0; c < p; c++) k->h[c] = 0;
    for (size_t i = 0; i < n; i++) {
        double wd = k->d[i] / sqrt(k->s2[i]);
        for (size_t c = 0; c < p; c++) k->h[c] += X[i * p + c] * wd;
    }
    free(X);
    return 0;
}

int kr_prob_init(kr_prob_t *k)
{
    size_t n = k->n, m = k->m;
    k->l_ms = k->l_msd = NAN;
    k->at_valid = 0;
    if (k->cells) {
        size_t p = 1;
        if (k->smooth) k->off_s = p, p += m;
        for (int j = 0; j < k->nl; j++) k->off_q[j] = p, p += (size_t)k->q[j] * k->q[j];
        k->p = p;
        k->H = zalloc(p * p), k->h = zalloc(p), k->C = zalloc(p * p), k->Ci = zalloc(p * p);
        k->chat = zalloc(p), k->t = zalloc(p * KR_MAX_THETA), k->y = zalloc(p * KR_MAX_THETA);
        if (!k->H || !k->h || !k->C || !k->Ci || !k->chat || !k->t || !k->y) return -ENOMEM;
        return build_cells(k);
    }
    if (k->smooth) {
        k->W = zalloc(n * m), k->Wd = zalloc(n * m), k->Ms = zalloc(n * n), k->Msd = zalloc(n * n);
        if (!k->W || !k->Wd || !k->Ms || !k->Msd) return -ENOMEM;
    }
    k->V = zalloc(n * n), k->Vi = zalloc(n * n);
    k->Py = zalloc(n), k->Vone = zalloc(n), k->Vd = zalloc(n);
    /* t: the average information's vectors, and the kernel factor's scratch (3 m) */
    k->t = zalloc(n * KR_MAX_THETA > 3 * m ? n * KR_MAX_THETA : 3 * m), k->y = zalloc(n * KR_MAX_THETA);
    return k->V && k->Vi && k->Py && k->Vone && k->Vd && k->t && k->y ? 0 : -ENOMEM;
}

void kr_prob_free(kr_prob_t *k)
{
    free(k->W), free(k->Wd), free(k->Ms), free(k->Msd), free(k->V), free(k->Vi);
    free(k->Py), free(k->Vone), free(k->Vd), free(k->H), free(k->h), free(k->C), free(k->Ci);
    free(k->chat), free(k->t), free(k->y);
    k->W = k->Wd = k->Ms = k->Msd = k->V = k->Vi = k->Py = k->Vone = k->Vd = NULL;
    k->H = k->h = k->C = k->Ci = k->chat = k->t = k->y = NULL;
}

/* The kernel at l, and in the points' space Ms = I0^2 A K A^T = I0^2 W W^T (and, with deriv,
 * Msd = I0^2 (Wd W^T + W Wd^T)), each made once per l. */
static void smooth_at(kr_prob_t *k, double l, int deriv)
{
    if (k->ker.l != l || k->ker.F != k->F) kr_kernel_set(&k->ker, k->F, l);
    if (k->cells) return;
    size_t n = k->n, m = k->m;
    double *scr = k->t; /* free while the products are made */
    if (deriv && l != k->l_msd) {
        for (size_t p = 0; p < n; p++)
            kr_kernel_factor(&k->ker, k->A + p * m, k->W + p * m, k->Wd + p * m, scr);
        fit_gemm(k->Wd, 0, k->W, 1, n, m, n, k->I0 * k->I0, 0, k->Msd);
        for (size_t i = 0; i < n; i++)
            for (size_t j = 0; j <= i; j++) {
                double s = k->Msd[i * n + j] + k->Msd[j * n + i];
                k->Msd[i * n + j] = k->Msd[j * n + i] = s;
            }
        k->l_msd = l;
        if (l != k->l_ms) {
            fit_syrk(k->W, n, m, k->I0 * k->I0, k->Ms);
            k->l_ms = l;
        }
    } else if (l != k->l_ms) {
        for (size_t p = 0; p < n; p++) kr_kernel_factor(&k->ker, k->A + p * m, k->W + p * m, NULL, scr);
        fit_syrk(k->W, n, m, k->I0 * k->I0, k->Ms);
        k->l_ms = l;
    }
}

static double value_points(kr_prob_t *k, const double *th)
{
    size_t n = k->n;
    int nl = k->nl;
    if (k->smooth) smooth_at(k, exp(th[nl + 1]), 0);
    double *V = k->V;
    memset(V, 0, sizeof(double) * n * n);
    for (size_t i = 0; i < n; i++) V[i * n + i] = k->s2[i];
    for (int j = 0; j < nl; j++) {
        double t = exp(th[j]);
        const double *M = k->Mq[j];
        for (size_t i = 0; i < n * n; i++) V[i] += t * M[i];
    }
    if (k->smooth) {
        double t = exp(th[nl]);
        for (size_t i = 0; i < n * n; i++) V[i] += t * k->Ms[i];
    }
    memcpy(k->Vi, V, sizeof(double) * n * n);
    if (LAPACKE_dpotrf_work(LAPACK_ROW_MAJOR, 'L', (lapack_int)n, k->Vi, (lapack_int)n))
        return HUGE_VAL;
    double logdet = 0;
    for (size_t i = 0; i < n; i++) logdet += 2 * log(k->Vi[i * n + i]);
    for (size_t i = 0; i < n; i++) k->Vone[i] = k->one[i], k->Vd[i] = k->d[i];
    LAPACKE_dpotrs_work(LAPACK_ROW_MAJOR, 'L', (lapack_int)n, 1, k->Vi, (lapack_int)n, k->Vone, 1);
    LAPACKE_dpotrs_work(LAPACK_ROW_MAJOR, 'L', (lapack_int)n, 1, k->Vi, (lapack_int)n, k->Vd, 1);
    double a = 0, b = 0;
    for (size_t i = 0; i < n; i++) a += k->one[i] * k->Vone[i], b += k->one[i] * k->Vd[i];
    if (!(a > 0)) return HUGE_VAL;
    k->a = a;
    k->mu = b / a;
    double dPd = 0;
    for (size_t i = 0; i < n; i++) {
        k->Py[i] = k->Vd[i] - k->Vone[i] * k->mu;
        dPd += k->d[i] * k->Py[i];
    }
    k->dPd = dPd;
    return 0.5 * (logdet + log(a) + dPd);
}

/* C = H + the prior's precision blocks at th. */
static void cells_matrix(kr_prob_t *k, const double *th)
{
    size_t p = k->p;
    memcpy(k->C, k->H, sizeof(double) * p * p);
    if (k->smooth) {
        const kr_kernel_t *K = &k->ker;
        int F = k->F;
        double w = exp(-th[k->nl]);
        for (int y = 0; y < F; y++)
            for (int x = 0; x < F; x++) {
                double *row = k->C + (k->off_s + (size_t)y * F + x) * p + k->off_s;
                for (int y2 = y > 0 ? y - 1 : 0; y2 <= y + 1 && y2 < F; y2++)
                    for (int x2 = x > 0 ? x - 1 : 0; x2 <= x + 1 && x2 < F; x2++) {
                        double ty = y == y2 ? K->tdiag[y] : K->toff;
                        double tx = x == x2 ? K->tdiag[x] : K->toff;
                        row[(size_t)y2 * F + x2] += w * ty * tx;
                    }
            }
    }
    for (int j = 0; j < k->nl; j++) {
        double w = exp(-th[j]);
        size_t qq = (size_t)k->q[j] * k->q[j];
        for (size_t c = 0; c < qq; c++) k->C[(k->off_q[j] + c) * p + k->off_q[j] + c] += w;
    }
}

static double value_cells(kr_prob_t *k, const double *th)
{
    size_t p = k->p;
    int nl = k->nl;
    double logdetS = 0;
    if (k->smooth) {
        smooth_at(k, exp(th[nl + 1]), 0);
        logdetS += (double)k->m * th[nl] + k->ker.logdet;
    }
    for (int j = 0; j < nl; j++) logdetS += (double)k->q[j] * k->q[j] * th[j];
    cells_matrix(k, th);
    if (LAPACKE_dpotrf_work(LAPACK_ROW_MAJOR, 'L', (lapack_int)p, k->C, (lapack_int)p))
        return HUGE_VAL;
    double logdetC = 0;
    for (size_t i = 0; i < p; i++) logdetC += 2 * log(k->C[i * p + i]);
    memcpy(k->chat, k->h, sizeof(double) * p);
    LAPACKE_dpotrs_work(LAPACK_ROW_MAJOR, 'L', (lapack_int)p, 1, k->C, (lapack_int)p, k->chat, 1);
    double hc = 0;
    for (size_t i = 0; i < p; i++) hc += k->h[i] * k->chat[i];
    k->mu = k->chat[0];
    k->dPd = k->dDd - hc; /* Woodbury: d^T V^-1 d less the part the cells explain */
    /* log|X^T V^-1 X| is inside log|C| (the 1_A column is W's first) */
    return 0.5 * (k->logdetD + logdetS + logdetC + k->dDd - hc);
}

double kr_value(kr_prob_t *k, const double *th)
{
    k->evals++;
    k->at_valid = 0;
    if (fit_stop_now(k->stop)) {
        k->stopped = 1;
        return HUGE_VAL;
    }
    double f = k->cells ? value_cells(k, th) : value_points(k, th);
    if (!isfinite(f)) return HUGE_VAL;
    memcpy(k->at, th, sizeof(double) * (size_t)kr_theta_count(k));
    k->at_valid = 1;
    return f;
}

/* Lower triangle of a factor's inverse (dpotri) mirrored to a full symmetric matrix. */
static int invert_factor(double *M, size_t n)
{
    if (LAPACKE_dpotri_work(LAPACK_ROW_MAJOR, 'L', (lapack_int)n, M, (lapack_int)n)) return -1;
    for (size_t i = 0; i < n; i++)
        for (size_t j = i + 1; j < n; j++) M[i * n + j] = M[j * n + i];
    return 0;
}

/* P w = Vi w - Vone (Vone^T w) / a, Vi the full inverse */
static void apply_P(const kr_prob_t *k, const double *w, double *out)
{
    size_t n = k->n;
    fit_gemm(k->Vi, 0, w, 0, n, n, 1, 1, 0, out);
    double s = 0;
    for (size_t i = 0; i < n; i++) s += k->Vone[i] * w[i];
    for (size_t i = 0; i < n; i++) out[i] -= k->Vone[i] * s / k->a;
}

static int derivs_points(kr_prob_t *k, const double *th, double *g, double *AI)
{
    size_t n = k->n;
    int nl = k->nl, np = kr_theta_count(k);
    if (k->smooth) smooth_at(k, exp(th[nl + 1]), 1);
    if (invert_factor(k->Vi, n)) return -1;
    double *w = k->y, *Pw = k->t, u[1];
    (void)u;
    for (int c = 0; c < np; c++) {
        const double *M = c < nl ? k->Mq[c] : c == nl ? k->Ms : k->Msd;
        double s = exp(th[c < nl ? c : nl]); /* V_c = s M */
        double tr = 0, vv = 0;
        for (size_t i = 0; i < n; i++) {
            double mi = 0, mv = 0;
            for (size_t j = 0; j < n; j++) {
                tr += k->Vi[i * n + j] * M[i * n + j];
                mi += M[i * n + j] * k->Py[j];
                mv += M[i * n + j] * k->Vone[j];
            }
            w[c * n + i] = s * mi;
            vv += k->Vone[i] * mv;
        }
        double pVp = 0;
        for (size_t i = 0; i < n; i++) pVp += k->Py[i] * w[c * n + i];
        g[c] = 0.5 * (s * (tr - vv / k->a) - pVp);
        apply_P(k, w + c * n, Pw + c * n);
    }
    for (int c = 0; c < np; c++)
        for (int e = 0; e <= c; e++) {
            double s = 0;
            for (size_t i = 0; i < n; i++) s += w[c * n + i] * Pw[e * n + i];
            AI[c * np + e] = AI[e * np + c] = 0.5 * s;
        }
    return 0;
}

static int derivs_cells(kr_prob_t *k, const double *th, double *g, double *AI)
{
    size_t p = k->p, m = k->m;
    int nl = k->nl, np = kr_theta_count(k);
    if (k->smooth) smooth_at(k, exp(th[nl + 1]), 1);
    memcpy(k->Ci, k->C, sizeof(double) * p * p);
    if (invert_factor(k->Ci, p)) return -1;
    double *y = k->y, *t = k->t;
    memset(y, 0, sizeof(double) * p * (size_t)np);
    for (int j = 0; j < nl; j++) { /* grid levels: R = I */
        size_t o = k->off_q[j], qq = (size_t)k->q[j] * k->q[j];
        double tr = 0, cc = 0;
        for (size_t c = 0; c < qq; c++) {
            tr += k->Ci[(o + c) * p + o + c];
            cc += k->chat[o + c] * k->chat[o + c];
            y[(size_t)j * p + o + c] = k->chat[o + c];
        }
        g[j] = 0.5 * ((double)qq - exp(-th[j]) * (tr + cc));
    }
    if (k->smooth) {
        const kr_kernel_t *K = &k->ker;
        size_t o = k->off_s;
        const double *cs = k->chat + o, *Cs = k->Ci + o * p + o;
        double *kc = malloc(sizeof(double) * m * 2);
        if (!kc) return -1;
        double w = exp(-th[nl]), q0 = 0, q1 = 0;
        kr_kernel_prec(K, cs, kc, 0);
        for (size_t c = 0; c < m; c++) q0 += cs[c] * kc[c];
        g[nl] = 0.5 * ((double)m - w * (kr_kernel_prec_trace(K, Cs, p, 0) + q0));
        kr_kernel_prec(K, cs, kc, 1);
        for (size_t c = 0; c < m; c++) q1 += cs[c] * kc[c];
        g[nl + 1] = 0.5 * (K->dlogdet + w * (kr_kernel_prec_trace(K, Cs, p, 1) + q1));
        memcpy(y + (size_t)nl * p + o, cs, sizeof(double) * m);
        kr_kernel_cov(K, kc, kc + m, 0); /* y_l = -K (dK^-1 c^_s) */
        for (size_t c = 0; c < m; c++) y[(size_t)(nl + 1) * p + o + c] = -kc[m + c];
        free(kc);
    }
    /* t_c = H y_c; AI_cd = (1/2) (y_c^T t_d - t_c^T Ci t_d) */
    fit_gemm(y, 0, k->H, 0, (size_t)np, p, p, 1, 0, t); /* rows: y_c^T H = (H y_c)^T */
    double *u = malloc(sizeof(double) * p * (size_t)np);
    if (!u) return -1;
    fit_gemm(t, 0, k->Ci, 0, (size_t)np, p, p, 1, 0, u);
    for (int c = 0; c < np; c++)
        for (int e = 0; e <= c; e++) {
            double s = 0;
            for (size_t i = 0; i < p; i++) s += y[(size_t)c * p + i] * t[(size_t)e * p + i] -
                                                u[(size_t)c * p + i] * t[(size_t)e * p + i];
            AI[c * np + e] = AI[e * np + c] = 0.5 * s;
        }
    free(u);
    return 0;
}

int kr_derivs(kr_prob_t *k, const double *th, double *g, double *AI)
{
    if (!k->at_valid) return -1;
    int rc = k->cells ? derivs_cells(k, th, g, AI) : derivs_points(k, th, g, AI);
    if (rc) k->failed = 1;
    return rc;
}
