/* test_pipeline.c: the fit pipeline (fit/pipeline.h) against independent values: the published
 * fits of tests/data/paperlike_scan.json (chi2 of every r for both noise models, the best r as the
 * argmin of the published AIC / BIC, the F-test's chi2 of both hypotheses, F by eq. 6 and the
 * nesting of the models), the paper's own F-test numbers, the interpolation's exactness at the
 * sub-pixel centres; the watch (progress monotone and complete, a stop before any step keeps
 * nothing), bad options, parts that fail without failing the run; and fit/'s GSL error policy,
 * checked first, in fresh processes that never called gsl_set_error_handler_off(). */
#include <errno.h>
#include <gsl/gsl_errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "fit/box.h"
#include "fit/pipeline.h"
#include "refdata.h"

#define EDGES_TLB (FIT_EDGE_TOP | FIT_EDGE_LEFT | FIT_EDGE_BOTTOM) /* the paper's edge model */

/* ---- GSL errors never abort: a box integral asked for more than doubles can give ---- */

/* The published box of tests/data/airy_box.json: the centred sub-pixel of a 7 x 7 split of the
 * 6 um pixel under the R = 1.34 um spot at (3, 3). */
static int centred_box(double *R, fit_rect_t *b, double *xk, double *yk, double *want)
{
    json_error_t je;
    json_t *ref = json_load_file("airy_box.json", 0, &je), *o;
    size_t i;
    int found = 0;
    json_array_foreach(json_object_get(ref, "boxes"), i, o)
    {
        if (found || ref_num(o, "R") != 1.34 || ref_num(o, "xk") != 3.0 || ref_num(o, "yk") != 3.0)
            continue;
        *b = (fit_rect_t){ref_num(o, "x0"), ref_num(o, "x1"), ref_num(o, "y0"), ref_num(o, "y1")};
        if (!(b->x0 < 3 && b->x1 > 3 && b->y0 < 3 && b->y1 > 3)) continue;
        *R = 1.34, *xk = 3, *yk = 3, *want = ref_num(o, "value");
        found = 1;
    }
    json_decref(ref);
    return found ? 0 : -1;
}

/* Runs fn in a child process (fresh as far as fit/ is concerned: the parent has not called fit/
 * yet) and checks that it exited 0, not by a signal (GSL's default handler calls abort()). */
static void in_child(int (*fn)(void))
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) _exit(fn());
    int st = 0;
    CHECK(pid > 0 && waitpid(pid, &st, 0) == pid);
    CHECK(!WIFSIGNALED(st));
    CHECK(WIFEXITED(st) && WEXITSTATUS(st) == 0);
}

/* 1e-15 relative is below what GSL's Gauss-Kronrod can certify in doubles: QAG reports a
 * roundoff error (GSL_EROUND) through the handler; fit_box_integral says -ERANGE and still gives
 * the honest value with a bound that covers the published one. */
static int box_beyond_doubles(void)
{
    double R = 0, xk = 0, yk = 0, want = 0, v = NAN, bound = NAN;
    fit_rect_t b = {0, 0, 0, 0};
    err_t err = {{0}};
    int found = centred_box(&R, &b, &xk, &yk, &want) == 0;
    CHECK(found);
    if (!found) return check_failures;
    CHECK(fit_box_integral(R, &b, xk, yk, 1e-15, &v, &bound, &err) == -ERANGE);
    CHECK(strstr(err.msg, "tolerance") != NULL);
    CHECK_NEAR(v, want, 1e-12, 0);
    CHECK(fabs(v - want) <= bound + 1e-16 * want);
    return check_failures;
}

/* GSL's default handler in place (nothing set it): the error comes back as a return code. */
static int gsl_default_handler(void)
{
    gsl_error_handler_t *before = gsl_set_error_handler(NULL);
    CHECK(before == NULL); /* GSL's default: print and abort */
    box_beyond_doubles();
    gsl_error_handler_t *after = gsl_set_error_handler(NULL);
    CHECK(after != NULL); /* fit/ turned the abort off */
    gsl_set_error_handler(after);
    return check_failures ? 1 : 0;
}

