/* model.h: fitting the paper's pixel response model M_k = I0 sum_ij S_ij A_kij (eq. 3) to a scan
 * by weighted chi-square (eq. 4), model selection over r (AIC, BIC), and the F-test of a nested
 * edge model. Thread-safe, no I/O; results own their arrays (free with the matching _free).
 *
 * Methods: `linear` solves the weighted linear least-squares problem in T = I0 S (the model is
 * linear in T; numerics note 1) by SVD: the global minimum, fast, with the condition number.
 * `lm` is the paper's Levenberg-Marquardt (GSL gsl_multifit_nlinear) from S = 1; `both` runs LM
 * and flags when it stops above the global minimum. S is normalised to mean 1, I0 = mean(T).
 *
 * GSL errors: GSL's default error handler aborts the process. Every fit/ function that can reach
 * GSL (the fits and the sweep here, the pipeline, the F-test, Wiener, the interpolation, the box
 * integral) turns that default off, once per process, on its first call, and reports GSL's
 * failures through its own return code; callers need not call gsl_set_error_handler_off(). A
 * handler the program installed before its first fit/ call is kept (docs/numerics.md). */
#ifndef IPSD_FIT_MODEL_H
#define IPSD_FIT_MODEL_H

#include <stddef.h>

#include "fit/design.h"
#include "base/err.h"
#include "fit/noise.h"
#include "fit/scandata.h"

/* Status flags of a fit: any flag but FIT_SATURATED / FIT_NONFINITE (points left out, counted)
 * means the map must not be trusted as it is. */
enum fit_flag {
    FIT_UNDERDETERMINED = 1 << 0, /* r*r + 1 parameters > usable points: no map */
    FIT_UNCONSTRAINED = 1 << 1,   /* some sub-pixels' 1-sigma error exceeds the mean sensitivity */
    FIT_ILL_CONDITIONED = 1 << 2, /* near-collinear columns: cond > 1e8 (no map if mean T <= 0) */
    FIT_NONFINITE = 1 << 3,       /* points with non-finite position or signal were left out */
    FIT_SATURATED = 1 << 4,       /* points at or above full scale were left out */
    FIT_NO_SIGNAL = 1 << 5,       /* data consistent with no light (3 sigma): no map */
    FIT_LM_NOT_GLOBAL = 1 << 6,   /* LM stopped with chi2 above the linear global minimum */
    FIT_LM_NOT_CONVERGED = 1 << 7,/* LM hit its iteration limit */
    FIT_NO_POINTS = 1 << 8,       /* no usable point at all */
    FIT_POOR_FIT = 1 << 9,        /* the model does not describe the data: the chi-square p-value
                                     (noise model's sigma) is below FIT_POOR_FIT_P */
};

/* A fit whose chi2 would be exceeded by chance less often than this is a poor fit. */
#define FIT_POOR_FIT_P 1e-3

typedef enum fit_method { FIT_LINEAR = 0, FIT_LM = 1, FIT_BOTH = 2 } fit_method_t;

typedef struct fit_options {
    fit_noise_t noise;
    fit_method_t method;
    int nonneg;                /* constrain S_ij >= 0 (Lawson-Hanson NNLS on the linear path) */
    double design_tol;         /* design-matrix accuracy (design.h), default 1e-12 */
    fit_design_cache_t *design_cache; /* sweeps shared across fits of one scan (design.h); NULL:
                                         none. The pipeline gives its run one. */
    fit_stop_t stop;           /* polled inside the long loops (stop.h): a fit stopped there
                                  returns -ECANCELED; zero (the default): never */
} fit_options_t;

fit_options_t fit_options_default(void);

typedef struct fit_result {
    int r;
    int params;                /* r*r + 1, as the paper counts (the S_ij and I0) */
    size_t n_used;             /* points used (N of AIC/BIC) */
    size_t n_saturated, n_nonfinite, n_unconstrained;
    unsigned flags;            /* enum fit_flag */
    double chi2, chi2_red;     /* chi2_red = chi2 / (n_used - params) */
    double chi2_p;             /* P(chi2_dof >= chi2), dof = n_used - params: the goodness of fit
                                  under the noise model (NaN without degrees of freedom) */
    double aic, bic;           /* N ln(chi2/N) + 2p, N ln(chi2/N) + p ln N */
    double I0, I0_err;         /* DN per unit-peak-Airy flux (um^-2) */
    double *S, *S_err;         /* r*r, row-major y then x (index j*r + i); NULL without a map */
    double *model_dn;          /* n: fitted model M_k + bias for every input point (NaN if
                                  left out or no map) */
    double *resid;             /* n: normalised residuals (signal - model) / sigma_k of every
                                  input point (NaN if left out or no map); their squares sum to
                                  chi2 */
    double cond;               /* 2-norm condition number of the weighted design matrix */
    double lm_chi2;            /* LM's chi2 (method lm/both), else NaN */
    int lm_iterations;
    fit_design_stats_t design; /* leave-out statistics of the design matrix */
    double cv_chi2;            /* leave-one-out prediction chi2 (see fit_loo_chi2 in model.c) */
    double design_ms, solve_ms;/* cost of this fit */
} fit_result_t;

