/* test_recommend.c: the recommended r (fit/recommend.h) and the leave-one-out prediction chi2 it
 * rests on, against independent values: cv_chi2 of the reference scan recomputed by brute force
 * (the fit refitted without each point in turn, the left-out point predicted from box integrals
 * of fit/box.c, not the design matrix, and sigma from eq. 5 written out here); range_edge against
 * the argmin of the published AIC / BIC of tests/data/paperlike_scan.json; the admissibility rule
 * on maps built by hand (a map whose noise exceeds a quarter of its contrast is never recommended,
 * r = 1 always may be, flagged fits never); the expected map error of step 3 against the analytic
 * within-sub-pixel variance of a linear truth, step 3 on a tilt built by hand, and step 4's
 * misfit ratio and expected-error bound on a sweep built by hand; the standard error of the
 * leave-one-out chi2 by hand, and step 2's one-standard-error rule on a sweep built by hand. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/airy.h"
#include "fit/box.h"
#include "fit/pipeline.h"
#include "fit/recommend.h"
#include "refdata.h"

/* sigma of eq. 5 as the paper prints it, over sqrt(frames) (eq. 4): the "paper" noise model */
static double paper_sigma(const fit_scan_t *s, double signal)
{
    double d = signal - s->bias_dn, rg = s->read_noise_e / s->gain_e_per_dn;
    return sqrt((d > 0 ? d : 0) + rg * rg) / sqrt((double)s->frames);
}

/* The model at (x, y) of an r x r fit: I0 sum S_ij box_ij, boxes by fit_box_integral. */
static double predict(const fit_scan_t *s, const fit_result_t *f, double x, double y)
{
    int r = f->r;
    double h = s->pitch_um / r, sum = 0;
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            fit_rect_t b = {i * h, (i + 1) * h, j * h, (j + 1) * h};
            double v, eb;
            CHECK(fit_box_integral(s->spot_radius_um, &b, x, y, 1e-12, &v, &eb, NULL) == 0);
            sum += f->S[j * r + i] * v;
        }
    return f->I0 * sum;
}

/* PRESS by its definition: each point predicted by the fit to all the others. */
static double brute_force_loo(const fit_scan_t *s, int r)
{
    size_t n = s->n;
    double *x = malloc(sizeof(double) * 3 * n), *y = x + n, *d = y + n, press = 0;
    fit_options_t o = fit_options_default(); /* paper noise, linear */
    for (size_t k = 0; k < n; k++) {
        size_t q = 0;
        for (size_t i = 0; i < n; i++)
            if (i != k) x[q] = s->x_um[i], y[q] = s->y_um[i], d[q] = s->signal_dn[i], q++;
        fit_scan_t less = *s;
        less.n = n - 1, less.x_um = x, less.y_um = y, less.signal_dn = d;
        fit_result_t f;
        CHECK(fit_map(&less, r, &o, &f, NULL) == 0 && f.S);
        if (f.S) {
            double e = s->signal_dn[k] - s->bias_dn - predict(s, &f, s->x_um[k], s->y_um[k]);
            double sg = paper_sigma(s, s->signal_dn[k]);
            press += e * e / (sg * sg);
        }
        fit_result_free(&f);
    }
    free(x);
    return press;
}

static void test_loo(const ref_scan_t *ref)
{
    fit_options_t o = fit_options_default();
    for (int r = 2; r <= 4; r += 2) {
        fit_result_t f;
        CHECK(fit_map(&ref->scan, r, &o, &f, NULL) == 0);
        /* design matrix (1e-12) against box integrals (1e-12): agreement to ~1e-9 relative */
        CHECK_NEAR(f.cv_chi2, brute_force_loo(&ref->scan, r), 1e-7, 0);
        CHECK(f.cv_chi2 >= f.chi2); /* a point predicted from the others fits no better */
        fit_result_free(&f);
    }
}

