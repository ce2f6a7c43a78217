/* test_jitter.c: jitter photometry (fit/jitter.h) against independent values: the analytic
 * limits (a flat map adds no error; a PSF much larger than the pixel sees the map's mean; a PSF
 * much smaller than a cell sees the cell's S), the Airy cell sums against the adaptive box
 * integral (fit/box.h, GSL QAG: not the design-matrix path jitter.c uses), a Gaussian's mass by
 * hand, and a Monte Carlo on the simulated bench: random jitter positions, each pixel response
 * rendered by the simulator (instrument/sim.h, the paperlike scene and a uniform one), their
 * ratio against the predicted relative response, and noisy frames corrected by it. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/airy.h"
#include "fit/box.h"
#include "fit/jitter.h"
#include "instrument/cam.h"
#include "instrument/scene.h"
#include "instrument/sim.h"
#include "check.h"

#define P 6.0 /* pitch, um */
#define POI 128

static fit_jitter_setup_t one_pixel(const fit_jitter_pixel_t *px, fit_psf_kind_t kind, double w,
                                    double x0, double y0)
{
    return (fit_jitter_setup_t){
        .pitch_um = P, .psf = {kind, w}, .pixels = px, .n_pixels = 1, .x0_um = x0, .y0_um = y0};
}

/* A map with structure and a mean other than 1 (so "the mean" is not confused with 1). */
static void test_map(int r, double *S, double *mean)
{
    double s = 0;
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++) {
            S[j * r + i] = 1.1 + 0.3 * sin(1.7 * i + 0.4) * cos(0.9 * j) + (i == 0 ? -0.25 : 0);
            s += S[j * r + i];
        }
    *mean = s / (r * r);
}

/* A flat map adds no error: rho = 1 at every position, err 0, for both PSFs and with a flat
 * neighbour in the aperture. */
static void test_flat(void)
{
    double S[16];
    for (int k = 0; k < 16; k++)
        S[k] = 1;
    fit_jitter_pixel_t px[2] = {{0, 0, 4, S}, {1, 0, 0, NULL}};
    double dx[50], dy[50], rho[50], e[50];
    CHECK(fit_jitter_draw(0.5, 50, 7, dx, dy, NULL) == 0);
    for (int kind = 0; kind < 2; kind++) {
        fit_jitter_setup_t s = one_pixel(px, kind, 1.342, 3, 3);
        s.n_pixels = 2;
        fit_jitter_stats_t st;
        CHECK(fit_jitter_run(&s, dx, dy, 50, rho, e, &st, NULL) == 0);
        for (int k = 0; k < 50; k++)
            CHECK_NEAR(rho[k], 1, 1e-14, 0);
        CHECK(st.err_rms < 1e-14 && st.err_max < 1e-14 && st.rho_scatter < 1e-14);
        CHECK_NEAR(st.rho0, 1, 1e-14, 0);
        CHECK(st.flat_scatter > 0); /* the aperture's own loss is there, and is not IPS */
    }
}

/* A PSF much larger than the pixel: rho -> the map's mean. Gaussian sigma = 6 mm: the PSF's
 * curvature across the pixel is (p / sigma)^2 ~ 1e-6; Airy R = 300 um: the intensity varies by
 * ~(a p)^2 / 8 ~ 2e-3 ... over the pixel around the centre, its mean-centred part cancels to
 * second order, leaving ~1e-5. */
static void test_large_psf(void)
{
    double S[36], mean;
    test_map(6, S, &mean);
    fit_jitter_pixel_t px = {0, 0, 6, S};
    double x[3] = {3, 0.5, 4.1}, y[3] = {3, 5.0, 1.2}, fm[3], ff[3];
    fit_jitter_setup_t g = one_pixel(&px, FIT_PSF_GAUSS, 6000, 3, 3);
    CHECK(fit_jitter_flux(&g, x, y, 3, fm, ff, NULL) == 0);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(fm[k] / ff[k], mean, 1e-6, 0);
    fit_jitter_setup_t a = one_pixel(&px, FIT_PSF_AIRY, 300, 3, 3);
    CHECK(fit_jitter_flux(&a, x, y, 3, fm, ff, NULL) == 0);
    for (int k = 0; k < 3; k++)
        CHECK_NEAR(fm[k] / ff[k], mean, 1e-4, 0);
}

