/* fitjson.h: the JSON form of fit results (fit/model.h, fit/wiener.h) as the `ips fit` output
 * contract of docs/contracts.md defines it: numbers at full precision, non-finite values as null
 * (JSON has no NaN), the status word and flag names of every fit. Used by `ips fit` and by ipsd,
 * which stores the same document in fits.result. Every function returns a new reference owned by
 * the caller (hand it to jansson with a _set_new / _append_new), or NULL when out of memory. */
#ifndef IPSD_JSON_FITJSON_H
#define IPSD_JSON_FITJSON_H

#include <stddef.h>
#include <stdio.h>

#include <jansson.h>

#include "fit/geometry.h"
#include "fit/krige.h"
#include "fit/model.h"
#include "fit/region.h"
#include "fit/shrink.h"
#include "fit/wiener.h"

/* A JSON real, or null when v is not finite. */
json_t *fitjson_num(double v);

/* A JSON array of n numbers (non-finite as null), or null when v is NULL. */
json_t *fitjson_array(const double *v, size_t n);

/* A JSON integer, or null when v is 0 (for "no such r" answers). */
json_t *fitjson_int_or_null(int v);

/* The names of the set bits of flags (enum fit_flag), most severe first. */
json_t *fitjson_flags(unsigned flags);

/* One fit of the sweep: r, chi2, params, aic, bic, I0, I0_err, S, S_err, cond, chi2_red, status,
 * flags, n_used, n_saturated, n_nonfinite, n_unconstrained, cv_chi2, chi2_p, residuals (one per
 * input point, null where left out), design, timing_ms (and lm_chi2, lm_iterations when method is
 * not linear). */
json_t *fitjson_fit(const fit_result_t *f, fit_method_t method);

/* The F-test: r, edges (names), chi2_H0, params_H0, chi2_H1, params_H1, F, p_value, N, status,
 * flags. */
json_t *fitjson_ftest(const fit_ftest_t *t);

/* Adds the region of the fit to a root document (additions): "region" (inside, all, margin),
 * "margin_um" (null unless margin) and "n_raster" (the points of the whole scan; n_points are
 * those in the region). Returns 0 or -ENOMEM. */
int fitjson_add_region(json_t *root, const fit_region_t *rg, size_t n_raster);

/* The Wiener baseline: nx, ny, step_um [x, y], x0_um, y0_um, nsr, S; additions nsr_method,
 * region ("all": every point given was deconvolved), raster [nx, ny] (that grid), cropped (S is
 * its part in the pixel), signal_fraction. */
json_t *fitjson_wiener(const fit_wiener_t *w);

/* The geometry fit (fit/geometry.h): spot_radius_um, spot_radius_um_err, dx_um, dx_um_err, dy_um,
 * dy_um_err, chi2_fixed, chi2_fitted, and r, status, N, params, chi2_red, written_spot_radius_um,
 * correlation {R_dx, R_dy, dx_dy}, iterations, evaluations. */
json_t *fitjson_geometry(const fit_geometry_t *g);

/* The shrunk map (fit/shrink.h): r, toward_r, factor, detail_rms, noise_rms, tau, S, S_err; null
 * without one. */
json_t *fitjson_shrunk(const fit_shrunk_t *s);

/* The kriged map (fit/krige.h): grid, r, smooth, likelihood_ratio, amplitude, length_um (null
 * without the smooth part), levels [{q, sd}], log_likelihood, evaluations, S, S_err (grid^2
 * each, row-major y then x), and mixture {expected_err, priors [{r, map_err, spread, log_likelihood, weight}]} when it was
 * made (fit_krige_mix); with k NULL, {"error": why_not} (null when why_not is NULL or
 * empty). */
json_t *fitjson_kriged(const fit_kriged_t *k, const char *why_not);

/* The root document of a sweep: N, n_points, sigma, method, nonneg, design_tol, full_scale_dn,
 * fits[], best_r {aic, bic}, recommended_r, recommended_reason, range_edge, shrunk_map. The caller adds
 * "ftest", "wiener", "interp" and "timing_ms". */
json_t *fitjson_sweep(const fit_sweep_t *sw, size_t n_points, const fit_options_t *opts,
                      double full_scale_dn);

/* Prints root to f, indented, every real with 17 significant digits, and a newline.
 * Returns 0 or -EIO. root stays the caller's. */
int fitjson_print(const json_t *root, FILE *f);

#endif