/* range_edge: AIC or BIC at the largest r the sweep determines, read from the published fits. */
static void test_range_edge(const ref_scan_t *ref)
{
    int aic_r = 0, bic_r = 0;
    double aic = INFINITY, bic = INFINITY;
    size_t i;
    json_t *o;
    json_array_foreach(json_object_get(ref->root, "fits"), i, o)
    {
        const char *noise = json_string_value(json_object_get(o, "noise"));
        if (!noise || strcmp(noise, "paper")) continue;
        int r = (int)json_integer_value(json_object_get(o, "r"));
        if (ref_num(o, "aic") < aic) aic = ref_num(o, "aic"), aic_r = r;
        if (ref_num(o, "bic") < bic) bic = ref_num(o, "bic"), bic_r = r;
    }
    CHECK(aic_r > 0 && bic_r > 0);
    for (int r_max = 6; r_max <= 8; r_max++) {
        fit_pipeline_opts_t po = fit_pipeline_opts_default();
        po.r_max = r_max;
        fit_pipeline_t pl;
        CHECK(fit_pipeline_run(&ref->scan, &po, NULL, &pl, NULL) == 0);
        /* published argmins restricted to 1..r_max: at r_max whenever the global one is beyond */
        int edge = (aic_r >= r_max) || (bic_r >= r_max);
        CHECK(pl.sweep.range_edge == edge);
        /* the recommendation is one of the swept maps, and says why in a sentence */
        CHECK(pl.sweep.recommended_r >= 1 && pl.sweep.recommended_r <= r_max);
        CHECK(strlen(pl.sweep.recommended_reason) > 20);
        fit_pipeline_free(&pl);
    }
}

/* Admissibility on a sweep built by hand: fits at r = 1, 2, 3 with chosen S, S_err, cv_chi2. */
static void test_rule(void)
{
    fit_result_t f[3];
    double S2[4] = {0.9, 1.1, 1.1, 0.9}, E2[4], S3[9], E3[9];
    memset(f, 0, sizeof f);
    for (int j = 0; j < 9; j++) S3[j] = j % 2 ? 1.2 : 0.8, E3[j] = 0.01;
    double S1 = 1, E1 = 0;
    for (int k = 0; k < 3; k++) {
        f[k].r = k + 1;
        f[k].params = (k + 1) * (k + 1) + 1;
        f[k].n_used = 100;
        f[k].chi2_red = 1;
    }
    f[0].S = &S1, f[0].S_err = &E1, f[0].cv_chi2 = 500;
    f[1].S = S2, f[1].S_err = E2, f[1].cv_chi2 = 200;
    f[2].S = S3, f[2].S_err = E3, f[2].cv_chi2 = 300;
    fit_sweep_t sw = {.r_min = 1, .r_max = 3, .fits = f};
    fit_recommendation_t rec;
    /* r = 2: contrast 0.1; noise 0.02 is a fifth of it: admissible, and best CV */
    for (int j = 0; j < 4; j++) E2[j] = 0.02;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 2);
    /* noise 0.03 is above a quarter of the contrast: r = 2 is out, r = 3 (contrast 0.2, noise
     * 0.01) has the next best CV */
    for (int j = 0; j < 4; j++) E2[j] = 0.03;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 3);
    /* a flag that makes r = 3 untrustworthy leaves r = 1, always admissible */
    f[2].flags = FIT_ILL_CONDITIONED;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 1);
    /* the paper's sigma is sqrt(G) too large: S_err scale with it, but so does sqrt(chi2_red),
     * which rescales them; with chi2_red = 1/4 the noise counts half: r = 2 is back */
    f[2].flags = 0;
    for (int k = 0; k < 3; k++) f[k].chi2_red = 0.25;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 2);
    /* nothing with a map: no recommendation, and a reason */
    f[0].S = f[1].S = f[2].S = NULL;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 0 && strstr(rec.reason, "no fit"));
}

/* The expected error's resolution part against the analytic within-sub-pixel variance of a
 * linear truth 1 + g (x/p - 1/2): a sub-pixel of width p/r sees it vary by g/r, uniformly, so
 * its variance is (g/r)^2 / 12; a noiseless r x r map of its sub-pixel means has exactly that. */
