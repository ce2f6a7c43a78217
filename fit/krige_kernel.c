/* krige_kernel.c: the exponential kernel's closed forms (krige_kernel.h): the AR(1) correlation
 * rho^|i - j|, its Cholesky factor as discounted running sums, its tridiagonal inverse, its log
 * determinant, each with its derivative in log l. Written here because these closed forms are
 * what make the kriged map fast; LAPACK would factor and invert K1 as a dense matrix. */
#include "krige_kernel.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gemm.h"

void kr_kernel_set(kr_kernel_t *k, int F, double l)
{
    k->F = F;
    k->l = l;
    k->rho = exp(-1 / (F * l));
    k->drho = k->rho / (F * l); /* -rho log rho */
    double r = k->rho, dr = k->drho, one_m = -expm1(-2 / (F * l)); /* 1 - rho^2, accurately */
    k->s = sqrt(one_m);
    k->ds = -r * dr / k->s;
    for (int i = 0; i < F; i++)
        for (int j = 0; j < F; j++) {
            int d = abs(i - j);
            k->K1[i * F + j] = pow(r, d);
            k->dK1[i * F + j] = d ? d * pow(r, d - 1) * dr : 0;
        }
    double c = 1 / one_m, dc = 2 * r * dr * c * c;
    for (int i = 0; i < F; i++) {
        int end = i == 0 || i == F - 1;
        k->tdiag[i] = end ? c : c * (1 + r * r);
        k->dtdiag[i] = end ? dc : dc * (1 + r * r) + c * 2 * r * dr;
    }
    k->toff = -c * r;
    k->dtoff = -(dc * r + c * dr);
    k->logdet = 2.0 * F * (F - 1) * log(one_m);
    k->dlogdet = 2.0 * F * (F - 1) * (-2 * r * dr / one_m);
}

/* Two doubles as one value (GCC's and clang's vector extension: one SSE2 operation on x86-64,
 * the lanes independent): the running sums of two columns advance together. */
typedef double v2d __attribute__((vector_size(16)));

static v2d load2(const double *p)
{
    v2d v;
    memcpy(&v, p, sizeof v);
    return v;
}

static void store2(double *p, v2d v)
{
    memcpy(p, &v, sizeof v);
}

/* L^T X down the rows of the F x F matrix X (along its first index, for every column at once):
 * out_j = s_j c_j, c_j = sum_{i >= j} rho^(i - j) X_i, and, when dout, dout_j = d out_j / d log l
 * = ds_j c_j + s_j drho e_j, e_j = d c_j / d rho = c_{j+1} + rho e_{j+1}. The columns go four
 * at a time, two by two (F is padded to a multiple of 4 in the sums; the extra lanes are not
 * stored). */
static void factor_rows(const kr_kernel_t *k, const double *X, double *out, double *dout)
{
    int F = k->F, F4 = (F + 3) / 4 * 4;
    double c[KR_KERNEL_MAX_F + 4] = {0}, e[KR_KERNEL_MAX_F + 4] = {0}, x[KR_KERNEL_MAX_F + 4] = {0},
           o[KR_KERNEL_MAX_F + 4], od[KR_KERNEL_MAX_F + 4];
    const double rho = k->rho;
    for (int j = F - 1; j >= 0; j--) {
        memcpy(x, X + (size_t)j * F, sizeof(double) * (size_t)F);
        double s = j ? k->s : 1, ds = j ? k->ds : 0, sd = s * k->drho;
        for (int i = 0; i < F4; i += 2) {
            v2d cv = load2(c + i), xv = load2(x + i);
            if (dout) {
                v2d ev = load2(e + i);
                ev = cv + rho * ev; /* e_{F-1} = 0: c starts at 0 */
                store2(e + i, ev);
                cv = xv + rho * cv;
                store2(od + i, ds * cv + sd * ev);
            } else {
                cv = xv + rho * cv;
            }
            store2(c + i, cv);
            store2(o + i, s * cv);
        }
        memcpy(out + (size_t)j * F, o, sizeof(double) * (size_t)F);
        if (dout) memcpy(dout + (size_t)j * F, od, sizeof(double) * (size_t)F);
    }
}

static void transpose(const double *X, int F, double *Y)
{
    for (int i = 0; i < F; i++)
        for (int j = 0; j < F; j++) Y[(size_t)j * F + i] = X[(size_t)i * F + j];
}

