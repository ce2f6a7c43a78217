/* test_adapt_plan.c: the adaptive scan's planner (fit/adapt_plan.h) against independent results.
 *   - Travel order: positions on a line taken from one end are visited in order, the path the
 *     line's length; three on a line where the nearest neighbour first goes the wrong way (8 um)
 *     get the best path by hand (6 um); on random sets the order is a permutation, its length the sum of its own
 *     steps (summed here), never longer than the positions' own order and never shorter than the
 *     best of all orders (every permutation tried).
 *   - Starting raster: the n0 x n0 cell centres (i + 0.5) p / n0, a path of n0^2 - 1 steps of
 *     one cell; a box leaves out exactly the centres outside it.
 *   - Candidates: the lattice's (L - 1)^2 interior nodes for `inside`, (L + 1)^2 with `all`, the
 *     margin's count by hand; never outside the box.
 *   - A tilted pixel seen only in its right half (box integrals of the truth, fit/box.h, with
 *     noise of a fixed seed): every position of the first batch lies in the unseen left half;
 *     the same points give the same batch; the posterior's error is the root of the mean S_err^2
 *     the kriged map reports and the expected error the map's error under the neighbouring
 *     priors (krige.h, fit_krige_mix); the batch lowers the expected error, and measured (box integrals again)
 *     the refitted map's expected error lands within a factor 1.5 of the prediction; the
 *     reported path is the sum of the batch's steps from the last point; an allowed box keeps
 *     every position inside it.
 *   - Stop rule: a target met stops at once (target, no batch) when the scan holds more than its
 *     starting raster, else plans a batch; one just under the expected error plans a batch; a full budget stops (budget), a budget of fewer points than a batch shortens
 *     it.
 *   - An honest stop against the truth: a scan of the tilted pixel from the 5 x 5 start, batch
 *     after batch measured by box integrals, stops on a target; the map it stops with is within
 *     1.5x of the target against the tilt itself (rms of the two mean-1 maps over the pixel).
 *     Every plan of it with the candidates' rows reused from the plan before gives the batch,
 *     stop and errors of the same plan without reuse, bit for bit; so does a plan on other
 *     candidates (a 20-division lattice: 19 x 19 of them), which rebuilds the rows.
 *   - Bad options (batch 0, target <= 0, an empty box) are refused naming them. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/adapt_plan.h"
#include "fit/box.h"
#include "fit/noise.h"

#define P 6.0    /* pitch, um */
#define RAD 1.34 /* spot radius, um */
#define BIAS 100.0
#define GAIN 3.153
#define READ 5.67
#define FRAMES 12
#define PEAK 3000.0 /* DN per unit-peak Airy flux (um^-2) */
#define G 6         /* the truth's partition of the pixel */
#define NMAX 200
#define TILT_TARGET 0.01 /* the honest stop's target */

/* A deterministic standard normal (splitmix64 and Box-Muller), fixed by seed. */
static double gauss(unsigned long long *s)
{
    double u[2];
    for (int i = 0; i < 2; i++) {
        unsigned long long z = (*s += 0x9E3779B97F4A7C15ULL);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
        z ^= z >> 31;
        u[i] = ((double)(z >> 11) + 0.5) / 9007199254740992.0;
    }
    return sqrt(-2 * log(u[0])) * cos(2 * M_PI * u[1]);
}

