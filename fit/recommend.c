/* recommend.c: the recommended r of a sweep (see recommend.h). */
#include "fit/recommend.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

fit_recommend_opts_t fit_recommend_opts_default(void)
{
    return (fit_recommend_opts_t){.noise_to_contrast = 0.25, .noise_weight = 2,
                                  .coarse_misfit = 1.5, .escape_misfit = 1.7,
                                  .escape_noise_to_contrast = 0.5, .escape_error_ratio = 2,
                                  .coarse_near = 1.15, .one_se = 1, .one_se_nested = 1};
}

void fit_map_noise_contrast(const fit_result_t *f, double *noise, double *contrast)
{
    *noise = *contrast = NAN;
    if (!f->S || !f->S_err) return;
    size_t m = (size_t)f->r * f->r;
    double v = 0, mean = 0, c = 0;
    for (size_t j = 0; j < m; j++) v += f->S_err[j] * f->S_err[j], mean += f->S[j];
    mean /= (double)m;
    for (size_t j = 0; j < m; j++) c += (f->S[j] - mean) * (f->S[j] - mean);
    *noise = sqrt(v / (double)m);
    *contrast = sqrt(c / (double)m);
}

double fit_map_expected_error(const fit_result_t *f, double noise_scale, double noise_weight,
                              double *noise, double *resolution)
{
    if (noise) *noise = NAN;
    if (resolution) *resolution = NAN;
    if (!f->S || !f->S_err || f->r < 2) return NAN;
    int r = f->r;
    double v = 0, dx = 0, dy = 0;
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            double s = f->S[j * r + i];
            v += f->S_err[j * r + i] * f->S_err[j * r + i];
            if (i + 1 < r) dx += (f->S[j * r + i + 1] - s) * (f->S[j * r + i + 1] - s);
            if (j + 1 < r) dy += (f->S[(j + 1) * r + i] - s) * (f->S[(j + 1) * r + i] - s);
        }
    double n2 = v / ((double)r * r) * noise_scale * noise_scale, pairs = (double)r * (r - 1);
    /* within-sub-pixel variance of a linear truth: d^2 / 12 per axis (uniform over the width);
     * E[d_measured^2] = d^2 + 2 noise^2 per axis, so 4 noise^2 come off the sum of the two */
    double res2 = fmax((dx / pairs + dy / pairs - 4 * n2) / 12, 0);
    if (noise) *noise = sqrt(n2);
    if (resolution) *resolution = sqrt(res2);
    return sqrt(noise_weight * n2 + res2);
}

/* The flags that make a map untrustworthy as it is (model.h). */
#define UNTRUSTED (FIT_UNDERDETERMINED | FIT_NO_SIGNAL | FIT_ILL_CONDITIONED | FIT_UNCONSTRAINED | \
                   FIT_NO_POINTS)

static int admissible(const fit_result_t *f, const fit_recommend_opts_t *o, double scale)
{
    if (!f->S || (f->flags & UNTRUSTED) || !isfinite(f->cv_chi2)) return 0;
    if (f->r == 1) return 1;
    double noise, contrast;
    fit_map_noise_contrast(f, &noise, &contrast);
    return noise * scale <= o->noise_to_contrast * contrast;
}

/* How far the noise model's sigma is from the data's own scatter: sqrt of the smallest reduced
 * chi2 among the fits with a map and at least a quarter of the points as degrees of freedom (the
 * most flexible model that still leaves enough residuals to measure the scatter). The paper's
 * sigma (eq. 5 as printed) is sqrt(G) too large, so its S_err are too; scaled by this they are
 * the map's real noise under either noise model. 1 when no fit qualifies. */
static double noise_scale(const fit_sweep_t *sw)
{
    double best = INFINITY;
    for (int r = sw->r_min; r <= sw->r_max; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        double dof = (double)f->n_used - f->params;
        if (f->S && dof >= 0.25 * (double)f->n_used && f->chi2_red < best) best = f->chi2_red;
    }
    return isfinite(best) && best > 0 ? sqrt(best) : 1;
}

/* The largest r of the sweep whose fit has enough points (r*r + 1 <= N). */
static int largest_determined(const fit_sweep_t *sw)
{
    int r_det = 0;
    for (int r = sw->r_min; r <= sw->r_max; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        if (!(f->flags & (FIT_UNDERDETERMINED | FIT_NO_POINTS))) r_det = r;
    }
    return r_det;
}

