/* lm.h (internal to fit/): the paper's fit, Levenberg-Marquardt on (S_ij, I0) of
 * M_k = I0 sum_j S_j A_kj (eq. 3), minimising eq. 4, by GSL's gsl_multifit_nlinear. */
#ifndef IPSD_FIT_LM_H
#define IPSD_FIT_LM_H

#include <stddef.h>

#include "fit/stop.h"

typedef struct lm_result {
    double chi2;
    int iterations;
    int converged; /* 0 when the iteration limit was hit */
} lm_result_t;

/* A: n x m row-major design matrix, y: measured signal minus bias, sigma: uncertainties.
 * S (m) and *I0 hold the start on entry (the paper starts from S = 1) and the result on exit.
 * stop (may be NULL) is polled (stop.h, site "lm") before each iteration, each Jacobian and each
 * evaluation of the residuals.
 * Returns 0, -ENOMEM, -ECANCELED (stopped), or -EDOM when GSL reports a failure other than
 * non-convergence. */
int lm_fit(const double *A, const double *sigma, const double *y, size_t n, size_t m, double *S,
           double *I0, const fit_stop_t *stop, lm_result_t *res);

#endif
