/* test_geometry.c: the geometry fit (fit/geometry.h) on scans with a known truth, made here with
 * the independent box integrator (fit/box.h, adaptive Gauss-Kronrod, not the design matrix the fit
 * uses): a 3 x 3 map under a spot 1.1x wider than written, scanned on a 9 x 9 grid shifted by
 * (-0.3, +0.2) um, with Gaussian noise of the shot+read model's sigma. Asserts: R, dx, dy recovered
 * within 3 sigma; over 24 noise seeds the pulls (fit - truth) / sigma have an rms between 0.6 and
 * 1.6 (the sigmas are honest); a scan with the written geometry gives dx, dy within 3 sigma of 0
 * and chi2_fitted <= chi2_fixed; the pipeline's geometry step is reported first in its progress
 * and the sweep then fits the geometry-corrected scan; bad r, too few points and a scan without
 * light are errors or flags, never a crash. */
#include <errno.h>
#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "fit/box.h"
#include "fit/geometry.h"
#include "fit/noise.h"
#include "fit/pipeline.h"

#define PITCH 6.0
#define R_WRITTEN 1.342
#define GRID 9
#define NPTS (GRID * GRID)
#define RM 3 /* the true map's resolution */
#define SEEDS 24

static const double true_map[RM * RM] = {0.8, 1.0, 0.9, 0.75, 1.1, 1.05, 0.85, 1.0, 0.95};

struct scan_buf {
    double x[NPTS], y[NPTS], model[NPTS], s[NPTS];
    fit_scan_t scan;
};

/* The noiseless signal (DN above bias) at the written grid for a spot of radius R at written
 * position + (dx, dy): I0 sum_ij S_ij * box integral of sub-pixel ij (eq. 3 by quadrature). */
static int make_model(double R, double dx, double dy, double I0, struct scan_buf *b)
{
    for (int j = 0; j < GRID; j++)
        for (int i = 0; i < GRID; i++) {
            int k = j * GRID + i;
            b->x[k] = PITCH / 2 + (i - (GRID - 1) / 2.0) * 0.6;
            b->y[k] = PITCH / 2 + (j - (GRID - 1) / 2.0) * 0.6;
            double m = 0;
            for (int c = 0; c < RM * RM; c++) {
                double cx = c % RM * PITCH / RM, cy = c / RM * PITCH / RM, v;
                fit_rect_t rect = {cx, cx + PITCH / RM, cy, cy + PITCH / RM};
                if (fit_box_integral(R, &rect, b->x[k] + dx, b->y[k] + dy, 1e-12, &v, NULL, NULL))
                    return -1;
                m += true_map[c] * v;
            }
            b->model[k] = I0 * m;
        }
    b->scan = (fit_scan_t){.n = NPTS, .x_um = b->x, .y_um = b->y, .signal_dn = b->s,
                           .pitch_um = PITCH, .spot_radius_um = R_WRITTEN, .bias_dn = 100,
                           .gain_e_per_dn = 3.0, .read_noise_e = 5.0, .frames = 12,
                           .full_scale_dn = 16383};
    return 0;
}

/* One noisy scan: the model plus Gaussian noise of the shot+read sigma at the model. */
static void add_noise(struct scan_buf *b, unsigned long seed)
{
    gsl_rng *rng = gsl_rng_alloc(gsl_rng_mt19937);
    gsl_rng_set(rng, seed);
    for (int k = 0; k < NPTS; k++) {
        double sig = fit_noise_sigma(FIT_NOISE_SHOT_READ, &b->scan, b->model[k] + 100);
        b->s[k] = b->model[k] + 100 + gsl_ran_gaussian_ziggurat(rng, sig);
    }
    gsl_rng_free(rng);
}

static fit_options_t shot_read(void)
{
    fit_options_t o = fit_options_default();
    o.noise = FIT_NOISE_SHOT_READ;
    return o;
}

/* ~1e4 DN in the middle of the pixel: the paper's signal level */
#define I0_DN 2000.0

static void offset_scan(void)
{
    const double R = 1.1 * R_WRITTEN, dx = -0.3, dy = 0.2;
    static struct scan_buf b;
    CHECK(make_model(R, dx, dy, I0_DN, &b) == 0);
    fit_options_t o = shot_read();
    double sum2[3] = {0};
    int ok = 0;
    for (unsigned long seed = 1; seed <= SEEDS; seed++) {
        add_noise(&b, seed);
        fit_geometry_t g;
        err_t err;
        int rc = fit_geometry_run(&b.scan, RM, &o, &g, &err);
        CHECK(rc == 0);
        if (rc) {
            fprintf(stderr, "seed %lu: %s\n", seed, err.msg);
            continue;
        }
        CHECK(g.flags == 0);
        CHECK(g.chi2_fitted <= g.chi2_fixed);
        double pull[3] = {(g.R_um - R) / g.R_err_um, (g.dx_um - dx) / g.dx_err_um,
                          (g.dy_um - dy) / g.dy_err_um};
        if (seed == 1) {
            printf("seed 1: R %.4f +- %.4f (true %.4f), dx %.4f +- %.4f, dy %.4f +- %.4f, "
                   "chi2 %.1f -> %.1f, %d iterations, %d designs\n",
                   g.R_um, g.R_err_um, R, g.dx_um, g.dx_err_um, g.dy_um, g.dy_err_um, g.chi2_fixed,
                   g.chi2_fitted, g.iterations, g.evaluations);
            for (int i = 0; i < 3; i++) CHECK(fabs(pull[i]) < 3);
            CHECK(g.R_written_um == R_WRITTEN);
            CHECK(g.params == RM * RM + 3);
            CHECK(g.n_used == NPTS);
        }
        for (int i = 0; i < 3; i++) sum2[i] += pull[i] * pull[i];
        ok++;
    }
    for (int i = 0; i < 3; i++) {
        double rms = sqrt(sum2[i] / ok);
        printf("rms pull of %s over %d seeds: %.3f\n", i == 0 ? "R" : i == 1 ? "dx" : "dy", ok, rms);
        CHECK(rms > 0.6 && rms < 1.6);
    }
}