static double urand(unsigned long long *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* ---- travel order ---- */

static double path_of(size_t n, const double *x, const double *y, const size_t *perm, double x0,
                      double y0)
{
    double L = 0;
    for (size_t k = 0; k < n; k++) {
        L += hypot(x[perm[k]] - x0, y[perm[k]] - y0);
        x0 = x[perm[k]], y0 = y[perm[k]];
    }
    return L;
}

/* The shortest open path from (x0, y0) over every permutation (Heap's algorithm). */
static double best_path(size_t n, const double *x, const double *y, double x0, double y0)
{
    size_t p[8], c[8] = {0};
    for (size_t k = 0; k < n; k++) p[k] = k;
    double best = path_of(n, x, y, p, x0, y0);
    for (size_t i = 1; i < n;) {
        if (c[i] < i) {
            size_t j = i % 2 ? c[i] : 0, t = p[j];
            p[j] = p[i], p[i] = t;
            double L = path_of(n, x, y, p, x0, y0);
            if (L < best) best = L;
            c[i]++, i = 1;
        } else {
            c[i++] = 0;
        }
    }
    return best;
}

static void order(void)
{
    const double lx[5] = {5, 1, 3, 2, 4}, ly[5] = {0};
    size_t perm[8];
    double L = fit_adapt_order(5, lx, ly, 0, 0, perm);
    CHECK(fabs(L - 5) < 1e-12);
    for (int k = 0; k < 5; k++) CHECK(lx[perm[k]] == k + 1);
    /* from 0 the nearest is 1, then -1.5, then 3: 1 + 2.5 + 4.5 = 8, the order given
     * 3 + 2 + 2.5 = 7.5, the best -1.5, 1, 3: 1.5 + 2.5 + 2 = 6 */
    const double tx[3] = {3, 1, -1.5};
    L = fit_adapt_order(3, tx, ly, 0, 0, perm);
    CHECK(fabs(L - 6) < 1e-12 && tx[perm[0]] == -1.5 && tx[perm[1]] == 1 && tx[perm[2]] == 3);
    unsigned long long s = 3;
    for (int t = 0; t < 40; t++) {
        size_t n = 2 + (size_t)t % 6;
        double x[8], y[8], x0 = 6 * urand(&s), y0 = 6 * urand(&s);
        for (size_t k = 0; k < n; k++) x[k] = 6 * urand(&s), y[k] = 6 * urand(&s);
        L = fit_adapt_order(n, x, y, x0, y0, perm);
        int seen[8] = {0}, valid = 1;
        for (size_t k = 0; k < n; k++) valid &= perm[k] < n && !seen[perm[k]]++;
        CHECK(valid);
        size_t own[8];
        for (size_t k = 0; k < n; k++) own[k] = k;
        CHECK(fabs(L - path_of(n, x, y, perm, x0, y0)) < 1e-12 * (1 + L));
        CHECK(L <= path_of(n, x, y, own, x0, y0) + 1e-12);
        CHECK(L >= best_path(n, x, y, x0, y0) - 1e-12);
    }
    double nanx[2] = {1, NAN}, y2[2] = {0, 0};
    CHECK(isnan(fit_adapt_order(2, nanx, y2, 0, 0, perm)));
}

/* ---- starting raster and candidates ---- */

static void start_and_candidates(void)
{
    double x[49], y[49];
    CHECK(fit_adapt_start(P, 5, NULL, x, y) == 25);
    int cell[25] = {0}, ok = 1;
    for (int k = 0; k < 25; k++) {
        double i = x[k] / 1.2 - 0.5, j = y[k] / 1.2 - 0.5; /* (i + 0.5) p / 5 */
        ok &= fabs(i - round(i)) < 1e-12 && fabs(j - round(j)) < 1e-12;
        if (ok) cell[(int)round(j) * 5 + (int)round(i)]++;
        if (k) ok &= fabs(hypot(x[k] - x[k - 1], y[k] - y[k - 1]) - 1.2) < 1e-12;
    }
    for (int c = 0; c < 25; c++) ok &= cell[c] == 1;
    CHECK(ok);
    const double left[4] = {-INFINITY, 3.0, -INFINITY, INFINITY}; /* x = 0.6, 1.8, 3.0 */
    CHECK(fit_adapt_start(P, 5, left, x, y) == 15);
    CHECK(fit_adapt_start(P, 0, NULL, x, y) == -EINVAL);

    fit_adapt_opts_t o = fit_adapt_opts_default();
    double *cx, *cy;
    long n = fit_adapt_candidates(P, &o, &cx, &cy);
    CHECK(n == 29 * 29);
    int inside = 1;
    for (long k = 0; k < n; k++) inside &= cx[k] > 0 && cx[k] < P && cy[k] > 0 && cy[k] < P;
    CHECK(inside);
    free(cx), free(cy);
    o.region.kind = FIT_REGION_ALL;
    CHECK(fit_adapt_candidates(P, &o, &cx, &cy) == 31 * 31);
    free(cx), free(cy);
    o.region = (fit_region_t){FIT_REGION_MARGIN, 0.5}; /* nodes -0.4 .. 6.4: 35 a side */
    CHECK(fit_adapt_candidates(P, &o, &cx, &cy) == 35 * 35);
    free(cx), free(cy);
    o.region.kind = FIT_REGION_INSIDE;
    const double box[4] = {1.0, 2.5, 4.1, 10}; /* x 1.0..2.4 (8 nodes), y 4.2..5.8 (9 nodes) */
    memcpy(o.box_um, box, sizeof box);
    n = fit_adapt_candidates(P, &o, &cx, &cy);
    CHECK(n == 8 * 9);
    int in_box = 1;
    for (long k = 0; k < n; k++)
        in_box &= cx[k] >= 1.0 && cx[k] <= 2.5 && cy[k] >= 4.1 && cy[k] <= 10;
    CHECK(in_box);
    free(cx), free(cy);
    o.lattice = 1;
    CHECK(fit_adapt_candidates(P, &o, &cx, &cy) == -EINVAL);
}

/* ---- the planner on a known pixel ---- */

static double tilt(double u, double v) { return 1 + 0.3 * (u - 0.5) + 0.1 * (v - 0.5); }

struct scan {
    double x[NMAX], y[NMAX], sig[NMAX];
    fit_scan_t sc;
    unsigned long long seed;
};

/* Measures the truth at (x, y): box integrals of the tilt on its G x G partition, the noise
 * model's noise of the seed. */
static void measure(struct scan *b, double x, double y)
{
    size_t k = b->sc.n++;
    b->x[k] = x, b->y[k] = y;
    double s = 0;
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            fit_rect_t r = {P * i / G, P * (i + 1) / G, P * j / G, P * (j + 1) / G};
            double v, eb;
            err_t e;
            CHECK(fit_box_integral(RAD, &r, x, y, 1e-10, &v, &eb, &e) == 0);
            s += v * tilt((i + 0.5) / G, (j + 0.5) / G);
        }
    double sig = BIAS + PEAK * s;
    b->sig[k] = sig + fit_noise_sigma(FIT_NOISE_SHOT_READ, &b->sc, sig) * gauss(&b->seed);
}