static int gsl_calls;
static void counting_handler(const char *reason, const char *file, int line, int gsl_errno)
{
    (void)reason, (void)file, (void)line, (void)gsl_errno;
    gsl_calls++;
}

/* A handler of the program's own, installed before the first fit/ call, is kept and called:
 * which also shows that the call above really raised GSL errors. */
static int gsl_own_handler(void)
{
    gsl_set_error_handler(counting_handler);
    box_beyond_doubles();
    CHECK(gsl_calls > 0);
    gsl_error_handler_t *kept = gsl_set_error_handler(counting_handler);
    CHECK(kept == counting_handler);
    return check_failures ? 1 : 0;
}

/* ---- the pipeline on the reference scan ---- */

/* What the watch saw. */
struct seen {
    int calls, bad, last_done, total;
    fit_step_t steps[64];
    int stop_at; /* stop before the step of this index; -1: never */
    int stop_asks;
};

static void on_progress(int done, int total, const fit_step_t *step, void *params)
{
    struct seen *s = params;
    /* done counts up by one, the total never changes, the step is the one just done */
    if (done != s->last_done + 1 || (s->total && total != s->total) || done > total ||
        step->index != done - 1 || step->total != total)
        s->bad++;
    s->last_done = done;
    s->total = total;
    if (s->calls < 64) s->steps[s->calls] = *step;
    s->calls++;
}

static int on_stop(const fit_step_t *next, void *params)
{
    struct seen *s = params;
    if (next->index != s->calls) s->bad++; /* asked before the step, after the previous one */
    s->stop_asks++;
    return next->index == s->stop_at;
}

/* The published fits of one noise model: chi2 etc. by r, and the r = 7 F-test. */
struct published {
    double chi2[9], aic[9], bic[9];
    int params[9], best_aic, best_bic;
    double chi2_h0, F, p_value;
    int params_h0;
};

static void published(const ref_scan_t *rs, fit_noise_t noise, struct published *p)
{
    memset(p, 0, sizeof *p);
    double amin = INFINITY, bmin = INFINITY;
    size_t i;
    json_t *f;
    json_array_foreach(json_object_get(rs->root, "fits"), i, f)
    {
        if (strcmp(json_string_value(json_object_get(f, "noise")), fit_noise_name(noise))) continue;
        int r = (int)json_integer_value(json_object_get(f, "r"));
        if (r < 1 || r > 8) continue;
        p->chi2[r] = ref_num(f, "chi2");
        p->aic[r] = ref_num(f, "aic");
        p->bic[r] = ref_num(f, "bic");
        p->params[r] = (int)json_integer_value(json_object_get(f, "params"));
        if (p->aic[r] < amin) amin = p->aic[r], p->best_aic = r;
        if (p->bic[r] < bmin) bmin = p->bic[r], p->best_bic = r;
        json_t *ft = json_object_get(f, "ftest_H0_top_left_bottom_edges");
        if (ft && r == 7) {
            p->chi2_h0 = ref_num(ft, "chi2_H0");
            p->F = ref_num(ft, "F");
            p->p_value = ref_num(ft, "p_value");
            p->params_h0 = (int)json_integer_value(json_object_get(ft, "params_H0"));
        }
    }
}

/* The F-test of a run against the published r = 7 test, eq. 6 and the nesting of the models. */
static void check_ftest(const fit_ftest_t *t, const struct published *p, size_t n)
{
    CHECK(t->r == 7 && t->edges == EDGES_TLB && t->n == n);
    CHECK(t->params_h1 == p->params[7] && t->params_h0 == p->params_h0);
    CHECK_NEAR(t->chi2_h1, p->chi2[7], 1e-8, 0);
    CHECK_NEAR(t->chi2_h0, p->chi2_h0, 1e-8, 0);
    /* nested: H1 (r = 7) contains H0 (edges free, one S0), which contains the uniform map */
    CHECK(t->chi2_h1 <= t->chi2_h0 && t->chi2_h0 <= p->chi2[1]);
    /* eq. 6 from the two chi2 and the published parameter counts */
    double d1 = p->params[7] - p->params_h0, d2 = (double)n - p->params[7];
    CHECK_NEAR(t->F, ((t->chi2_h0 - t->chi2_h1) / t->chi2_h1) * (d2 / d1), 1e-12, 0);
    CHECK_NEAR(t->F, p->F, 1e-7, 0);
    CHECK_NEAR(t->p_value, p->p_value, 1e-6, 0);
}