static void test_expected_error(void)
{
    const double g = 0.2;
    for (int r = 2; r <= 6; r++) {
        double S[36], E[36] = {0};
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) S[j * r + i] = 1 + g * ((i + 0.5) / r - 0.5);
        fit_result_t f = {.r = r, .S = S, .S_err = E};
        double noise, res;
        double e = fit_map_expected_error(&f, 1, 2, &noise, &res);
        /* dy = 0: the mean of dx^2 + dy^2 is (g/r)^2, and the resolution error is its 1/12 */
        CHECK_NEAR(res, sqrt((g / r) * (g / r) / 12 / 1), 1e-12, 0);
        CHECK(noise == 0);
        CHECK_NEAR(e, res, 1e-15, 0);
        /* noise: rms 0.01 scaled by 2 counts 0.02, twice in the sum of squares */
        for (int k = 0; k < r * r; k++) E[k] = 0.01;
        e = fit_map_expected_error(&f, 2, 2, &noise, &res);
        CHECK_NEAR(noise, 0.02, 1e-12, 0);
        /* at r = 5 the two cancel: the square root of a rounding error, hence the absolute 1e-9 */
        CHECK_NEAR(res, sqrt(fmax(((g / r) * (g / r) - 4 * 0.02 * 0.02) / 12, 0)), 1e-12, 1e-9);
        CHECK_NEAR(e, sqrt(2 * 0.02 * 0.02 + res * res), 1e-12, 0);
    }
    double one = 1, zero = 0;
    fit_result_t f1 = {.r = 1, .S = &one, .S_err = &zero};
    CHECK(isnan(fit_map_expected_error(&f1, 1, 2, NULL, NULL)));
}

/* Step 3 on a sweep built by hand: a linear tilt seen at r = 2, 3, 4 without noise. r = 2
 * predicts left-out points best, but r = 3 fits the points as well and resolves the tilt better
 * (resolution error g/(3 sqrt 12) against g/(2 sqrt 12)); r = 4 is not r_cv's neighbour. With
 * r = 3 fitting worse than r = 2 (misaligned), r = 2 stays. */
static void test_refine(void)
{
    const double g = 0.2;
    fit_result_t f[4];
    double S[4][16], E[4][16], one = 1, zero = 0;
    memset(f, 0, sizeof f);
    memset(E, 0, sizeof E);
    for (int k = 0; k < 4; k++) {
        int r = k + 1;
        f[k].r = r;
        f[k].params = r * r + 1;
        f[k].n_used = 100;
        f[k].chi2 = 100, f[k].chi2_red = 100.0 / (100 - f[k].params);
        f[k].cv_chi2 = k == 1 ? 200 : 300;
        f[k].S = S[k], f[k].S_err = E[k];
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) S[k][j * r + i] = 1 + g * ((i + 0.5) / r - 0.5);
    }
    f[0].S = &one, f[0].S_err = &zero;
    fit_sweep_t sw = {.r_min = 1, .r_max = 4, .fits = f};
    fit_recommendation_t rec;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 3);
    CHECK(strstr(rec.reason, "expected map error") != NULL);
    CHECK(rec.r_cv == 2 && rec.step == 3 && rec.vetoed == 0);
    f[2].chi2 = 150;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 2);
    CHECK(rec.r_cv == 2 && rec.step == 2);
    /* r_cv = 3 (the tilt resolved best) with r = 2 misfitting: its reduced chi2 10 against the
     * scatter 1.03 (the smallest reduced chi2, r = 1's 100 / 98 at N/4 dof) is over 1.5 times:
     * vetoed, whatever its expected error */
    f[2].chi2 = 100, f[1].cv_chi2 = 400, f[2].cv_chi2 = 200;
    f[1].chi2_red = 10, f[1].chi2 = 950;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r_cv == 3 && rec.vetoed == 2 && rec.r != 2);
    CHECK(fabs(rec.noise_scale - sqrt(100.0 / 98)) < 1e-12);
    /* unless r_cv misfits about as much: r = 2's 10 within 1.15 times r = 3's 9 */
    f[2].chi2_red = 9, f[2].chi2 = 810;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r_cv == 3 && rec.vetoed == 0);
    f[2].chi2_red = 100.0 / 90, f[2].chi2 = 100;
    f[1].chi2_red = 100.0 / 95, f[1].chi2 = 100, f[1].cv_chi2 = 200, f[2].cv_chi2 = 300;
    /* without step 3 (noise_weight 0) the leave-one-out pick stands */
    f[2].chi2 = 100;
    fit_recommend_opts_t o = fit_recommend_opts_default();
    o.noise_weight = 0;
    o.escape_misfit = 0;
    fit_recommend(&sw, &o, &rec);
    CHECK(rec.r == 2);
}

