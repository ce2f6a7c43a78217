/* test_fit_threads.c: fits on several threads at once give what one thread gives, bit for bit.
 *
 * Two ways fits share a process: ipsd's fit workers run whole pipelines side by side, and the
 * sweep's r run on threads of one pipeline (fit_pipeline_opts_t.threads, `ips fit --threads`).
 * The scan is the bench's large case, a 41 x 41 raster of 0.12 um steps over the 6 um pixel
 * (1681 points), fitted for r = 1..12: at r >= 11 the weighted matrix has more than 128 columns
 * and LAPACK's blocked QR runs through OpenBLAS's shared buffers, where Debian's serial OpenBLAS
 * raced (two threads' QR of the same matrix differed in 34 of 40 calls; CMakeLists.txt). The
 * data are a known map's model (built here from box integrals of fit/box.c, not the design
 * matrix) with deterministic noise, so the fit at the true r is also checked against the truth. */
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/box.h"
#include "fit/pipeline.h"

#define GRID 41
#define NPTS (GRID * GRID)
#define PITCH 6.0
#define RADIUS 1.342
#define R_TRUE 4 /* the truth: a 4 x 4 map (exact in the model at r = 4, 8, 12) */
#define R_MAX 12
#define PEAK_DN 60000.0
#define BIAS 100.0

static double xs[NPTS], ys[NPTS], sig[NPTS];

/* The truth: a tilt and a dip (the fit normalises its map to mean 1, and so does the check). */
static double truth(int i, int j)
{
    static const double dip[R_TRUE][R_TRUE] = {
        {0, 0, 0, 0}, {0, -0.2, -0.1, 0}, {0, -0.1, -0.05, 0}, {0, 0, 0, 0}};
    return 1.0 + 0.05 * (i - 1.5) - 0.03 * (j - 1.5) + dip[j][i];
}

/* Uniform deviates on (0, 1) from a 64-bit LCG (Knuth's MMIX constants): reproducible anywhere. */
static double uniform(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return ((double)(*s >> 11) + 0.5) / 9007199254740992.0;
}

static fit_scan_t make_scan(void)
{
    uint64_t seed = 12345;
    fit_scan_t s = {.n = NPTS, .x_um = xs, .y_um = ys, .signal_dn = sig, .pitch_um = PITCH,
                    .spot_radius_um = RADIUS, .bias_dn = BIAS, .gain_e_per_dn = 1.0,
                    .read_noise_e = 5.0, .frames = 1, .full_scale_dn = 1e9};
    double h = PITCH / R_TRUE;
    for (int q = 0; q < NPTS; q++) {
        xs[q] = 0.6 + 0.12 * (q % GRID);
        ys[q] = 0.6 + 0.12 * (q / GRID);
        double m = 0;
        for (int j = 0; j < R_TRUE; j++)
            for (int i = 0; i < R_TRUE; i++) {
                fit_rect_t b = {i * h, (i + 1) * h, j * h, (j + 1) * h};
                double v, eb;
                CHECK(fit_box_integral(RADIUS, &b, xs[q], ys[q], 1e-12, &v, &eb, NULL) == 0);
                m += truth(i, j) * v;
            }
        m *= PEAK_DN;
        /* Gaussian noise of eq. 5's sigma (shot + read, gain 1) by Box-Muller */
        double sd = sqrt(m + 25.0), u1 = uniform(&seed), u2 = uniform(&seed);
        sig[q] = BIAS + m + sd * sqrt(-2 * log(u1)) * cos(2 * M_PI * u2);
    }
    return s;
}

static fit_pipeline_opts_t opts_for(int threads)
{
    fit_pipeline_opts_t o = fit_pipeline_opts_default();
    o.r_min = 1;
    o.r_max = R_MAX;
    o.threads = threads;
    return o;
}

/* The same doubles, NaN equal to NaN (bit patterns). */
static int same(const double *a, const double *b, size_t n)
{
    return (!a && !b) || (a && b && memcmp(a, b, sizeof(double) * n) == 0);
}