/* The right half of the 9 x 9 raster at 0.6 um (x = 3.6 .. 5.4: 36 points). */
static void right_half(struct scan *b)
{
    memset(b, 0, sizeof *b);
    b->sc = (fit_scan_t){0, b->x, b->y, b->sig, P, RAD, BIAS, GAIN, READ, FRAMES,
                         FIT_FULL_SCALE_DEFAULT};
    b->seed = 21;
    for (int j = 0; j < 9; j++)
        for (int i = 5; i < 9; i++) measure(b, P / 2 + 0.6 * (i - 4), P / 2 + 0.6 * (j - 4));
}

static void planner(void)
{
    static struct scan b;
    right_half(&b);
    fit_adapt_opts_t o = fit_adapt_opts_default();
    o.target_err = 1e-4;
    fit_adapt_step_t s1, s2;
    err_t err = {{0}};
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s1, &err) == 0);
    CHECK(s1.stop == FIT_ADAPT_GO && s1.n == 9 && s1.n_fitted == 36);
    int left = 1;
    for (int k = 0; k < s1.n; k++) left &= s1.x_um[k] < P / 2;
    CHECK(left);
    fprintf(stderr, "half-seen tilt: expected error %.4f, predicted after 9 picks %.4f (r = %d, "
            "F = %d, %.0f ms)\n", s1.expected_err, s1.predicted_err, s1.r, s1.map.grid, s1.ms);
    /* the same points, the same batch */
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    CHECK(s2.n == s1.n && !memcmp(s1.x_um, s2.x_um, sizeof(double) * (size_t)s1.n) &&
          !memcmp(s1.y_um, s2.y_um, sizeof(double) * (size_t)s1.n) &&
          s1.expected_err == s2.expected_err);
    fit_adapt_step_free(&s2);
    /* the posterior's error is the root of the mean S_err^2 of the map; the expected error, under
     * the neighbouring priors, is the map's mixture error and at least the kept prior's share */
    size_t m = (size_t)s1.map.grid * s1.map.grid;
    double v = 0;
    for (size_t c = 0; c < m; c++) v += s1.map.S_err[c] * s1.map.S_err[c];
    CHECK(fabs(s1.posterior_err - sqrt(v / (double)m)) < 1e-9 * s1.posterior_err);
    CHECK(s1.map.mix_n >= 2 && s1.expected_err == s1.map.mix_err);
    fprintf(stderr, "half-seen tilt: posterior %.4f, under r %d..%d %.4f\n", s1.posterior_err,
            s1.map.mix_r[0], s1.map.mix_r[s1.map.mix_n - 1], s1.expected_err);
    CHECK(s1.predicted_err < s1.expected_err);
    /* the path from the last point taken */
    double L = 0, x0 = b.x[b.sc.n - 1], y0 = b.y[b.sc.n - 1];
    for (int k = 0; k < s1.n; k++)
        L += hypot(s1.x_um[k] - x0, s1.y_um[k] - y0), x0 = s1.x_um[k], y0 = s1.y_um[k];
    CHECK(fabs(L - s1.path_um) < 1e-12 * L);
    /* measured: the refitted map's expected error near the prediction */
    for (int k = 0; k < s1.n; k++) measure(&b, s1.x_um[k], s1.y_um[k]);
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    fprintf(stderr, "after the batch: expected error %.4f (predicted %.4f)\n", s2.expected_err,
            s1.predicted_err);
    CHECK(s2.expected_err < s1.expected_err);
    CHECK(s2.expected_err < 1.5 * s1.predicted_err && s2.expected_err > s1.predicted_err / 1.5);
    fit_adapt_step_free(&s2);
    /* an allowed box: every position in it */
    const double box[4] = {0.5, 2.0, 1.0, 4.0};
    memcpy(o.box_um, box, sizeof box);
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    int in_box = s2.n == 9;
    for (int k = 0; k < s2.n; k++)
        in_box &= s2.x_um[k] >= 0.5 && s2.x_um[k] <= 2.0 && s2.y_um[k] >= 1.0 && s2.y_um[k] <= 4.0;
    CHECK(in_box);
    fit_adapt_step_free(&s2);

    /* the stop rule: the first plan at the target stops, with no batch, once the scan holds more
     * than its starting raster */
    o = fit_adapt_opts_default();
    o.target_err = 1.0; /* a mean-1 map's error is far below its mean */
    CHECK(b.sc.n > o.start_points);
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    CHECK(s2.stop == FIT_ADAPT_TARGET && s2.target_met && s2.n == 0 && s2.expected_err <= 1.0);
    fit_adapt_step_free(&s2);
    o.start_points = b.sc.n; /* the points so far are all the start: a batch first */
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    CHECK(s2.stop == FIT_ADAPT_GO && s2.target_met && s2.n == 9);
    fit_adapt_step_free(&s2);
    o.start_points = fit_adapt_opts_default().start_points;
    double e_now = s2.expected_err;
    o.target_err = e_now * (1 - 1e-9); /* just under this map's expected error */
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    CHECK(s2.stop == FIT_ADAPT_GO && !s2.target_met && s2.n == 9 && s2.expected_err == e_now);
    fit_adapt_step_free(&s2);
    o.target_err = 1e-4;
    o.max_points = b.sc.n;
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    CHECK(s2.stop == FIT_ADAPT_BUDGET && s2.n == 0 && s2.expected_err > 1e-4);
    fit_adapt_step_free(&s2);
    o.max_points = b.sc.n + 4;
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s2, &err) == 0);
    CHECK(s2.stop == FIT_ADAPT_GO && s2.n == 4);
    fit_adapt_step_free(&s2);
    fit_adapt_step_free(&s1);
}

