/* geometry.h: the scan's geometry as fit parameters: the spot's first-zero radius R (eq. 1) and the
 * offset (dx, dy) of the true spot positions from the written ones (true = written + offset, the
 * convention of `ips simulate --offset`), fitted together with the r x r map.
 *
 * Method: variable projection (Golub and Pereyra 1973). For fixed (R, dx, dy) the model
 * M_k = sum_ij T_ij A_kij(R, dx, dy) (eq. 3, T = I0 S) is linear in T, so its weighted least-squares
 * solution T(R, dx, dy) is exact (numerics note 1) and the chi-square of eq. 4 becomes a function
 * of the three nonlinear parameters only. That function is minimised by GSL's trust-region
 * Levenberg-Marquardt (gsl_multifit_nlinear) on the projected residual vector
 * (d_k - M_k) / sigma_k with a central finite-difference Jacobian; each residual evaluation is one
 * design matrix (design.h, positions shifted by (dx, dy), radius R) and one linear solve. The
 * bounds (R in [R_written / 2, 2 R_written], |dx|, |dy| <= pitch) are kept by a smooth change of
 * variable p = c + h tanh(u), so LM runs unconstrained in u.
 *
 * Uncertainties: from the Jacobian of the whole problem (the r*r values of T and R, dx, dy) at the
 * optimum, cov = (J^T W J)^-1 with W the noise model's 1/sigma^2, as fit_map's S_err (model.h):
 * not scaled by chi2_red (the noise model is taken as known; chi2_red is reported so a caller can
 * scale). The marginal sigma of R, dx, dy are the square roots of its last three diagonal
 * entries (the T are profiled out, so the map's freedom widens them).
 *
 * The inner solve is always the unconstrained linear one (method and nonneg of the options are not
 * used: an active set would make chi2 non-smooth in the geometry); noise and design_tol are.
 * Pure numerics: no I/O, no globals, thread-safe. GSL errors never abort (model.h). */
#ifndef IPSD_FIT_GEOMETRY_H
#define IPSD_FIT_GEOMETRY_H

#include <stddef.h>

#include "base/err.h"
#include "fit/model.h"
#include "fit/scandata.h"

/* Why a geometry fit must not be used (the rest of the result is filled as far as it got). */
enum fit_geometry_flag {
    FIT_GEOMETRY_NOT_CONVERGED = 1 << 0, /* LM hit its iteration limit */
    FIT_GEOMETRY_AT_BOUND = 1 << 1,      /* a parameter ran into its bound: no minimum inside */
    FIT_GEOMETRY_ILL_CONDITIONED = 1 << 2, /* the whole-problem Jacobian is (near) rank-deficient:
                                              the geometry is not determined by these points */
    FIT_GEOMETRY_POOR_FIT = 1 << 3,      /* chi2_p < FIT_POOR_FIT_P (model.h): the r x r map and
                                            the geometry do not describe the data, so the quoted
                                            sigmas are not the error (the misfit is absorbed by R,
                                            dx, dy). A warning: the geometry is still used */
};

/* The flags that make a geometry unusable (poor_fit alone does not). */
#define FIT_GEOMETRY_UNUSABLE \
    (FIT_GEOMETRY_NOT_CONVERGED | FIT_GEOMETRY_AT_BOUND | FIT_GEOMETRY_ILL_CONDITIONED)

/* The geometry fit's r picked from the data (geometry_pick.c): the first r tried, the most
 * tried, and how many degrees of freedom a fit must keep (at least n / FIT_GEOMETRY_DOF_DIV). */
#define FIT_GEOMETRY_PICK_R_MIN 3
#define FIT_GEOMETRY_PICK_R_MAX 16
#define FIT_GEOMETRY_DOF_DIV 5
#define FIT_GEOMETRY_PICK_PATIENCE 1 /* r past the best BIC tried before stopping, less one */