/* Step 3 (recommend.h): r_cv against r_cv - 1 and r_cv + 1 by the expected error. */
static int refine(const fit_sweep_t *sw, const fit_recommend_opts_t *o, double scale, int r_cv,
                  double *err_best, int *vetoed)
{
    *vetoed = 0;
    const fit_result_t *f0 = &sw->fits[r_cv - sw->r_min];
    int r_best = r_cv;
    *err_best = fit_map_expected_error(f0, scale, o->noise_weight, NULL, NULL);
    if (o->noise_weight <= 0 || !isfinite(*err_best)) return r_cv;
    for (int r = r_cv - 1; r <= r_cv + 1; r += 2) {
        if (r < 2 || r < sw->r_min || r > sw->r_max) continue;
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        if (!admissible(f, o, scale)) continue;
        if (r > r_cv && !(f->chi2 <= f0->chi2)) continue; /* misaligned with what r_cv resolves */
        /* too coarse: misfits the points beyond their own scatter (the noise model's absolute
         * sigma, hence FIT_POOR_FIT, is off by sqrt(G) under the paper's model), and clearly
         * more than r_cv does (a sharp edge seen at 19 x 19, seed 10: r = 7 misfits 3.08 against
         * r_cv = 8's 2.84 and the scatter's 1.03, and is the better map, 0.036 against 0.057) */
        if (r < r_cv && !(f->chi2_red <= o->coarse_misfit * scale * scale) &&
            !(o->coarse_near > 0 && f->chi2_red <= o->coarse_near * f0->chi2_red)) {
            *vetoed = r;
            continue;
        }
        double e = fit_map_expected_error(f, scale, o->noise_weight, NULL, NULL);
        if (e < *err_best) *err_best = e, r_best = r;
    }
    return r_best;
}

/* Step 4 (recommend.h): r_cv + 1 when r_cv misfits the points by escape_misfit times more than
 * r_cv + 1 does (and than their scatter), r_cv + 1 fits them better, is not noise-dominated
 * (noise at most escape_noise_to_contrast of its contrast) and its expected error is at most
 * escape_error_ratio times r_cv's. The misfit is measured against r_cv + 1's own reduced chi2,
 * not only against the scatter: the scatter is the smallest reduced chi2 of the sweep and carries
 * the finest fits' own bias (paper-like 9 x 9: scatter^2 1.3-1.8 from r = 7, where r = 6 misfits
 * 1.8-1.95 times more and r = 7 is the better map). The error ratio keeps a checkerboard out:
 * a 19 x 19 paper-like scan (seed 9) had r = 9 pass the other tests with noise 11 times r = 8's,
 * expected error 0.29 against 0.042, map error 5.3x. */
static int escape_misfit(const fit_sweep_t *sw, const fit_recommend_opts_t *o, double scale,
                         int r_cv)
{
    if (o->escape_misfit <= 0 || r_cv + 1 > sw->r_max) return 0;
    const fit_result_t *f0 = &sw->fits[r_cv - sw->r_min], *f1 = f0 + 1;
    fit_recommend_opts_t relaxed = *o;
    relaxed.noise_to_contrast = o->escape_noise_to_contrast;
    if (!(f0->chi2_red > o->escape_misfit * fmax(f1->chi2_red, scale * scale)) ||
        !(f1->chi2 <= f0->chi2) || !admissible(f1, &relaxed, scale))
        return 0;
    double e0 = fit_map_expected_error(f0, scale, o->noise_weight, NULL, NULL);
    double e1 = fit_map_expected_error(f1, scale, o->noise_weight, NULL, NULL);
    return !isfinite(e0) || (o->escape_error_ratio > 0 && e1 <= o->escape_error_ratio * e0);
}

double fit_loo_se(const fit_result_t *f)
{
    if (!f->resid || !(f->chi2 > 0) || !isfinite(f->cv_chi2)) return NAN;
    /* resid holds every input point: the used ones and those left out (NaN) */
    size_t n_in = f->n_used + f->n_saturated + f->n_nonfinite, n = 0;
    double k = f->cv_chi2 / f->chi2, sum = 0, sum2 = 0;
    for (size_t i = 0; i < n_in; i++) {
        double e = f->resid[i];
        if (!isfinite(e)) continue;
        double c = k * e * e; /* point i's leave-one-out term, e^2 / (1 - h)^2 with h common */
        sum += c, sum2 += c * c, n++;
    }
    if (n < 2) return NAN;
    double mean = sum / (double)n, var = fmax(sum2 / (double)n - mean * mean, 0);
    /* the standard error of a sum of n terms: sqrt(n) x their standard deviation (n - 1) */
    return sqrt((double)n * var * (double)n / (double)(n - 1));
}

/* Step 2's one-standard-error rule (recommend.h): the smallest admissible r below r_cv whose
 * leave-one-out chi2 is within one_se standard errors of r_cv's and whose reduced chi2 is within
 * coarse_misfit of the data's scatter, or whose grid r_cv's refines (one_se_nested); r_cv when
 * there is none. */
static int one_se(const fit_sweep_t *sw, const fit_recommend_opts_t *o, double scale, int r_cv)
{
    const fit_result_t *f0 = &sw->fits[r_cv - sw->r_min];
    double se = fit_loo_se(f0);
    if (!(o->one_se > 0) || !isfinite(se)) return r_cv;
    for (int r = sw->r_min; r < r_cv; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        if (admissible(f, o, scale) && f->cv_chi2 <= f0->cv_chi2 + o->one_se * se &&
            (f->chi2_red <= o->coarse_misfit * scale * scale ||
             (o->one_se_nested && r > 1 && r_cv % r == 0)))
            return r;
    }
    return r_cv;
}