/* The rms over the pixel of the mean-1 map S (F x F) against the mean-1 tilt on its G x G
 * partition (the truth measure() integrates), both sampled at n x n points. */
static double rms_vs_tilt(const double *S, int F)
{
    const int n = 240;
    double ms = 0, mt = 0, acc = 0;
    for (int c = 0; c < F * F; c++) ms += S[c] / (F * F);
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) mt += tilt((i + 0.5) / G, (j + 0.5) / G) / (G * G);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double u = (i + 0.5) / n, v = (j + 0.5) / n;
            double d = S[(int)(v * F) * F + (int)(u * F)] / ms -
                       tilt(((int)(u * G) + 0.5) / G, ((int)(v * G) + 0.5) / G) / mt;
            acc += d * d;
        }
    return sqrt(acc / (n * n));
}

/* Do two steps hold the same stop, the same batch and the same expected errors, bit for bit? */
static int same_batch(const fit_adapt_step_t *a, const fit_adapt_step_t *b)
{
    return a->stop == b->stop && a->n == b->n &&
           (a->n == 0 || (!memcmp(a->x_um, b->x_um, sizeof(double) * (size_t)a->n) &&
                          !memcmp(a->y_um, b->y_um, sizeof(double) * (size_t)a->n))) &&
           !memcmp(&a->expected_err, &b->expected_err, sizeof(double)) &&
           !memcmp(&a->predicted_err, &b->predicted_err, sizeof(double));
}

