/* krige_kernel.h (internal to fit/): the kriged map's smooth prior on the fine F x F grid, the
 * exponential kernel K = K1 (x) K1 with K1_ij = rho^|i - j|, rho = exp(-1 / (F l)) (l, the
 * correlation length, in pitches; cell centres 1/F apart), and the closed forms of its algebra
 * that make the kriged map's cost independent of l's value (krige.h):
 *   - K1 is the covariance of a stationary AR(1) sequence, so K1 = L L^T with
 *     L_ij = rho^(i - j) s_j (i >= j), s_0 = 1, s_j = sqrt(1 - rho^2): L^T a L for an F x F image
 *     a is two discounted running sums, O(F^2) instead of two O(F^3) products;
 *   - K1^-1 is tridiagonal: (1 - rho^2)^-1 times diag(1, 1 + rho^2, ..., 1 + rho^2, 1) with
 *     -rho beside it, so K^-1 = K1^-1 (x) K1^-1 has nine entries a row (a 3 x 3 stencil);
 *   - log |K| = 2 F (F - 1) log(1 - rho^2).
 * Every quantity comes with its derivative in log l (the restricted likelihood's gradient). */
#ifndef IPSD_FIT_KRIGE_KERNEL_H
#define IPSD_FIT_KRIGE_KERNEL_H

#include <stddef.h>

#define KR_KERNEL_MAX_F 64

typedef struct kr_kernel {
    int F;
    double l, rho, drho;  /* drho = d rho / d log l = -rho log rho */
    double s, ds;         /* sqrt(1 - rho^2) and its d / d log l */
    double K1[KR_KERNEL_MAX_F * KR_KERNEL_MAX_F], dK1[KR_KERNEL_MAX_F * KR_KERNEL_MAX_F];
    double tdiag[KR_KERNEL_MAX_F], toff, dtdiag[KR_KERNEL_MAX_F], dtoff; /* K1^-1, d / d log l */
    double logdet, dlogdet; /* log |K| and d / d log l */
} kr_kernel_t;

/* Sets the kernel for F cells (2..KR_KERNEL_MAX_F) and correlation length l > 0 (pitches). */
void kr_kernel_set(kr_kernel_t *k, int F, double l);

/* W = L^T a L for the F x F image a (row-major), and, when Wd is not NULL, Wd = d W / d log l,
 * both stored transposed (x-major; the same order for every image, so <W_p, W_q> = a_p^T K a_q
 * holds). W and Wd may not alias a; scratch holds 3 F^2 values. */
void kr_kernel_factor(const kr_kernel_t *k, const double *a, double *W, double *Wd,
                      double *scratch);

/* Y = K^-1 X (deriv 0) or (d K^-1 / d log l) X (deriv 1), X and Y F x F images (vec form of the
 * F^2 fine cells), Y not aliasing X. */
void kr_kernel_prec(const kr_kernel_t *k, const double *X, double *Y, int deriv);

/* Y = K X (deriv 0) or (d K / d log l) X (1), dense F x F products. */
void kr_kernel_cov(const kr_kernel_t *k, const double *X, double *Y, int deriv);

/* tr(K^-1 C) (deriv 0) or tr((d K^-1 / d log l) C) (1) for a symmetric F^2 x F^2 block C of a
 * row-major matrix with leading dimension ldc: only C's entries on the stencil are read. */
double kr_kernel_prec_trace(const kr_kernel_t *k, const double *C, size_t ldc, int deriv);

#endif