/* A PSF much smaller than a cell: rho -> S of the cell under the star. Gaussian sigma = 1 nm at
 * a cell centre 0.5 um from the cell's edges: exact to erfc(350) = 0. Airy R = 1 nm: the flux
 * outside the distance d = 0.5 um is q(a d) = J0^2 + J1^2 ~ 2 / (pi a d) = 1.7e-3 (airy.h), the
 * most the neighbouring cells can change rho (by at most max |S - S_ij| each). */
static void test_small_psf(void)
{
    double S[36], mean;
    test_map(6, S, &mean);
    fit_jitter_pixel_t px = {0, 0, 6, S};
    double x[4] = {0.5, 2.5, 5.5, 3.5}, y[4] = {0.5, 1.5, 5.5, 4.5}, fm[4], ff[4];
    int cell[4] = {0, 1 * 6 + 2, 5 * 6 + 5, 4 * 6 + 3};
    fit_jitter_setup_t g = one_pixel(&px, FIT_PSF_GAUSS, 1e-3, 0, 0);
    CHECK(fit_jitter_flux(&g, x, y, 4, fm, ff, NULL) == 0);
    for (int k = 0; k < 4; k++)
        CHECK_NEAR(fm[k] / ff[k], S[cell[k]], 1e-12, 0);
    fit_jitter_setup_t a = one_pixel(&px, FIT_PSF_AIRY, 1e-3, 0, 0);
    CHECK(fit_jitter_flux(&a, x, y, 4, fm, ff, NULL) == 0);
    double q, pin;
    fit_radial(fit_airy_a(1e-3) * 0.5, &q, &pin);
    CHECK(q < 2e-3);
    for (int k = 0; k < 4; k++)
        CHECK_NEAR(fm[k] / ff[k], S[cell[k]], 0, 0.7 * 2 * q);
}

/* A Gaussian at the pixel centre on a flat pixel: F_1 = erf(p / (2 sqrt 2 sigma))^2 (by hand). */
static void test_gauss_mass(void)
{
    fit_jitter_pixel_t px = {0, 0, 0, NULL};
    fit_jitter_setup_t g = one_pixel(&px, FIT_PSF_GAUSS, 2.0, 3, 3);
    double x = 3, y = 3, fm, ff;
    CHECK(fit_jitter_flux(&g, &x, &y, 1, &fm, &ff, NULL) == 0);
    double want = pow(erf(6.0 / (2 * M_SQRT2 * 2.0)), 2);
    CHECK_NEAR(ff, want, 1e-14, 0);
    CHECK_NEAR(fm, want, 1e-14, 0);
}

/* The Airy flux against a sum of adaptive box integrals (fit/box.h), over two pixels of the
 * aperture, the star inside, on an edge and outside the reference pixel. */
static void test_airy_vs_box(void)
{
    double S[25], T[9], mean;
    test_map(5, S, &mean);
    test_map(3, T, &mean);
    fit_jitter_pixel_t px[2] = {{0, 0, 5, S}, {-1, 1, 3, T}};
    fit_jitter_setup_t a = {
        .pitch_um = P, .psf = {FIT_PSF_AIRY, 1.342}, .pixels = px, .n_pixels = 2};
    double x[3] = {2.2, 0.0, -1.5}, y[3] = {3.7, 6.0, 7.2}, fm[3], ff[3];
    double tot = fit_airy_total(fit_airy_a(1.342));
    CHECK(fit_jitter_flux(&a, x, y, 3, fm, ff, NULL) == 0);
    for (int k = 0; k < 3; k++) {
        double sm = 0, sf = 0;
        for (int p = 0; p < 2; p++) {
            int r = px[p].r;
            double h = P / r, ox = px[p].dcol * P, oy = px[p].drow * P;
            for (int j = 0; j < r; j++)
                for (int i = 0; i < r; i++) {
                    fit_rect_t c = {ox + i * h, ox + (i + 1) * h, oy + j * h, oy + (j + 1) * h};
                    double v = NAN, eb;
                    CHECK(fit_box_integral(1.342, &c, x[k], y[k], 1e-13, &v, &eb, NULL) == 0);
                    sm += px[p].S[j * r + i] * v;
                    sf += v;
                }
        }
        CHECK_NEAR(fm[k], sm / tot, 1e-9, 1e-13);
        CHECK_NEAR(ff[k], sf / tot, 1e-9, 1e-13);
    }
}