/* Every number of every fit, and the choices, equal; only the times may differ. */
static int same_sweep(const fit_pipeline_t *a, const fit_pipeline_t *b)
{
    const fit_sweep_t *x = &a->sweep, *y = &b->sweep;
    int ok = x->best_aic == y->best_aic && x->best_bic == y->best_bic &&
             x->recommended_r == y->recommended_r && x->range_edge == y->range_edge;
    for (int r = x->r_min; r <= x->r_max && ok; r++) {
        const fit_result_t *f = &x->fits[r - x->r_min], *g = &y->fits[r - y->r_min];
        size_t m = (size_t)r * r;
        ok = f->flags == g->flags && same(&f->chi2, &g->chi2, 1) && same(&f->I0, &g->I0, 1) &&
             same(&f->I0_err, &g->I0_err, 1) && same(&f->cond, &g->cond, 1) &&
             same(&f->cv_chi2, &g->cv_chi2, 1) && same(f->S, g->S, m) &&
             same(f->S_err, g->S_err, m) && same(f->resid, g->resid, NPTS) &&
             same(f->model_dn, g->model_dn, NPTS) &&
             f->design.radial_evals == g->design.radial_evals;
        if (!ok) fprintf(stderr, "  r = %d differs\n", r);
    }
    return ok;
}

static const fit_scan_t *g_scan;

/* One of ipsd's fit workers: a whole pipeline on one thread. */
static void *worker(void *arg)
{
    fit_pipeline_opts_t o = opts_for(1);
    fit_pipeline_t *pl = arg;
    if (fit_pipeline_run(g_scan, &o, NULL, pl, NULL)) memset(pl, 0, sizeof *pl);
    return NULL;
}

int main(void)
{
    fit_scan_t scan = make_scan();
    g_scan = &scan;
    fit_pipeline_opts_t o1 = opts_for(1);
    fit_pipeline_t ref;
    err_t err;
    CHECK(fit_pipeline_run(&scan, &o1, NULL, &ref, &err) == 0);

    /* the fit at the true r against the truth: within 5 of its own standard errors */
    const fit_result_t *f = &ref.sweep.fits[R_TRUE - 1];
    CHECK(f->S != NULL && f->chi2_red < 1.3);
    double mean = 0;
    for (int j = 0; j < R_TRUE; j++)
        for (int i = 0; i < R_TRUE; i++) mean += truth(i, j) / (R_TRUE * R_TRUE);
    for (int c = 0; f->S && c < R_TRUE * R_TRUE; c++)
        CHECK_NEAR(f->S[c], truth(c % R_TRUE, c / R_TRUE) / mean, 0, 5 * f->S_err[c]);

    /* the sweep's r on 2 and on 5 threads: the same sweep, bit for bit (three times each) */
    for (int t = 2; t <= 5; t += 3)
        for (int rep = 0; rep < 3; rep++) {
            fit_pipeline_opts_t o = opts_for(t);
            fit_pipeline_t pl;
            CHECK(fit_pipeline_run(&scan, &o, NULL, &pl, &err) == 0);
            CHECK(same_sweep(&ref, &pl));
            fit_pipeline_free(&pl);
        }

    /* two fit workers side by side, as ipsd runs them: each gets the one-thread sweep */
    for (int rep = 0; rep < 3; rep++) {
        fit_pipeline_t pl[2];
        pthread_t tid[2];
        for (int w = 0; w < 2; w++) CHECK(pthread_create(&tid[w], NULL, worker, &pl[w]) == 0);
        for (int w = 0; w < 2; w++) pthread_join(tid[w], NULL);
        for (int w = 0; w < 2; w++) {
            CHECK(pl[w].sweep.fits != NULL && same_sweep(&ref, &pl[w]));
            fit_pipeline_free(&pl[w]);
        }
    }

    /* bad thread counts are refused, naming the option */
    for (int t = -1; t <= 65; t += 66) {
        fit_pipeline_opts_t o = opts_for(t);
        fit_pipeline_t pl;
        CHECK(fit_pipeline_run(&scan, &o, NULL, &pl, &err) == -EINVAL);
        CHECK(strstr(err.msg, "threads") != NULL);
    }
    fit_pipeline_free(&ref);
    CHECK_DONE();
}
