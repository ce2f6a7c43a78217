/* gemm.c: matrix products through the Fortran BLAS (see gemm.h). */
#include "gemm.h"

#include "fit/gslerr.h"

/* BLAS level 3 (reference interface; OpenBLAS provides it) */
extern void dgemm_(const char *ta, const char *tb, const int *m, const int *n, const int *k,
                   const double *alpha, const double *a, const int *lda, const double *b,
                   const int *ldb, const double *beta, double *c, const int *ldc);
extern void dsyrk_(const char *uplo, const char *trans, const int *n, const int *k,
                   const double *alpha, const double *a, const int *lda, const double *beta,
                   double *c, const int *ldc);
extern void dtrmm_(const char *side, const char *uplo, const char *ta, const char *diag,
                   const int *m, const int *n, const double *alpha, const double *a,
                   const int *lda, double *b, const int *ldb);

void fit_gemm(const double *X, int tx, const double *Y, int ty, size_t a, size_t b, size_t c,
              double alpha, double beta, double *out)
{
    if (a == 0 || c == 0) return;
    fit_gsl_policy(); /* one BLAS thread (gslerr.h) */
    /* row-major out = op(X) op(Y) is column-major out^T = op(Y)^T op(X)^T: the column-major
     * views of Y and X are their transposes, so pass Y first with the same flags */
    int m = (int)c, n = (int)a, k = (int)b;
    int ldy = ty ? (int)b : (int)c, ldx = tx ? (int)a : (int)b, ldo = (int)c;
    dgemm_(ty ? "T" : "N", tx ? "T" : "N", &m, &n, &k, &alpha, Y, &ldy, X, &ldx, &beta, out,
           &ldo);
}

void fit_syrk(const double *X, size_t a, size_t b, double alpha, double *out)
{
    if (a == 0) return;
    fit_gsl_policy();
    /* row-major X (a x b) is column-major X^T (b x a): X X^T = (X^T)^T (X^T), dsyrk's "T" form;
     * it fills one triangle of the symmetric a x a product (column-major upper is row-major
     * lower), mirrored here */
    int n = (int)a, k = (int)b, ld = (int)b, lo = (int)a;
    double zero = 0;
    dsyrk_("U", "T", &n, &k, &alpha, X, &ld, &zero, out, &lo);
    for (size_t i = 0; i < a; i++)
        for (size_t j = i + 1; j < a; j++) out[i * a + j] = out[j * a + i];
}

void fit_trmm(int left, int upper, int trans, int unit, size_t rows, size_t cols,
              const double *A, size_t lda, double *B, size_t ldb)
{
    if (rows == 0 || cols == 0) return;
    fit_gsl_policy();
    int m = (int)rows, n = (int)cols, la = (int)lda, lb = (int)ldb;
    double one = 1;
    dtrmm_(left ? "L" : "R", upper ? "U" : "L", trans ? "T" : "N", unit ? "U" : "N", &m, &n, &one,
           A, &la, B, &lb);
}