void kr_kernel_factor(const kr_kernel_t *k, const double *a, double *W, double *Wd,
                      double *scratch)
{
    int F = k->F;
    double *B = scratch, *Bd = scratch + F * F, *T = scratch + 2 * F * F;
    factor_rows(k, a, B, Wd ? Bd : NULL); /* along y: B = L^T a, Bd = (d L^T) a */
    transpose(B, F, T);                    /* along x, as rows of the transpose: W^T = L^T B^T */
    factor_rows(k, T, W, Wd);              /* W (x-major) = (B L)^T, Wd = (B dL)^T */
    if (Wd) {
        transpose(Bd, F, T);
        factor_rows(k, T, B, NULL);        /* (Bd L)^T */
        for (int i = 0; i < F * F; i++) Wd[i] += B[i];
    }
}

/* (T v)_i along one line: tridiagonal diag[i], off beside it. */
static void tri_line(const double *diag, double off, int F, const double *v, size_t st,
                     double *out, size_t so)
{
    for (int i = 0; i < F; i++) {
        double s = diag[i] * v[(size_t)i * st];
        if (i > 0) s += off * v[(size_t)(i - 1) * st];
        if (i < F - 1) s += off * v[(size_t)(i + 1) * st];
        out[(size_t)i * so] = s;
    }
}

/* Y = Ty X Tx: Ty along y (columns), Tx along x (rows) */
static void tri_both(const kr_kernel_t *k, const double *dy, double oy, const double *dx, double ox,
                     const double *X, double *Y, int add)
{
    int F = k->F;
    double B[KR_KERNEL_MAX_F * KR_KERNEL_MAX_F], t[KR_KERNEL_MAX_F];
    for (int x = 0; x < F; x++) tri_line(dy, oy, F, X + x, (size_t)F, B + x, (size_t)F);
    for (int y = 0; y < F; y++) {
        tri_line(dx, ox, F, B + (size_t)y * F, 1, t, 1);
        for (int x = 0; x < F; x++) Y[(size_t)y * F + x] = (add ? Y[(size_t)y * F + x] : 0) + t[x];
    }
}

void kr_kernel_prec(const kr_kernel_t *k, const double *X, double *Y, int deriv)
{
    if (!deriv) {
        tri_both(k, k->tdiag, k->toff, k->tdiag, k->toff, X, Y, 0);
        return;
    }
    tri_both(k, k->dtdiag, k->dtoff, k->tdiag, k->toff, X, Y, 0);
    tri_both(k, k->tdiag, k->toff, k->dtdiag, k->dtoff, X, Y, 1);
}

void kr_kernel_cov(const kr_kernel_t *k, const double *X, double *Y, int deriv)
{
    size_t F = (size_t)k->F;
    double B[KR_KERNEL_MAX_F * KR_KERNEL_MAX_F];
    fit_gemm(deriv ? k->dK1 : k->K1, 0, X, 0, F, F, F, 1, 0, B);
    fit_gemm(B, 0, k->K1, 0, F, F, F, 1, 0, Y);
    if (deriv) {
        fit_gemm(k->K1, 0, X, 0, F, F, F, 1, 0, B);
        fit_gemm(B, 0, k->dK1, 0, F, F, F, 1, 1, Y);
    }
}

static double tri_at(const double *diag, double off, int i, int j)
{
    return i == j ? diag[i] : off;
}

double kr_kernel_prec_trace(const kr_kernel_t *k, const double *C, size_t ldc, int deriv)
{
    int F = k->F;
    double tr = 0;
    for (int y = 0; y < F; y++)
        for (int x = 0; x < F; x++) {
            const double *row = C + ((size_t)y * F + x) * ldc;
            for (int y2 = y > 0 ? y - 1 : 0; y2 <= y + 1 && y2 < F; y2++)
                for (int x2 = x > 0 ? x - 1 : 0; x2 <= x + 1 && x2 < F; x2++) {
                    double ty = tri_at(k->tdiag, k->toff, y, y2), tx = tri_at(k->tdiag, k->toff, x, x2);
                    double w = ty * tx;
                    if (deriv)
                        w = tri_at(k->dtdiag, k->dtoff, y, y2) * tx +
                            ty * tri_at(k->dtdiag, k->dtoff, x, x2);
                    tr += w * row[(size_t)y2 * F + x2];
                }
        }
    return tr;
}