void fit_recommend(const fit_sweep_t *sw, const fit_recommend_opts_t *opts,
                   fit_recommendation_t *out)
{
    fit_recommend_opts_t o = opts ? *opts : fit_recommend_opts_default();
    memset(out, 0, sizeof *out);
    int r_det = largest_determined(sw);
    out->range_edge = r_det > 0 && (sw->best_aic == r_det || sw->best_bic == r_det);
    double cv_min = INFINITY, scale = noise_scale(sw);
    int r_cv = 0, first_bad = 0;
    for (int r = sw->r_min; r <= sw->r_max; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        if (!admissible(f, &o, scale)) {
            if (f->S && !first_bad) first_bad = r;
            continue;
        }
        if (f->cv_chi2 < cv_min) cv_min = f->cv_chi2, r_cv = r;
    }
    out->noise_scale = scale;
    if (!r_cv) {
        snprintf(out->reason, sizeof out->reason,
                 "no fit of r = %d..%d has a map that can be trusted (see each fit's status)",
                 sw->r_min, sw->r_max);
        return;
    }
    double err;
    int r_se = one_se(sw, &o, scale, r_cv), base = r_se; /* steps 3 and 4 start from r_se */
    out->r = refine(sw, &o, scale, base, &err, &out->vetoed);
    int escaped = out->r == base && escape_misfit(sw, &o, scale, base);
    if (escaped) out->r = base + 1;
    out->r_cv = r_cv;
    out->r_se = r_se;
    out->step = escaped ? 4 : out->r != base ? 3 : 2;
    const fit_result_t *f = &sw->fits[out->r - sw->r_min];
    double noise, contrast, res;
    fit_map_noise_contrast(f, &noise, &contrast);
    /* the map steps 3 and 4 started from, in words */
    char from[200];
    const fit_result_t *fb = &sw->fits[base - sw->r_min], *fc = &sw->fits[r_cv - sw->r_min];
    if (base == r_cv)
        snprintf(from, sizeof from,
                 "r = %d, the best leave-one-out predictor among the maps whose noise is at most "
                 "%g of their contrast", base, o.noise_to_contrast);
    else
        snprintf(from, sizeof from,
                 "r = %d, the smallest r within one standard error of the best leave-one-out "
                 "predictor r = %d and fitting the points within their scatter", base, r_cv);
    int n;
    if (escaped)
        n = snprintf(out->reason, sizeof out->reason,
                     "r = %d: %s, misfits the points (reduced chi2 %.3g against %.3g for r = %d, "
                     "scatter %.3g); r = %d fits them, noise %.2g against contrast %.2g",
                     out->r, from, fb->chi2_red, f->chi2_red, out->r, scale * scale, out->r,
                     noise * scale, contrast);
    else if (out->r == r_cv)
        n = snprintf(out->reason, sizeof out->reason,
                     "r = %d predicts left-out spot positions best (leave-one-out chi2/N %.3g) "
                     "among the maps whose noise is at most %g of their contrast (here %.2g "
                     "against %.2g)",
                     out->r, f->cv_chi2 / (double)f->n_used, o.noise_to_contrast, noise * scale,
                     contrast);
    else if (out->r == base) {
        n = snprintf(out->reason, sizeof out->reason,
                     "r = %d is the smallest r whose leave-one-out chi2/N (%.3g) is within one "
                     "standard error (%.2g) of the best predictor's, r = %d (%.3g), and whose ",
                     out->r, f->cv_chi2 / (double)f->n_used,
                     fit_loo_se(fc) / (double)fc->n_used, r_cv, fc->cv_chi2 / (double)fc->n_used);
        size_t at = n > 0 && (size_t)n < sizeof out->reason ? (size_t)n : 0;
        if (at && f->chi2_red <= o.coarse_misfit * scale * scale)
            n += snprintf(out->reason + at, sizeof out->reason - at,
                          "reduced chi2 (%.3g) is within %gx the data's scatter (%.3g)",
                          f->chi2_red, o.coarse_misfit, scale * scale);
        else if (at) /* step 2's guard waived: one_se_nested */
            n += snprintf(out->reason + at, sizeof out->reason - at,
                          "grid r = %d refines: the same map with fewer parameters", r_cv);
    } else {
        fit_map_expected_error(f, scale, o.noise_weight, &noise, &res);
        n = snprintf(out->reason, sizeof out->reason,
                     "r = %d has the smallest expected map error (noise %.2g, sub-pixel "
                     "resolution %.2g) of %s, and its neighbours",
                     out->r, noise, res, from);
    }
    if (first_bad && n > 0 && (size_t)n < sizeof out->reason)
        snprintf(out->reason + n, sizeof out->reason - (size_t)n,
                 "; r = %d is the first whose map is noise-dominated or flagged", first_bad);
}
