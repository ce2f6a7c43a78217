/* gemm.h (internal to fit/): a row-major matrix product, a symmetric one and a column-major
 * triangular one through the Fortran BLAS (dgemm, dsyrk, dtrmm) that the fit library links
 * (OpenBLAS, with LAPACK). Not gsl_blas_dgemm: that calls cblas_dgemm, which
 * resolves to GSL's own CBLAS in one binary and to OpenBLAS's in another (ipsd links libgsl
 * shared, `ips` statically), and the two round differently; the fit documents of `ips` and ipsd
 * are equal number for number (docs/contracts.md). */
#ifndef IPSD_FIT_GEMM_H
#define IPSD_FIT_GEMM_H

#include <stddef.h>

/* out (a x c) = alpha op(X) op(Y) + beta out, row-major; op(X) = X (a x b) or, when tx, X^T
 * (X stored b x a); op(Y) = Y (b x c) or, when ty, Y^T (Y stored c x b). */
void fit_gemm(const double *X, int tx, const double *Y, int ty, size_t a, size_t b, size_t c,
              double alpha, double beta, double *out);

/* out (a x a) = alpha X X^T, row-major, X a x b: the symmetric product at half a product's cost
 * (dsyrk), both triangles filled. */
void fit_syrk(const double *X, size_t a, size_t b, double alpha, double *out);

/* B (rows x cols, column-major, leading dimension ldb) = op(A) B when left, else B op(A); A
 * triangular (order rows when left, else cols; leading dimension lda), upper or lower, op(A) =
 * A or A^T (trans), with an implied unit diagonal when unit (A's diagonal is not read). */
void fit_trmm(int left, int upper, int trans, int unit, size_t rows, size_t cols,
              const double *A, size_t lda, double *B, size_t ldb);

#endif