/* A whole scan of the tilted pixel, the 5 x 5 start then the planner's batches, to its stop; each
 * plan with the candidates' rows kept from plan to plan (fit_adapt_cache_t) and again without. */
static void honest_stop(void)
{
    static struct scan b;
    memset(&b, 0, sizeof b);
    b.sc = (fit_scan_t){0, b.x, b.y, b.sig, P, RAD, BIAS, GAIN, READ, FRAMES,
                        FIT_FULL_SCALE_DEFAULT};
    b.seed = 5;
    double x[25], y[25];
    int n0 = fit_adapt_start(P, 5, NULL, x, y);
    CHECK(n0 == 25);
    for (int k = 0; k < n0; k++) measure(&b, x[k], y[k]);
    fit_adapt_opts_t o = fit_adapt_opts_default();
    o.target_err = TILT_TARGET;
    o.max_points = NMAX;
    fit_adapt_step_t s, ref;
    fit_adapt_cache_t cache = {0};
    err_t err = {{0}};
    int plans = 0, met_before = 0, same = 1;
    for (;;) {
        CHECK(fit_adapt_plan(&b.sc, &o, &cache, &s, &err) == 0);
        /* the same plan without the cache: the same batch, bit for bit */
        CHECK(fit_adapt_plan(&b.sc, &o, NULL, &ref, &err) == 0);
        same &= same_batch(&s, &ref);
        fit_adapt_step_free(&ref);
        plans++;
        if (s.stop != FIT_ADAPT_GO) break;
        for (int k = 0; k < s.n; k++) measure(&b, s.x_um[k], s.y_um[k]);
        met_before = s.target_met;
        fit_adapt_step_free(&s);
    }
    double rms = rms_vs_tilt(s.map.S, s.map.grid);
    fprintf(stderr, "tilt to target %.4f: stopped (%s) at %zu points after %d plans, expected "
            "error %.4f, against the tilt %.4f\n", TILT_TARGET, fit_adapt_stop_name(s.stop),
            b.sc.n, plans, s.expected_err, rms);
    CHECK(s.stop == FIT_ADAPT_TARGET && s.target_met && !met_before && plans >= 2);
    CHECK(rms <= 1.5 * TILT_TARGET);
    CHECK(same && cache.A && cache.grid == s.map.grid);
    fit_adapt_step_free(&s);
    /* other candidates (a coarser lattice): the cache is rebuilt, the batch again the uncached */
    o.target_err = 1e-4;
    o.lattice = 20;
    CHECK(fit_adapt_plan(&b.sc, &o, &cache, &s, &err) == 0);
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &ref, &err) == 0);
    CHECK(s.n == 9 && same_batch(&s, &ref) && cache.nc == 19 * 19);
    fit_adapt_step_free(&s);
    fit_adapt_step_free(&ref);
    fit_adapt_cache_free(&cache);
    CHECK(!cache.A && cache.grid == 0);
}

static void bad_options(void)
{
    static struct scan b;
    right_half(&b);
    fit_adapt_step_t s;
    err_t err = {{0}};
    fit_adapt_opts_t o = fit_adapt_opts_default();
    o.batch = 0;
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s, &err) == -EINVAL && strstr(err.msg, "batch"));
    fit_adapt_step_free(&s);
    o = fit_adapt_opts_default();
    o.target_err = 0;
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s, &err) == -EINVAL && strstr(err.msg, "target_err"));
    fit_adapt_step_free(&s);
    o = fit_adapt_opts_default();
    o.box_um[0] = 4, o.box_um[1] = 3;
    CHECK(fit_adapt_plan(&b.sc, &o, NULL, &s, &err) == -EINVAL && strstr(err.msg, "box"));
    fit_adapt_step_free(&s);
}

int main(void)
{
    order();
    start_and_candidates();
    planner();
    honest_stop();
    bad_options();
    CHECK_DONE();
}