static void no_offset_scan(void)
{
    static struct scan_buf b;
    CHECK(make_model(R_WRITTEN, 0, 0, I0_DN, &b) == 0);
    fit_options_t o = shot_read();
    for (unsigned long seed = 100; seed < 103; seed++) {
        add_noise(&b, seed);
        fit_geometry_t g;
        CHECK(fit_geometry_run(&b.scan, RM, &o, &g, NULL) == 0);
        CHECK(g.flags == 0);
        CHECK(fabs(g.dx_um) < 3 * g.dx_err_um);
        CHECK(fabs(g.dy_um) < 3 * g.dy_err_um);
        CHECK(fabs(g.R_um - R_WRITTEN) < 3 * g.R_err_um);
        CHECK(g.chi2_fitted <= g.chi2_fixed);
    }
}

/* ---- the pipeline step ---- */

static int first_kind = -1, steps_seen;

static void progress(int done, int total, const fit_step_t *step, void *params)
{
    (void)done, (void)total, (void)params;
    if (steps_seen++ == 0) first_kind = (int)step->kind;
}

static void pipeline_step(void)
{
    static struct scan_buf b;
    CHECK(make_model(1.1 * R_WRITTEN, -0.3, 0.2, I0_DN, &b) == 0);
    add_noise(&b, 7);
    fit_pipeline_opts_t po = fit_pipeline_opts_default();
    po.fit = shot_read();
    po.r_min = 2, po.r_max = 4;
    po.fit_geometry = 1, po.geometry_r = RM;
    fit_watch_t w = {.progress = progress};
    fit_pipeline_t pl, plain;
    err_t err;
    CHECK(fit_pipeline_run(&b.scan, &po, &w, &pl, &err) == 0);
    CHECK(first_kind == FIT_STEP_GEOMETRY);
    CHECK(steps_seen == 4); /* geometry + r = 2..4 */
    CHECK(strcmp(fit_step_name(FIT_STEP_GEOMETRY), "geometry") == 0);
    CHECK(pl.geometry_part.asked && pl.geometry_part.rc == 0);
    CHECK(fabs(pl.geometry.dx_um + 0.3) < 3 * pl.geometry.dx_err_um);
    /* the sweep fitted the corrected scan: at r = RM it is the true model, chi2 ~ N - p */
    po.fit_geometry = 0;
    CHECK(fit_pipeline_run(&b.scan, &po, NULL, &plain, &err) == 0);
    const fit_result_t *f = &pl.sweep.fits[RM - 2], *f0 = &plain.sweep.fits[RM - 2];
    printf("sweep chi2 at r = %d: %.1f written geometry, %.1f fitted (dof %zu)\n", RM, f0->chi2,
           f->chi2, f->n_used - (size_t)f->params);
    CHECK(f->chi2 < f->n_used - f->params + 5 * sqrt(2.0 * (f->n_used - f->params)));
    CHECK(f0->chi2 > 10 * f->chi2);
    CHECK(!plain.geometry_part.asked);
    fit_pipeline_free(&pl);
    fit_pipeline_free(&plain);
    po.fit_geometry = 1, po.geometry_r = 33;
    CHECK(fit_pipeline_run(&b.scan, &po, NULL, &pl, &err) == -EINVAL);
    CHECK(strstr(err.msg, "geometry_r") != NULL);
}

/* ---- failures are errors or flags ---- */

static void failures(void)
{
    static struct scan_buf b;
    CHECK(make_model(R_WRITTEN, 0, 0, I0_DN, &b) == 0);
    add_noise(&b, 3);
    fit_options_t o = shot_read();
    fit_geometry_t g;
    err_t err;
    CHECK(fit_geometry_run(&b.scan, 0, &o, &g, &err) == -EINVAL);
    CHECK(fit_geometry_run(&b.scan, 33, &o, &g, &err) == -EINVAL);
    /* 81 points cannot determine 9 x 9 + 3 parameters */
    CHECK(fit_geometry_run(&b.scan, 9, &o, &g, &err) == -ERANGE);
    CHECK(strstr(err.msg, "81") != NULL);
    /* no light: the geometry is not determined at all */
    for (int k = 0; k < NPTS; k++) b.s[k] = 100;
    int rc = fit_geometry_run(&b.scan, 2, &o, &g, &err);
    CHECK(rc != 0 || g.flags != 0);
    printf("no light: rc %d, status %s\n", rc, rc ? err.msg : fit_geometry_status(g.flags));
    /* a bad scan constant */
    b.scan.spot_radius_um = 0;
    CHECK(fit_geometry_run(&b.scan, 2, &o, &g, &err) == -EINVAL);
}

int main(void)
{
    offset_scan();
    no_offset_scan();
    pipeline_step();
    failures();
    CHECK_DONE();
}