/* Step 4 on a sweep built by hand (tilt g = 0.2, 100 points, no noise but r = 3's): r = 2 is
 * r_cv and step 3 keeps it (r = 3's noise, 0.4 of its contrast g sqrt(2/27), is over the 0.25
 * bound); r = 2 misfits the points (reduced chi2 4 against r = 3's 1, the scatter) by more than
 * 1.7 times, so step 4 moves to r = 3. Its expected error sqrt(2 n^2 + (g^2/9 - 4 n^2)/12) is
 * 1.18 times r = 2's g/(2 sqrt 12): with escape_error_ratio 1.1 it stays at r = 2, and with r = 2
 * misfitting only 1.5 times r = 3 it stays too. */
static void test_escape(void)
{
    const double g = 0.2, n3 = 0.4 * g * sqrt(2.0 / 27);
    fit_result_t f[3];
    double S2[4], S3[9], E2[4] = {0}, E3[9], one = 1, zero = 0;
    memset(f, 0, sizeof f);
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) S2[j * 2 + i] = 1 + g * ((i + 0.5) / 2 - 0.5);
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) S3[j * 3 + i] = 1 + g * ((i + 0.5) / 3 - 0.5), E3[j * 3 + i] = n3;
    const double red[3] = {10, 4, 1}, cv[3] = {1000, 300, 400};
    for (int k = 0; k < 3; k++) {
        f[k].r = k + 1;
        f[k].params = (k + 1) * (k + 1) + 1;
        f[k].n_used = 100;
        f[k].chi2_red = red[k];
        f[k].chi2 = red[k] * (100 - f[k].params);
        f[k].cv_chi2 = cv[k];
    }
    f[0].S = &one, f[0].S_err = &zero;
    f[1].S = S2, f[1].S_err = E2;
    f[2].S = S3, f[2].S_err = E3;
    double e2 = fit_map_expected_error(&f[1], 1, 2, NULL, NULL);
    double e3 = fit_map_expected_error(&f[2], 1, 2, NULL, NULL);
    CHECK(fabs(e2 - g / 2 / sqrt(12.0)) < 1e-12);
    CHECK(fabs(e3 - sqrt(2 * n3 * n3 + (g * g / 9 - 4 * n3 * n3) / 12)) < 1e-12);
    fit_sweep_t sw = {.r_min = 1, .r_max = 3, .fits = f};
    fit_recommendation_t rec;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 3);
    CHECK(strstr(rec.reason, "misfits the points") != NULL);
    CHECK(rec.r_cv == 2 && rec.step == 4);
    fit_recommend_opts_t o = fit_recommend_opts_default();
    o.escape_error_ratio = 1.1; /* below e3 / e2 = 1.18: a noisier r + 1 than allowed */
    fit_recommend(&sw, &o, &rec);
    CHECK(rec.r == 2);
    f[1].chi2_red = 1.5, f[1].chi2 = 1.5 * 95; /* misfits 1.5 times r = 3 only: below 1.7 */
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 2);
}

/* fit_loo_se by hand: residuals 1, -1, 2, 0 and one point left out (NaN), chi2 6, leave-one-out
 * chi2 12: the terms are e^2 x 12 / 6 = 2, 2, 8, 0, mean 3, sample variance (1 + 1 + 25 + 9) / 3
 * = 12, and the sum's standard error sqrt(4 x 12). No residuals: NaN. */
static void test_loo_se(void)
{
    double e[5] = {1, -1, 2, NAN, 0};
    fit_result_t f = {.r = 2, .n_used = 4, .n_nonfinite = 1, .chi2 = 6, .cv_chi2 = 12, .resid = e};
    CHECK_NEAR(fit_loo_se(&f), sqrt(48.0), 1e-12, 0);
    f.resid = NULL;
    CHECK(isnan(fit_loo_se(&f)));
}