static void test_reference(const ref_scan_t *rs)
{
    for (int model = 0; model < 2; model++) {
        fit_noise_t noise = model ? FIT_NOISE_SHOT_READ : FIT_NOISE_PAPER;
        struct published p;
        published(rs, noise, &p);
        CHECK(p.best_aic >= 1 && p.best_bic >= 1 && p.params_h0 > 0);
        fit_pipeline_opts_t o = fit_pipeline_opts_default();
        o.fit.noise = noise;
        o.ftest_edges = EDGES_TLB;
        o.wiener = 1;
        o.interp_n = 8; /* an 8 x 8 grid: the sub-pixel centres of the best-AIC (r = 8) map */
        struct seen s = {.stop_at = -1};
        fit_watch_t w = {.progress = on_progress, .stop = on_stop, .params = &s};
        fit_pipeline_t pl;
        err_t err = {{0}};
        CHECK(fit_pipeline_run(&rs->scan, &o, &w, &pl, &err) == 0);
        const fit_sweep_t *sw = &pl.sweep;
        CHECK(sw->fits && sw->r_min == 1 && sw->r_max == 8);
        for (int r = 1; sw->fits && r <= 8; r++) {
            const fit_result_t *f = &sw->fits[r - 1];
            CHECK(f->r == r && f->params == p.params[r] && f->n_used == rs->scan.n);
            CHECK_NEAR(f->chi2, p.chi2[r], 1e-8, 0);
            CHECK_NEAR(f->aic, p.aic[r], 0, 1e-6);
            CHECK_NEAR(f->bic, p.bic[r], 0, 1e-6);
        }
        CHECK(sw->best_aic == p.best_aic && sw->best_bic == p.best_bic);
        /* the F-test reused the sweep's r = 7 fit: the published H1 */
        CHECK(pl.ftest_part.asked && pl.ftest_part.rc == 0);
        check_ftest(&pl.ftest, &p, rs->scan.n);
        /* Wiener on the reference raster: 9 x 9 points, 0.6 um apart; mean 1 */
        CHECK(pl.wiener_part.asked && pl.wiener_part.rc == 0);
        CHECK(pl.wiener.nx == 9 && pl.wiener.ny == 9 && pl.wiener.S);
        CHECK_NEAR(pl.wiener.step_x_um, 0.6, 1e-9, 0);
        double mean = 0;
        for (int c = 0; pl.wiener.S && c < 81; c++) mean += pl.wiener.S[c] / 81;
        CHECK_NEAR(mean, 1.0, 1e-12, 0);
        /* the interpolant passes through its samples: at the centres it is the map itself */
        CHECK(pl.interp_part.asked && pl.interp_part.rc == 0);
        CHECK(pl.interp_r == p.best_aic && pl.interp_n == 8 && pl.interp);
        const double *S = sw->fits ? sw->fits[p.best_aic - 1].S : NULL;
        for (int c = 0; pl.interp && S && p.best_aic == 8 && c < 64; c++)
            CHECK_NEAR(pl.interp[c], S[c], 0, 1e-12);
        /* the watch: every step once, in order, the total known from the start */
        CHECK(s.bad == 0 && s.calls == 11 && s.last_done == 11 && s.total == 11);
        CHECK(s.stop_asks == 11);
        for (int k = 0; k < 8; k++)
            CHECK(s.steps[k].kind == FIT_STEP_SWEEP && s.steps[k].r == k + 1);
        CHECK(s.steps[8].kind == FIT_STEP_FTEST && s.steps[8].r == 7);
        CHECK(s.steps[9].kind == FIT_STEP_WIENER);
        CHECK(s.steps[10].kind == FIT_STEP_INTERP && s.steps[10].r == p.best_aic);
        CHECK(strcmp(fit_step_name(s.steps[10].kind), "interp") == 0);
        /* the parts' times are parts of the whole */
        CHECK(pl.sweep_ms > 0 && pl.ftest_part.ms >= 0 && pl.wiener_part.ms >= 0);
        CHECK(pl.total_ms >=
              pl.sweep_ms + pl.ftest_part.ms + pl.wiener_part.ms + pl.interp_part.ms);
        fit_pipeline_free(&pl);
        CHECK(pl.sweep.fits == NULL && pl.interp == NULL && pl.wiener.S == NULL);
    }
}