typedef struct fit_geometry {
    int r;                     /* map resolution the geometry was fitted at */
    size_t n_used;             /* points used (finite, below full scale) */
    int params;                /* r*r + 3 (the T and R, dx, dy) */
    unsigned flags;            /* enum fit_geometry_flag; 0: the geometry can be used */
    double R_um, R_err_um;     /* fitted first-zero radius and its 1-sigma */
    double dx_um, dx_err_um;   /* true spot position minus written, x, and its 1-sigma */
    double dy_um, dy_err_um;
    double R_written_um;       /* the radius written in the scan */
    double chi2_fixed;         /* chi2 of the r x r fit at the written geometry */
    double chi2_fitted;        /* and at the fitted one (<= chi2_fixed) */
    double chi2_red;           /* chi2_fitted / (n_used - params) */
    double chi2_p;             /* upper tail of chi-square(n_used - params) at chi2_fitted */
    double bic;                /* n ln(chi2_fitted / n) + params ln n (the pick's criterion) */
    int r_picked;              /* 1: r picked from the data (fit_geometry_pick); 0: asked */
    int r_first, r_last;       /* the r the pick fitted (0, 0 when r was asked) */
    double corr[3];            /* correlations R-dx, R-dy, dx-dy */
    int iterations;            /* LM iterations */
    int evaluations;           /* design matrices built (the cost) */
    int kriged;                /* 1: refined under the kriged model (fit_geometry_krige); the
                                  chi2_* and bic above stay the r x r fit's, and the kriged
                                  model's own fit is below */
    double kriged_chi2;        /* d^T P d at the kriged optimum (krige_int.h) */
    double kriged_chi2_red;    /* over N - 1, its expectation under the model */
    double kriged_chi2_p;      /* upper tail of chi-square(N - 1): poor_fit below FIT_POOR_FIT_P */
    char kriged_error[256];    /* why the kriged refinement asked for was not kept (the pipeline,
                                  fit/pipeline.c): "" when it was, or was not asked */
} fit_geometry_t;

/* "ok", or "not_converged" / "at_bound" / "ill_conditioned" / "poor_fit" (the first of flags).
 * Static. */
const char *fit_geometry_status(unsigned flags);

/* Fits R, dx, dy with the r x r map (1 <= r <= 32) from the written geometry of scan. Returns 0
 * with *out filled (check out->flags), -EINVAL for bad arguments (r, the scan's constants),
 * -ERANGE when the points cannot determine r*r + 3 parameters (err says how many there are),
 * -EDOM when the linear algebra or GSL's solver failed, -ENOMEM. */
int fit_geometry_run(const fit_scan_t *scan, int r, const fit_options_t *opts,
                     fit_geometry_t *out, err_t *err);

/* Fits the geometry at r = FIT_GEOMETRY_PICK_R_MIN, +1, ... and keeps the usable fit (flags
 * without FIT_GEOMETRY_UNUSABLE) of smallest BIC = n ln(chi2/n) + (r*r + 3) ln n; stops when
 * two r in a row have a BIC above the best so far (a pixel's structure can suit odd r better
 * than even ones), or when a fit would keep fewer than
 * n / FIT_GEOMETRY_DOF_DIV degrees of freedom, or at FIT_GEOMETRY_PICK_R_MAX. Why: a map too
 * coarse for the pixel's structure biases R, dx, dy far beyond their sigmas (docs/numerics.md,
 * "Geometry fit"); BIC does not depend on the noise model's scale. *out is the kept fit (with
 * r_picked 1, r_first, r_last), or the last one tried when none is usable. Returns as
 * fit_geometry_run (-ERANGE when not even the first r fits). */
int fit_geometry_pick(const fit_scan_t *scan, const fit_options_t *opts, fit_geometry_t *out,
                      err_t *err);

/* Refines the r x r fit start (fit_geometry_run or _pick: its r and geometry) under the kriged
 * model (krige.h, the divisor grids of start->r): the (R, dx, dy) of largest likelihood with the
 * map integrated out and the hyperparameters profiled (geometry_krige.c), its sigmas from that
 * profile's curvature. *out is start with the geometry, sigmas, flags and evaluations replaced.
 * Returns 0, -EINVAL, -EDOM, -ENOMEM, -ECANCELED (opts->stop). */
int fit_geometry_krige(const fit_scan_t *scan, const fit_geometry_t *start,
                       const fit_options_t *opts, fit_geometry_t *out, err_t *err);

/* The scan as the geometry says it was: *out is a copy of scan with positions x_um + dx_um,
 * y_um + dy_um written into x and y (scan->n each, caller-allocated; out borrows them) and radius
 * R_um. */
void fit_geometry_apply(const fit_scan_t *scan, const fit_geometry_t *g, double *x, double *y,
                        fit_scan_t *out);

#endif