/* Step 2's one-standard-error rule on a sweep built by hand: a dead quadrant, exact at r = 2 and
 * at r = 4 (the same map refined), misaligned at r = 3, 100 points. r = 4 predicts left-out
 * points best (leave-one-out chi2 250: residuals 0.5 and 1.5 on half the points each, chi2 125,
 * terms 0.5 and 4.5, standard error sqrt(100 x 4 x 100 / 99) = 20.1); r = 2's 260 is within one
 * standard error and its reduced chi2 150 / 95 within 1.5 times the scatter (r = 4's 125 / 83):
 * r = 2. At 280, or with the rule off, r = 4. Misfitting the points (reduced chi2 2.5, above 1.5
 * x 1.506), r = 2 is still taken, its grid being one of r = 4's (one_se_nested; not with it
 * off); r = 3, whose grid is not, is not taken when it misfits so (leave-one-out chi2 262 and
 * reduced chi2 2.4), and is when it fits within 1.5 x the scatter (2.2). */
static void test_one_se(void)
{
    fit_result_t f[4];
    double S[4][16], E[4][16], e4[100];
    memset(f, 0, sizeof f);
    for (int k = 0; k < 100; k++) e4[k] = k % 2 ? 0.5 : -1.5;
    const double chi2[4] = {1000, 150, 400, 125}, cv[4] = {1100, 260, 500, 250};
    for (int k = 0; k < 4; k++) {
        int r = k + 1;
        f[k].r = r;
        f[k].params = r * r + 1;
        f[k].n_used = 100;
        f[k].chi2 = chi2[k], f[k].chi2_red = chi2[k] / (100 - f[k].params);
        f[k].cv_chi2 = cv[k];
        f[k].S = S[k], f[k].S_err = E[k];
        /* dead below-left quadrant (r = 3: one ninth, misaligned) */
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) {
                S[k][j * r + i] = 2 * i < r - (r % 2) && 2 * j < r - (r % 2) ? 0 : 1;
                E[k][j * r + i] = 1e-3;
            }
    }
    S[0][0] = 1;
    f[3].resid = e4;
    CHECK_NEAR(fit_loo_se(&f[3]), sqrt(100 * 4 * 100 / 99.0), 1e-12, 0);
    fit_sweep_t sw = {.r_min = 1, .r_max = 4, .fits = f};
    fit_recommendation_t rec;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 2 && rec.r_cv == 4 && rec.r_se == 2 && rec.step == 2);
    CHECK(strstr(rec.reason, "one standard error") != NULL);
    f[1].cv_chi2 = 280;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 4 && rec.r_se == 4);
    fit_recommend_opts_t o = fit_recommend_opts_default();
    f[1].cv_chi2 = 260, f[1].chi2_red = 2.5, f[1].chi2 = 2.5 * 95;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r == 2 && rec.r_se == 2 && rec.step == 2);
    CHECK(strstr(rec.reason, "whose grid r = 4 refines") != NULL);
    o.one_se_nested = 0;
    fit_recommend(&sw, &o, &rec);
    CHECK(rec.r == 4 && rec.r_se == 4);
    o.one_se_nested = 1;
    f[1].cv_chi2 = 280;                              /* r = 2 beyond one standard error */
    f[2].cv_chi2 = 262, f[2].chi2 = 2.4 * 90, f[2].chi2_red = 2.4; /* r = 3: 100 - 10 dof */
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r_se == 4);
    f[2].chi2 = 2.2 * 90, f[2].chi2_red = 2.2;
    fit_recommend(&sw, NULL, &rec);
    CHECK(rec.r_se == 3);
    f[1].cv_chi2 = 260, f[1].chi2_red = 150 / 95.0, f[1].chi2 = 150;
    f[2].cv_chi2 = 500, f[2].chi2 = 400, f[2].chi2_red = 400 / 90.0;
    o.one_se = 0;
    fit_recommend(&sw, &o, &rec);
    CHECK(rec.r == 4 && rec.r_se == 4);
}

int main(void)
{
    ref_scan_t ref;
    if (ref_scan_load("paperlike_scan.json", &ref)) return 1;
    test_loo(&ref);
    test_range_edge(&ref);
    test_rule();
    test_expected_error();
    test_refine();
    test_escape();
    test_loo_se();
    test_one_se();
    ref_scan_free(&ref);
    CHECK_DONE();
}
