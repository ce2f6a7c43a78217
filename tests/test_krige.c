/* test_krige.c: the kriged map (fit/krige.h) on synthetic 9 x 9 scans whose data come from the
 * accurate box integral (fit/box.h, not the design matrix the kriged map uses) of a known truth,
 * with deterministic noise: a flat pixel without noise is exactly flat and keeps no smooth part;
 * a pixel piecewise on the 3 x 3 grid (a dead corner) is recovered from the r = 3 prior within
 * its error bars and without the smooth part (its likelihood ratio below FIT_KRIGE_LR); a tilted
 * pixel keeps the smooth part and comes closer to the truth than the r = 6 fit's map; bad
 * arguments and a stop request are refused. The fidelity against the simulator over many scenes
 * is bench/fidelity.c --krige and test_fidelity. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "check.h"
#include "fit/adapt.h"
#include "fit/box.h"
#include "fit/design.h"
#include "fit/krige.h"
#include "fit/noise.h"

#define P 6.0   /* pitch, um */
#define RAD 1.34 /* spot radius, um */
#define N 81
#define BIAS 100.0
#define GAIN 3.153
#define READ 5.67
#define FRAMES 12
#define PEAK 3000.0 /* DN per unit-peak Airy flux (um^-2) */

/* A deterministic standard normal (splitmix64 and Box-Muller): the tests' noise, fixed by seed. */
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

/* The truth's value on a g x g partition of the pixel (row-major, y then x). */
typedef double (*truth_fn)(double u, double v); /* u, v: fractions of the pitch */

/* A scan and the arrays it borrows. */
struct scan {
    double x[N], y[N], sig[N];
    fit_scan_t sc;
};

/* A 9 x 9 scan at 0.6 um steps centred on the pixel: signal = bias + PEAK x the integral of the
 * Airy spot times the truth (constant on each cell of a g x g partition, the truth at the cell's
 * centre), by the box integral, plus the noise model's noise times noise (0: none). */
static fit_scan_t *make_scan(truth_fn t, int g, double noise, unsigned long long seed,
                             struct scan *b)
{
    double *x = b->x, *y = b->y, *sig = b->sig;
    fit_scan_t *sc = &b->sc;
    *sc = (fit_scan_t){N, x, y, sig, P, RAD, BIAS, GAIN, READ, FRAMES, FIT_FULL_SCALE_DEFAULT};
    for (int k = 0; k < N; k++) {
        x[k] = P / 2 + 0.6 * (k % 9 - 4);
        y[k] = P / 2 + 0.6 * (k / 9 - 4);
        double s = 0;
        for (int j = 0; j < g; j++)
            for (int i = 0; i < g; i++) {
                fit_rect_t r = {P * i / g, P * (i + 1) / g, P * j / g, P * (j + 1) / g};
                double v, eb;
                err_t e;
                CHECK(fit_box_integral(RAD, &r, x[k], y[k], 1e-12, &v, &eb, &e) == 0);
                s += v * t((i + 0.5) / g, (j + 0.5) / g);
            }
        sig[k] = BIAS + PEAK * s;
    }
    for (int k = 0; k < N && noise > 0; k++)
        sig[k] += noise * fit_noise_sigma(FIT_NOISE_SHOT_READ, sc, sig[k]) * gauss(&seed);
    return sc;
}

static double flat(double u, double v)
{
    (void)u, (void)v;
    return 1;
}

static double dead_corner(double u, double v) /* the top-left ninth dead */
{
    return u < 1.0 / 3 && v < 1.0 / 3 ? 0 : 1;
}

static double tilt(double u, double v) /* 30 % across the pixel in x, 10 % in y */
{
    return 1 + 0.3 * (u - 0.5) + 0.1 * (v - 0.5);
}

/* rms over a 120 x 120 sampling of the pixel between a piecewise map (c x c, mean 1) and the
 * truth scaled to mean 1 on the same samples. */