/* Bad input names the field. */
static void test_errors(void)
{
    fit_jitter_pixel_t px = {0, 0, 0, NULL};
    fit_jitter_setup_t s = one_pixel(&px, FIT_PSF_AIRY, 0, 3, 3);
    double x = 3, y = 3, fm, dx[2] = {0, 0}, dy[2] = {0, 0}, rho[2] = {1, 0}, out[2];
    err_t err;
    CHECK(fit_jitter_flux(&s, &x, &y, 1, &fm, NULL, &err) == -EINVAL);
    CHECK(strstr(err.msg, "width_um") != NULL);
    s.psf.width_um = 1;
    s.pitch_um = -1;
    CHECK(fit_jitter_flux(&s, &x, &y, 1, &fm, NULL, &err) == -EINVAL);
    CHECK(strstr(err.msg, "pitch_um") != NULL);
    s.pitch_um = P;
    x = NAN;
    CHECK(fit_jitter_flux(&s, &x, &y, 1, &fm, NULL, &err) == -EINVAL);
    /* a star so far away that no light reaches the pixel (Gaussian: exactly 0) */
    s.psf = (fit_psf_t){FIT_PSF_GAUSS, 0.1};
    s.x0_um = 500;
    CHECK(fit_jitter_run(&s, dx, dy, 2, NULL, NULL, NULL, &err) == -ERANGE);
    CHECK(fit_jitter_correct(dx, rho, 2, out, &err) == -EINVAL);
    CHECK(strstr(err.msg, "rho[1]") != NULL);
    CHECK(fit_jitter_draw(-1, 2, 1, dx, dy, &err) == -EINVAL);
}

static sim_t *open_sim(const char *scene, int noiseless)
{
    sim_config_t c = sim_config_default();
    c.scene = scene;
    c.noiseless = noiseless;
    c.leave_out_tol = 0;
    c.design_tol = 1e-12;
    sim_t *s = NULL;
    err_t err;
    if (sim_open(&c, &s, &err)) fprintf(stderr, "sim_open: %s\n", err.msg);
    return s;
}

/* The Monte Carlo on the simulated bench: 300 random jitter positions around the POI's centre
 * (0.3 um rms), each rendered by the simulator on the paperlike pixel and on a uniform one; the
 * ratio of the two is the relative response the scene's map gives, which the prediction from the
 * scene's known map (its m x m cells) must reproduce sample by sample, and so its rms. Then noisy
 * frames at 100 of the positions (through the stage and camera: the spot's true position
 * read back, stage errors included): the measured signal corrected by the predicted rho is the
 * flat pixel's signal up to photon and read noise (a chi-square of the normalised residuals). */