/* The primary status word of flags: "ok", or the most severe condition, in this order:
 * "saturated" / "nonfinite_input" / "no_points" (no usable point; the first two when all were
 * left out for that reason), "underdetermined", "no_signal", "ill_conditioned", "unconstrained",
 * "poor_fit", "lm_not_global", "lm_not_converged", then "nonfinite_input" and "saturated" again for a good
 * map from which such points were left out (counted in the result). Static string. */
const char *fit_status_name(unsigned flags);

/* Checks the sensor constants of a scan (positive pitch, radius, gain, frames; finite bias;
 * non-negative read noise). Returns 0 or -EINVAL naming the field. */
int fit_scan_check(const fit_scan_t *scan, err_t *err);

/* Fits the r x r model. Returns 0 with a result (check its flags), or -EINVAL for bad arguments
 * (r outside 1..32, non-positive pitch/radius/gain/frames), -ENOMEM. */
int fit_map(const fit_scan_t *scan, int r, const fit_options_t *opts, fit_result_t *out,
            err_t *err);

void fit_result_free(fit_result_t *res);

/* The joint covariance of the mean-1 maps S of the r1 x r1 and r2 x r2 linear fits of scan's
 * points (fit_map's points and weights; the unconstrained linear solution, whatever opts->method
 * and nonneg say): C11 (r1^2 x r1^2), C22 (r2^2 x r2^2) and C12 = Cov(S1, S2) (r1^2 x r2^2),
 * row-major, caller-allocated, in the noise model's units (as S_err^2). Both fits are solved
 * again. 0, -EINVAL (r outside 1..32, fewer points than either needs), -ENOMEM, -EDOM. */
int fit_map_joint_cov(const fit_scan_t *scan, int r1, int r2, const fit_options_t *opts,
                      double *C11, double *C22, double *C12, err_t *err);

typedef struct fit_sweep {
    int r_min, r_max;
    fit_result_t *fits;        /* r_max - r_min + 1 results */
    int best_aic, best_bic;    /* r of the smallest AIC / BIC among fits with a map; 0 if none */
    int recommended_r;         /* the r whose map is expected closest to the truth (recommend.h),
                                  0 if none; its map is the one a calibration stores with
                                  "map": "recommended" (the kriged map by default) */
    int range_edge;            /* AIC or BIC picked r_max or the largest r the points determine */
    char recommended_reason[320];
    struct fit_kriged *kriged; /* the kriged map of the recommended r (krige.h) when the pipeline
                                  was asked for it (fit_pipeline_opts_t.krige), else NULL */
    struct fit_shrunk *shrunk; /* the recommended map shrunk toward the next coarser fit's
                                  (shrink.h); NULL when there is none (r = 1, no coarser map) */
} fit_sweep_t;

/* Fits r = r_min..r_max and picks the best r by AIC and by BIC: fit_pipeline_run (pipeline.h)
 * with the sweep only. -EINVAL naming r_min / r_max for a range outside 1 <= r_min <= r_max <= 32.
 * On an error out->fits is NULL. */
int fit_sweep_run(const fit_scan_t *scan, int r_min, int r_max, const fit_options_t *opts,
                  fit_sweep_t *out, err_t *err);

void fit_sweep_free(fit_sweep_t *sw);

/* Edges of the F-test's null model: each sub-pixel touching a named edge keeps its own S_ij,
 * all others share one S0 (the paper: top, left, bottom; y downward, row 0 is the top). */
enum fit_edge { FIT_EDGE_TOP = 1, FIT_EDGE_LEFT = 2, FIT_EDGE_BOTTOM = 4, FIT_EDGE_RIGHT = 8 };

/* Parses "top,left,bottom" into a mask; returns 0 or -EINVAL naming the bad word in err. */
int fit_edges_parse(const char *list, unsigned *mask, err_t *err);

typedef struct fit_ftest {
    int r;
    unsigned edges;
    double chi2_h0, chi2_h1;
    int params_h0, params_h1;  /* p0 = edge sub-pixels + S0 + I0; p1 = r*r + 1 */
    size_t n;
    double F;                  /* ((chi2_0 - chi2_1)/chi2_1) ((N - p1)/(p1 - p0)), eq. 6 */
    double p_value;            /* upper tail of F(p1 - p0, N - p1) */
    unsigned flags;            /* fit flags of H1 and H0 combined */
} fit_ftest_t;

/* The p-value of eq. 6's F: the upper tail of the F distribution with (d1, d2) degrees of
 * freedom at F (GSL's gsl_cdf_fdist_Q); NaN when F is NaN or d1 < 1 or d2 < 1. */
double fit_ftest_p_value(double F, int d1, int d2);

/* The F-test of the paper for an r x r map. Needs N > p1 > p0. */
int fit_ftest_run(const fit_scan_t *scan, int r, unsigned edges, const fit_options_t *opts,
                  fit_ftest_t *out, err_t *err);

/* The same with H1 already fitted (e.g. taken from a sweep): h1 must be a linear fit of scan at
 * r = h1->r with the same options; it stays the caller's. */
int fit_ftest_with_h1(const fit_scan_t *scan, const fit_result_t *h1, unsigned edges,
                      const fit_options_t *opts, fit_ftest_t *out, err_t *err);

#endif