static double map_rms(const double *S, int c, truth_fn t)
{
    double acc = 0, mt = 0;
    for (int j = 0; j < 120; j++)
        for (int i = 0; i < 120; i++) mt += t((i + 0.5) / 120, (j + 0.5) / 120) / (120.0 * 120);
    for (int j = 0; j < 120; j++)
        for (int i = 0; i < 120; i++) {
            double d = S[(j * c / 120) * c + i * c / 120] - t((i + 0.5) / 120, (j + 0.5) / 120) / mt;
            acc += d * d;
        }
    return sqrt(acc / (120.0 * 120));
}

static fit_options_t shot_read(void)
{
    fit_options_t o = fit_options_default();
    o.noise = FIT_NOISE_SHOT_READ;
    return o;
}

static void flat_pixel(void)
{
    static struct scan b;
    const fit_scan_t *sc = make_scan(flat, 1, 0, 1, &b);
    fit_options_t o = shot_read();
    fit_kriged_t k;
    err_t e;
    for (int r = 1; r <= 2; r++) { /* no prior part, and the 2 x 2 grid's */
        CHECK(fit_krige(sc, r, &o, &k, &e) == 0);
        CHECK(k.grid == 24 && k.r == r && k.smooth == 0 && k.n_levels == (r == 2));
        CHECK(k.lr >= 0 && k.lr < FIT_KRIGE_LR);
        CHECK(isnan(k.length_um) && k.amplitude == 0);
        double worst = 0; /* data exactly a flat map's: the posterior is the mean itself */
        for (int c = 0; c < 24 * 24; c++) worst = fmax(worst, fabs(k.S[c] - 1));
        CHECK(worst < 1e-9);
        fit_kriged_free(&k);
        CHECK(k.S == NULL && k.grid == 0);
    }
}

static void piecewise_pixel(void)
{
    static struct scan b;
    const fit_scan_t *sc = make_scan(dead_corner, 3, 1, 7, &b);
    fit_options_t o = shot_read();
    fit_kriged_t k;
    err_t e;
    CHECK(fit_krige(sc, 3, &o, &k, &e) == 0);
    CHECK(k.grid == 24 && k.n_levels == 1 && k.level_q[0] == 3);
    fprintf(stderr, "dead corner: LR %.2f, rms %.5f\n", k.lr, map_rms(k.S, 24, dead_corner));
    CHECK(k.smooth == 0 && k.lr < FIT_KRIGE_LR);
    /* the dead ninth is 0 and the rest 9/8 (mean 1): every fine cell within 4 of its S_err */
    int bad = 0;
    for (int j = 0; j < 24; j++)
        for (int i = 0; i < 24; i++) {
            double want = i < 8 && j < 8 ? 0 : 9.0 / 8, s = k.S[j * 24 + i];
            bad += !(fabs(s - want) <= 4 * k.S_err[j * 24 + i]) || !(k.S_err[j * 24 + i] < 0.05);
        }
    CHECK(bad == 0);
    CHECK(map_rms(k.S, 24, dead_corner) < 0.01);
    fit_kriged_free(&k);
}

static void tilted_pixel(void)
{
    static struct scan b;
    const fit_scan_t *sc = make_scan(tilt, 24, 1, 11, &b);
    fit_options_t o = shot_read();
    fit_kriged_t k;
    fit_result_t f;
    err_t e;
    CHECK(fit_krige(sc, 6, &o, &k, &e) == 0);
    CHECK(fit_map(sc, 6, &o, &f, &e) == 0);
    CHECK(k.smooth == 1 && k.lr >= FIT_KRIGE_LR);
    CHECK(k.length_um > 0 && k.amplitude > 0 && k.evaluations > 0);
    double rk = map_rms(k.S, 24, tilt), rf = map_rms(f.S, 6, tilt);
    fprintf(stderr, "tilted pixel: kriged map rms %.5f (smooth part: sd %.3g, length %.3g um, "
                    "LR %.1f, %d evaluations, %.1f ms), r = 6 fit %.5f\n",
            rk, k.amplitude, k.length_um, k.lr, k.evaluations, k.ms, rf);
    /* the r = 6 map is a staircase of a 30 % tilt: 0.3 / 6 / sqrt(12) = 0.014 at the least */
    CHECK(rf > 0.3 / 6 / sqrt(12));
    CHECK(rk < 0.7 * rf);
    fit_result_free(&f);
    fit_kriged_free(&k);
}