static void test_sim_monte_carlo(void)
{
    sim_t *ps = open_sim("paperlike", 1), *us = open_sim("uniform", 1);
    CHECK(ps && us);
    if (!ps || !us) return;
    int m;
    const double *map = scene_map(sim_scene(ps), &m);
    double R = sim_spot_radius0(ps);
    enum { N = 300 };
    double dx[N], dy[N], rho[N], e[N];
    CHECK(fit_jitter_draw(0.3, N, 12, dx, dy, NULL) == 0);
    fit_jitter_pixel_t px = {0, 0, m, map};
    fit_jitter_setup_t s = one_pixel(&px, FIT_PSF_AIRY, R, 3, 3);
    fit_jitter_stats_t st;
    CHECK(fit_jitter_run(&s, dx, dy, N, rho, e, &st, NULL) == 0);
    cam_roi_t roi = {POI, POI, 1, 1};
    double es, eu, e0s, e0u, se2 = 0, worst = 0;
    CHECK(sim_expected(ps, POI * P + 3, POI * P + 3, R, &roi, &e0s, NULL, NULL) == 0);
    CHECK(sim_expected(us, POI * P + 3, POI * P + 3, R, &roi, &e0u, NULL, NULL) == 0);
    for (int k = 0; k < N; k++) {
        double xs = POI * P + 3 + dx[k], ys = POI * P + 3 + dy[k];
        CHECK(sim_expected(ps, xs, ys, R, &roi, &es, NULL, NULL) == 0);
        CHECK(sim_expected(us, xs, ys, R, &roi, &eu, NULL, NULL) == 0);
        double rk = es / eu, ek = rk / (e0s / e0u) - 1;
        worst = fmax(worst, fabs(rk - rho[k]));
        se2 += ek * ek;
    }
    CHECK(worst < 1e-8);
    CHECK_NEAR(st.err_rms, sqrt(se2 / N), 1e-6, 0);
    CHECK(st.err_rms > 1e-4); /* the paperlike pixel's structure does show */
    printf("paperlike, Airy R = %.4f um, jitter 0.3 um rms: flux error rms %.3g, max %.3g\n", R,
           st.err_rms, st.err_max);
    sim_close(us);

    /* noisy frames through the stage and the camera (the map stays ps's: borrowed) */
    sim_t *n = open_sim("paperlike", 0);
    CHECK(n != NULL);
    if (!n) {
        sim_close(ps);
        return;
    }
    enum { M = 100 };
    double xs[M], ys[M], meas[M], fm[M], ff[M], cor[M], rk[M];
    stage_pos_t c0 = sim_pixel_centre(n, POI, POI);
    cam_frame_t f;
    const double G = 3.153, B = 100, rn = 5.67;
    for (int k = 0; k < M; k++) {
        stage_pos_t c = c0;
        c.x_um += dx[k];
        c.y_um += dy[k];
        CHECK(stage_move(sim_stage(n), &c, NULL) == 0);
        double z;
        sim_spot(n, &xs[k], &ys[k], &z);
        xs[k] -= POI * P;
        ys[k] -= POI * P;
        CHECK(cam_capture(sim_camera(n), &roi, &f, NULL) == 0);
        meas[k] = (f.dn[0] - B) * G; /* electrons */
        cam_frame_free(&f);
    }
    CHECK(fit_jitter_flux(&s, xs, ys, M, fm, ff, NULL) == 0);
    for (int k = 0; k < M; k++)
        rk[k] = fm[k] / ff[k];
    CHECK(fit_jitter_correct(meas, rk, M, cor, NULL) == 0);
    /* corrected electrons = flux_e F_1 + noise of variance (flux_e F_S + rn^2 + G^2/12) / rho^2 */
    double flux = sim_config_default().flux_e, chi2 = 0, chi2_raw = 0;
    for (int k = 0; k < M; k++) {
        double var = (flux * fm[k] + rn * rn + G * G / 12) / (rk[k] * rk[k]);
        chi2 += pow(cor[k] - flux * ff[k], 2) / var;
        chi2_raw += pow(meas[k] - flux * ff[k] * st.rho0, 2) / var;
    }
    /* chi2 of M = 100 dof: mean 100, sd 14; < 160 fails by chance with p ~ 1e-5 */
    CHECK(chi2 > 50 && chi2 < 160);
    printf("noisy frames: chi2 of the corrected series %.1f (100 dof), uncorrected %.1f\n", chi2,
           chi2_raw);
    sim_close(n);
    sim_close(ps);
}

int main(void)
{
    test_flat();
    test_large_psf();
    test_small_psf();
    test_gauss_mass();
    test_airy_vs_box();
    test_errors();
    test_sim_monte_carlo();
    CHECK_DONE();
}