/* The F-test fits its own H1 when the sweep does not have the linear fit at ftest_r: outside the
 * swept range, or a sweep by LM. Same published values. */
static void test_ftest_own_h1(const ref_scan_t *rs)
{
    struct published p;
    published(rs, FIT_NOISE_PAPER, &p);
    for (int variant = 0; variant < 2; variant++) {
        fit_pipeline_opts_t o = fit_pipeline_opts_default();
        o.ftest_edges = EDGES_TLB;
        if (variant == 0) o.r_max = 4; /* r = 7 not swept */
        else o.fit.method = FIT_LM;    /* swept, but by LM */
        fit_pipeline_t pl;
        err_t err = {{0}};
        CHECK(fit_pipeline_run(&rs->scan, &o, NULL, &pl, &err) == 0);
        CHECK(pl.ftest_part.asked && pl.ftest_part.rc == 0);
        check_ftest(&pl.ftest, &p, rs->scan.n);
        CHECK(!pl.wiener_part.asked && !pl.interp_part.asked && !pl.interp);
        fit_pipeline_free(&pl);
    }
}

/* The paper's own numbers (numerics note 7): F = 2.490 with (29, 31) degrees of freedom has
 * p = 0.00711 (three figures); and F = 1 with equal degrees of freedom has p = 1/2 exactly,
 * since 1/F has the same distribution as F. */
static void test_p_value(void)
{
    CHECK_NEAR(fit_ftest_p_value(2.490, 29, 31), 0.00711, 0, 0.000005);
    CHECK_NEAR(fit_ftest_p_value(1.0, 7, 7), 0.5, 1e-12, 0);
    CHECK_NEAR(fit_ftest_p_value(1.0, 29, 29), 0.5, 1e-12, 0);
    CHECK(isnan(fit_ftest_p_value(NAN, 29, 31)));
    CHECK(isnan(fit_ftest_p_value(2.0, 0, 31)) && isnan(fit_ftest_p_value(2.0, 29, 0)));
}

/* A stop before any one of the steps: -ECANCELED, the steps before it reported, nothing kept. */
static void test_stop(const ref_scan_t *rs)
{
    fit_pipeline_opts_t o = fit_pipeline_opts_default();
    o.r_max = 4;
    o.ftest_edges = EDGES_TLB;
    o.ftest_r = 3;
    o.wiener = 1;
    o.interp_n = 4;
    const int total = 4 + 3;
    for (int k = 0; k < total; k++) {
        struct seen s = {.stop_at = k};
        fit_watch_t w = {.progress = on_progress, .stop = on_stop, .params = &s};
        fit_pipeline_t pl;
        err_t err = {{0}};
        CHECK(fit_pipeline_run(&rs->scan, &o, &w, &pl, &err) == -ECANCELED);
        CHECK(strstr(err.msg, "stopped before") != NULL);
        CHECK(s.bad == 0 && s.calls == k && s.stop_asks == k + 1);
        CHECK(pl.sweep.fits == NULL && pl.interp == NULL && pl.wiener.S == NULL);
        CHECK(!pl.ftest_part.asked && !pl.wiener_part.asked && !pl.interp_part.asked);
        fit_pipeline_free(&pl); /* allowed, and a no-op */
    }
    /* no stop: all steps */
    struct seen s = {.stop_at = -1};
    fit_watch_t w = {.progress = on_progress, .stop = on_stop, .params = &s};
    fit_pipeline_t pl;
    CHECK(fit_pipeline_run(&rs->scan, &o, &w, &pl, NULL) == 0);
    CHECK(s.bad == 0 && s.calls == total && s.total == total);
    fit_pipeline_free(&pl);
}