/* fit_map_ms_between against hand-worked cases and, for grids 24 and 25, against the centres of
 * the 600 x 600 grid both divide (each of its cells lies in one cell of either map, so the mean
 * over those centres is exact). */
static void ms_between(void)
{
    double one[1] = {1}, quad[4] = {1, 1, 1, 3}, half[4] = {0, 1, 0, 1};
    double third[9] = {0, 1, 1, 0, 1, 1, 0, 1, 1};
    CHECK(fabs(fit_map_ms_between(one, 1, quad, 2) - 1) < 1e-15);  /* a quarter at 2^2 */
    CHECK(fabs(fit_map_ms_between(half, 2, third, 3) - 1.0 / 6) < 1e-15); /* x in [1/3, 1/2) */
    CHECK(fabs(fit_map_ms_between(third, 3, half, 2) - 1.0 / 6) < 1e-15);
    CHECK(fit_map_ms_between(third, 3, third, 3) == 0);
    CHECK(isnan(fit_map_ms_between(one, 0, quad, 2)));
    CHECK(isnan(fit_map_ms_between(one, 1, quad, FIT_KRIGE_MIX_GRID_MAX + 1)));
    static double a[24 * 24], b[25 * 25];
    unsigned long long s = 5;
    for (int i = 0; i < 24 * 24; i++) a[i] = gauss(&s);
    for (int i = 0; i < 25 * 25; i++) b[i] = gauss(&s);
    double acc = 0;
    for (int j = 0; j < 600; j++)
        for (int i = 0; i < 600; i++) {
            double d = a[(j * 24 / 600) * 24 + i * 24 / 600] - b[(j * 25 / 600) * 25 + i * 25 / 600];
            acc += d * d;
        }
    double want = acc / (600.0 * 600), got = fit_map_ms_between(a, 24, b, 25);
    CHECK(fabs(got - want) <= 1e-12 * want);
}

/* The expected error under the neighbouring priors (fit_krige_mix): a flat pixel's maps are flat
 * under every prior (no spread; r = 1 has no r - 1). On the tilted pixel and the dead corner it
 * covers the map's error against the truth and is at most 2.5x it (the r prior's posterior alone
 * is 1.7-2x it there); on the dead corner, which r = 3's grid holds exactly, the priors of r = 2
 * and 4 cannot hold it and fall outside Occam's window, so their spread (0.09) stays out. */
static void mixture(void)
{
    static struct scan b;
    fit_options_t o = shot_read();
    fit_kriged_t k;
    err_t e;
    const fit_scan_t *sc = make_scan(flat, 1, 0, 1, &b);
    CHECK(fit_krige(sc, 1, &o, &k, &e) == 0);
    CHECK(fit_krige_mix(sc, &k, &o, &e) == 0);
    CHECK(k.mix_n == 2 && k.mix_r[0] == 1 && k.mix_r[1] == 2);
    CHECK(k.mix_spread[0] == 0 && k.mix_spread[1] < 1e-9);
    fit_kriged_free(&k);
    struct {
        truth_fn t;
        int g, r;
        unsigned long long seed;
        const char *name;
    } cases[] = {{tilt, 24, 6, 11, "tilted pixel"}, {dead_corner, 3, 3, 7, "dead corner"}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        sc = make_scan(cases[c].t, cases[c].g, 1, cases[c].seed, &b);
        CHECK(fit_krige(sc, cases[c].r, &o, &k, &e) == 0);
        CHECK(fit_krige_mix(sc, &k, &o, &e) == 0);
        double rms = map_rms(k.S, k.grid, cases[c].t), post = 0;
        for (int i = 0; i < k.grid * k.grid; i++) post += k.S_err[i] * k.S_err[i];
        post = sqrt(post / (k.grid * k.grid));
        fprintf(stderr, "%s: map %.5f from the truth; expected %.5f under r %d..%d (spreads %.5f "
                        "%.5f %.5f), %.5f under r = %d alone\n",
                cases[c].name, rms, k.mix_err, k.mix_r[0], k.mix_r[k.mix_n - 1], k.mix_spread[0],
                k.mix_spread[1], k.mix_spread[2], post, k.r);
        CHECK(k.mix_n == 3 && k.mix_r[0] == k.r - 1 && k.mix_r[1] == k.r && k.mix_r[2] == k.r + 1);
        CHECK(k.mix_spread[1] == 0 && fabs(k.mix_map_err[1] - post) <= 1e-12 * post);
        CHECK(k.mix_err >= rms && k.mix_err <= 2.5 * rms);
        if (cases[c].t == dead_corner)
            CHECK(k.mix_weight[0] == 0 && k.mix_weight[1] == 1 && k.mix_weight[2] == 0 &&
                  k.mix_spread[0] > 0.05 && fabs(k.mix_err - post) <= 1e-12 * post &&
                  k.mix_log_lik[0] < k.mix_log_lik[1] - FIT_KRIGE_MIX_WINDOW);
        else
            CHECK(k.mix_weight[0] == 1.0 / 3 && k.mix_weight[2] == 1.0 / 3);
        fit_kriged_free(&k);
    }
}

static int stop_now(void *arg)
{
    (void)arg;
    return 1;
}

static void refusals(void)
{
    static struct scan b;
    fit_scan_t sc = *make_scan(flat, 1, 0, 1, &b);
    fit_options_t o = shot_read();
    fit_kriged_t k;
    err_t e;
    CHECK(fit_krige(&sc, 0, &o, &k, &e) == -EINVAL && k.S == NULL);
    CHECK(fit_krige(&sc, 33, &o, &k, &e) == -EINVAL);
    fit_scan_t two = sc;
    two.n = 2;
    CHECK(fit_krige(&two, 3, &o, &k, &e) == -EINVAL && k.S == NULL);
    fit_scan_t dark = sc;
    double zero[N];
    for (int i = 0; i < N; i++) zero[i] = BIAS;
    dark.signal_dn = zero;
    CHECK(fit_krige(&dark, 3, &o, &k, &e) == -EINVAL && k.S == NULL);
    o.stop.poll = stop_now;
    CHECK(fit_krige(make_scan(tilt, 6, 1, 3, &b), 3, &o, &k, &e) == -ECANCELED && k.S == NULL);
}
/* The planner's covariance (fit_krige_with_cov): the same map as fit_krige_with, its diagonal
 * S_err^2 whether the smooth part was kept (a tilt) or dropped (a dead corner, where S_err is the
 * smooth model's second moment about the map, to the rounding of the prior's variance less what
 * the points explain), symmetric, and rows summing to 0 (S has mean 1
 * by construction, so its sum has no variance). */