/* Bad options are refused before any step (even with a watch that would stop), naming them. */
static void test_bad_options(const ref_scan_t *rs)
{
    static const struct {
        int r_min, r_max, ftest_r, interp_n;
        const char *word;
    } cases[] = {{0, 3, 7, 0, "r_min"}, {5, 4, 7, 0, "r_max"}, {1, 33, 7, 0, "r_max"},
                 {1, 8, 0, 0, "ftest_r"}, {1, 8, 33, 0, "ftest_r"}, {1, 8, 7, -1, "interp_n"},
                 {1, 8, 7, FIT_INTERP_MAX + 1, "interp_n"}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        fit_pipeline_opts_t o = fit_pipeline_opts_default();
        o.r_min = cases[i].r_min;
        o.r_max = cases[i].r_max;
        o.ftest_edges = FIT_EDGE_TOP;
        o.ftest_r = cases[i].ftest_r;
        o.interp_n = cases[i].interp_n;
        struct seen s = {.stop_at = 0};
        fit_watch_t w = {.progress = on_progress, .stop = on_stop, .params = &s};
        fit_pipeline_t pl;
        err_t err = {{0}};
        CHECK(fit_pipeline_run(&rs->scan, &o, &w, &pl, &err) == -EINVAL);
        CHECK(strstr(err.msg, cases[i].word) != NULL);
        CHECK(s.stop_asks == 0 && s.calls == 0 && pl.sweep.fits == NULL);
    }
    /* the sweep alone: the same check, the same words */
    fit_sweep_t sw;
    err_t err = {{0}};
    CHECK(fit_sweep_run(&rs->scan, 5, 4, NULL, &sw, &err) == -EINVAL && strstr(err.msg, "r_min"));
    CHECK(sw.fits == NULL);
    fit_scan_t bad = rs->scan;
    bad.pitch_um = 0;
    fit_pipeline_t pl;
    CHECK(fit_pipeline_run(&bad, NULL, NULL, &pl, &err) == -EINVAL && strstr(err.msg, "pitch"));
}

/* The reference scan without its last point (5.4, 5.4): no longer a regular grid for Wiener, and
 * an r = 9 F-test has 82 parameters for 80 points. Both parts fail, the run does not. */
static void test_failing_parts(const ref_scan_t *rs)
{
    fit_scan_t holey = rs->scan;
    holey.n--;
    fit_pipeline_opts_t o = fit_pipeline_opts_default();
    o.ftest_edges = EDGES_TLB;
    o.ftest_r = 9;
    o.wiener = 1;
    o.interp_n = 3;
    struct seen s = {.stop_at = -1};
    fit_watch_t w = {.progress = on_progress, .params = &s};
    fit_pipeline_t pl;
    err_t err = {{0}};
    CHECK(fit_pipeline_run(&holey, &o, &w, &pl, &err) == 0);
    CHECK(pl.ftest_part.asked && pl.ftest_part.rc == -EDOM);
    CHECK(strstr(pl.ftest_part.err.msg, "r = 9") != NULL);
    CHECK(strstr(pl.ftest_part.err.msg, "underdetermined") != NULL);
    CHECK(pl.wiener_part.asked && pl.wiener_part.rc == -EINVAL && pl.wiener.S == NULL);
    CHECK(strstr(pl.wiener_part.err.msg, "grid") != NULL);
    CHECK(pl.interp_part.asked && pl.interp_part.rc == 0 && pl.interp_r == pl.sweep.best_aic);
    for (int r = 1; pl.sweep.fits && r <= 8; r++) CHECK(pl.sweep.fits[r - 1].n_used == 80);
    CHECK(pl.sweep.best_aic >= 1 && pl.sweep.best_bic >= 1);
    CHECK(s.bad == 0 && s.calls == 11); /* failed parts are steps done all the same */
    fit_pipeline_free(&pl);
}

int main(void)
{
    /* first, while fit/ has not been called in this process */
    in_child(gsl_own_handler);
    in_child(gsl_default_handler);
    gsl_default_handler(); /* and here, in the test process itself */
    ref_scan_t rs;
    if (ref_scan_load("paperlike_scan.json", &rs)) return 1;
    test_reference(&rs);
    test_ftest_own_h1(&rs);
    test_p_value();
    test_stop(&rs);
    test_bad_options(&rs);
    test_failing_parts(&rs);
    ref_scan_free(&rs);
    CHECK_DONE();
}