static void covariance(void)
{
    static struct scan b1, b2;
    const fit_scan_t *scans[2] = {make_scan(dead_corner, 3, 1, 7, &b1),
                                  make_scan(tilt, 24, 1, 11, &b2)};
    const int rs[2] = {3, 6};
    for (int c = 0; c < 2; c++) {
        fit_options_t o = shot_read();
        fit_krige_prior_t pr = fit_krige_prior_divisors(rs[c]);
        pr.r = rs[c];
        fit_kriged_t k, kc;
        err_t e;
        CHECK(fit_krige_with(scans[c], &pr, &o, &k, &e) == 0 && k.S_cov == NULL);
        CHECK(fit_krige_with_cov(scans[c], &pr, &o, &kc, &e) == 0 && kc.S_cov != NULL);
        CHECK(kc.smooth == c && kc.grid == k.grid);
        size_t m = (size_t)k.grid * k.grid;
        double sdiff = 0, dworst = 0, aworst = 0, rworst = 0;
        for (size_t i = 0; kc.S_cov && i < m; i++) {
            double rs_i = 0, v = kc.S_err[i] * kc.S_err[i];
            sdiff = fmax(sdiff, fabs(kc.S[i] - k.S[i]));
            dworst = fmax(dworst, fabs(kc.S_cov[i * m + i] - v) / v);
            for (size_t j = 0; j < m; j++) {
                aworst = fmax(aworst, fabs(kc.S_cov[i * m + j] - kc.S_cov[j * m + i]) /
                                          (kc.S_err[i] * kc.S_err[j]));
                rs_i += kc.S_cov[i * m + j];
            }
            rworst = fmax(rworst, fabs(rs_i) / v);
        }
        fprintf(stderr, "cov %d: S %g diag %g asym %g rows %g\n", c, sdiff, dworst, aworst, rworst);
        CHECK(sdiff == 0 && dworst < 1e-6 && aworst < 1e-12 && rworst < 1e-6);
        fit_kriged_free(&k);
        fit_kriged_free(&kc);
    }
}

/* The planner (adapt.h) on the kriged covariance of a scan that saw only the pixel's right half
 * (x > 3.3 um): the map is uncertain where no spot fell, so the first batch from the whole 9 x 9
 * raster lies in the unseen left half, and the expected mean variance falls with each pick. */
static void plan_unseen_half(void)
{
    static struct scan b, half;
    const fit_scan_t *full = make_scan(tilt, 24, 1, 11, &b);
    size_t n = 0;
    for (size_t k = 0; k < N; k++)
        if (full->x_um[k] > P / 2 + 0.3)
            half.x[n] = full->x_um[k], half.y[n] = full->y_um[k], half.sig[n++] = full->signal_dn[k];
    half.sc = *full;
    half.sc.n = n, half.sc.x_um = half.x, half.sc.y_um = half.y, half.sc.signal_dn = half.sig;
    fit_options_t o = shot_read();
    fit_krige_prior_t pr = fit_krige_prior_divisors(6);
    pr.r = 6;
    fit_kriged_t k;
    err_t e;
    CHECK(n == 36 && fit_krige_with_cov(&half.sc, &pr, &o, &k, &e) == 0);
    if (!k.S_cov) return;
    size_t m = (size_t)k.grid * k.grid;
    double *A = malloc(sizeof(double) * N * m), s2[N], mv[10];
    fit_design_opts_t dopt = fit_design_opts_for_tol(1e-6);
    CHECK(A && fit_design_build(RAD, P, k.grid, full->x_um, full->y_um, N, &dopt, A, NULL, &e) == 0);
    for (int j = 0; j < N; j++) s2[j] = 1e-4; /* a 1 % measurement of the spot's flux */
    int picked[9], got = A ? fit_adapt_pick(m, k.S_cov, N, A, s2, 9, picked, mv, &e) : -1;
    CHECK(got == 9);
    int left = 0;
    for (int i = 0; i < got; i++) {
        left += full->x_um[picked[i]] < P / 2;
        CHECK(mv[i + 1] < mv[i]);
    }
    fprintf(stderr, "planner, right half seen: %d of %d picks in the left half; expected rms "
                    "error %.4f -> %.4f\n", left, got, sqrt(mv[0]), sqrt(mv[got > 0 ? got : 0]));
    CHECK(left == got);
    free(A);
    fit_kriged_free(&k);
}

int main(void)
{
    flat_pixel();
    piecewise_pixel();
    tilted_pixel();
    ms_between();
    mixture();
    covariance();
    plan_unseen_half();
    refusals();
    CHECK_DONE();
}
