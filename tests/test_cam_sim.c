/* test_cam_sim.c: the simulated camera and its optics (instrument/sim.h) against independent
 * references: noiseless pixel signals against fit_box_integral (uniform and paperlike pixels),
 * conservation of the spot's flux over a large sub-frame (against the box integral of the whole
 * region and the encircled-energy bounds), frame statistics (mean and variance against gain,
 * bias, shot and read noise by z and chi-square tests with a fixed seed), saturation, exposure
 * and gain scaling, defocus, the leave-out rule's bounds, the camera interface's errors, and the
 * fault switch with the frame timeout (a hang ended by the timeout, a failed capture). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>


#include "fit/airy.h"
#include "fit/box.h"
#include "instrument/cam.h"
#include "check.h"
#include "instrument/sim.h"

#define POI 128

static sim_t *open_sim(const char *scene, int noiseless, double tol)
{
    sim_config_t c = sim_config_default();
    c.scene = scene;
    c.noiseless = noiseless;
    c.leave_out_tol = tol;
    c.design_tol = 1e-12;
    sim_t *s = NULL;
    err_t err;
    if (sim_open(&c, &s, &err)) fprintf(stderr, "sim_open: %s\n", err.msg);
    return s;
}

static double box(double R, double x0, double x1, double y0, double y1, double u, double v)
{
    fit_rect_t r = {x0, x1, y0, y1};
    double val = NAN, eb;
    fit_box_integral(R, &r, u, v, 1e-14, &val, &eb, NULL);
    return val;
}

/* Electrons a uniform pixel gets from a spot at (u, v) relative to its corner (sim.h photometry).
 */
static double electrons(double flux, double R, double u, double v)
{
    return flux * box(R, 0, 6, 0, 6, u, v) / fit_airy_total(fit_airy_a(R));
}

static void test_uniform_vs_box(void)
{
    sim_t *s = open_sim("uniform", 1, 0);
    double R = sim_spot_radius0(s), flux = sim_config_default().flux_e, e;
    CHECK_NEAR(R, 1.22 * 0.55 / (2 * 0.25), 1e-15, 0); /* eq. 1 */
    double pos[][2] = {{3, 3},     {0.6, 0.6}, {0, 3},   {6, 6},
                       {5.4, 0.6}, {-2.5, 3},  {15, -9}, {3.3, 2.7}};
    cam_roi_t roi = {POI, POI, 1, 1};
    for (size_t k = 0; k < sizeof pos / sizeof pos[0]; k++) {
        double u = pos[k][0], v = pos[k][1];
        CHECK(sim_expected(s, POI * 6.0 + u, POI * 6.0 + v, R, &roi, &e, NULL, NULL) == 0);
        CHECK_NEAR(e, electrons(flux, R, u, v), 1e-9, 1e-12 * flux);
    }
    /* through the camera: expected_dn = B + e / G, and the noiseless frame is its rounding */
    stage_pos_t c = sim_pixel_centre(s, POI, POI);
    c.x_um += 0.3;
    CHECK(stage_move(sim_stage(s), &c, NULL) == 0);
    cam_frame_t f;
    CHECK(cam_capture(sim_camera(s), &roi, &f, NULL) == 0);
    double want = 100 + electrons(flux, R, 3.3, 3) / 3.153;
    CHECK_NEAR(f.expected_dn[0], want, 1e-9, 0);
    CHECK(f.dn[0] == (uint16_t)nearbyint(want));
    cam_frame_free(&f);
    sim_close(s);
}

/* The paperlike pixel: sum over its 30 x 30 cells of S_c times the cell's box integral. */
static void test_paperlike_vs_box(void)
{
    sim_t *s = open_sim("paperlike", 1, 0);
    int m;
    const double *map = scene_map(sim_scene(s), &m);
    double R = sim_spot_radius0(s), flux = sim_config_default().flux_e, h = 6.0 / m, e;
    double pos[][2] = {{3, 3}, {0.4, 2.0}, {-1.0, 5.8}};
    cam_roi_t roi = {POI, POI, 1, 1};
    for (size_t k = 0; k < sizeof pos / sizeof pos[0]; k++) {
        double u = pos[k][0], v = pos[k][1], acc = 0;
        for (int j = 0; j < m; j++)
            for (int i = 0; i < m; i++)
                acc += map[j * m + i] * box(R, i * h, (i + 1) * h, j * h, (j + 1) * h, u, v);
        CHECK(sim_expected(s, POI * 6.0 + u, POI * 6.0 + v, R, &roi, &e, NULL, NULL) == 0);
        CHECK_NEAR(e, flux * acc / fit_airy_total(fit_airy_a(R)), 1e-9, 0);
    }
    sim_close(s);
}

/* Flux conservation on a uniform sensor: the 41 x 41 sub-frame around the spot receives exactly
 * the box integral of its whole area, which lies between the encircled energies of its inscribed
 * and circumscribed discs (Rayleigh: 1 - J0^2 - J1^2), i.e. all but ~0.2 % of the flux. */
static void test_flux_conservation(void)
{
    sim_t *s = open_sim("uniform", 1, 0);
    double R = sim_spot_radius0(s), a = fit_airy_a(R), flux = sim_config_default().flux_e;
    int n = 41, h = n / 2;
    cam_roi_t roi = {POI - h, POI - h, n, n};
    double *e = malloc(sizeof(double) * n * n), sum = 0, xs = POI * 6.0 + 3, ys = POI * 6.0 + 3;
    CHECK(sim_expected(s, xs, ys, R, &roi, e, NULL, NULL) == 0);
    for (int k = 0; k < n * n; k++)
        sum += e[k];
    double x0 = (POI - h) * 6.0, x1 = (POI + h + 1) * 6.0;
    double whole = flux * box(R, x0, x1, x0, x1, xs, ys) / fit_airy_total(a);
    CHECK_NEAR(sum, whole, 1e-9, 0);
    double rin = xs - x0, q, p_in, p_out;
    fit_radial(a * rin, &q, &p_in);
    fit_radial(a * rin * sqrt(2), &q, &p_out);
    CHECK(sum >= flux * p_in * (1 - 1e-12) && sum <= flux * p_out * (1 + 1e-12));
    CHECK(sum > 0.997 * flux && sum < flux);
    /* the leave-out rule: every pixel within the bound the simulator reports */
    sim_t *t = open_sim("uniform", 1, 1e-4);
    double *et = malloc(sizeof(double) * n * n), bound, worst = 0;
    CHECK(sim_expected(t, xs, ys, R, &roi, et, &bound, NULL) == 0);
    for (int k = 0; k < n * n; k++)
        worst = fmax(worst, fabs(et[k] - e[k]));
    CHECK(bound > 0 && bound <= 1e-4 * flux);
    CHECK(worst <= bound);
    CHECK(et[h * n + h] == e[h * n + h]); /* the POI itself is always integrated */
    sim_stats_t st;
    sim_get_stats(t, &st);
    CHECK(st.left_out > 0);
    free(e);
    free(et);
    sim_close(s);
    sim_close(t);
}

/* Mean and variance of one pixel over many frames: mean B + lambda / G, variance
 * (lambda + sigma_r^2) / G^2 + 1/12 (Poisson shot noise, Gaussian read noise, rounding). */
static void check_stats(const double *x, int n, double lambda, const char *what)
{
    double sum = 0, sq = 0;
    for (int k = 0; k < n; k++)
        sum += x[k];
    double mean = sum / n;
    for (int k = 0; k < n; k++)
        sq += (x[k] - mean) * (x[k] - mean);
    double var = sq / (n - 1), G = 3.153, rn = 5.67;
    double mu = 100 + lambda / G, sig2 = (lambda + rn * rn) / (G * G) + 1.0 / 12;
    double z_mean = (mean - mu) / sqrt(sig2 / n);
    double z_var = ((n - 1) * var / sig2 - (n - 1)) / sqrt(2.0 * (n - 1));
    printf("%s: lambda %.1f e-: mean %.3f (want %.3f, z %.2f), var %.3f (want %.3f, z %.2f)\n",
           what, lambda, mean, mu, z_mean, var, sig2, z_var);
    CHECK(fabs(z_mean) < 4);
    CHECK(fabs(z_var) < 4);
}

static void test_frame_statistics(void)
{
    sim_t *s = open_sim("uniform", 0, 1e-4);
    double R = sim_spot_radius0(s), flux = sim_config_default().flux_e;
    stage_pos_t c = sim_pixel_centre(s, POI, POI);
    CHECK(stage_move(sim_stage(s), &c, NULL) == 0);
    int n = 4000;
    double *poi = malloc(sizeof(double) * n), *corner = malloc(sizeof(double) * n);
    double *dark = malloc(sizeof(double) * n);
    cam_roi_t roi = {POI - 1, POI - 1, 3, 3}, far = {POI + 40, POI - 40, 1, 1};
    cam_frame_t f;
    for (int k = 0; k < n; k++) {
        CHECK(cam_capture(sim_camera(s), &roi, &f, NULL) == 0);
        poi[k] = f.dn[4];
        corner[k] = f.dn[0];
        cam_frame_free(&f);
        CHECK(cam_capture(sim_camera(s), &far, &f, NULL) == 0);
        dark[k] = f.dn[0];
        cam_frame_free(&f);
    }
    check_stats(poi, n, electrons(flux, R, 3, 3), "POI");
    check_stats(corner, n, electrons(flux, R, 9, 9), "corner neighbour");
    check_stats(dark, n, 0, "dark pixel (left out)");
    free(poi);
    free(corner);
    free(dark);
    sim_close(s);
}

static void test_exposure_gain_saturation(void)
{
    sim_t *s = open_sim("uniform", 1, 1e-4);
    cam_t *cam = sim_camera(s);
    stage_pos_t c = sim_pixel_centre(s, POI, POI);
    stage_move(sim_stage(s), &c, NULL);
    cam_roi_t roi = {POI, POI, 1, 1};
    cam_frame_t f;
    CHECK(cam_capture(cam, &roi, &f, NULL) == 0);
    double base = f.expected_dn[0] - 100;
    int64_t t0 = f.timestamp_ns;
    cam_frame_free(&f);
    CHECK(cam_set_exposure(cam, 20000, NULL) == 0 && cam_set_gain(cam, 2, NULL) == 0);
    CHECK(cam_capture(cam, &roi, &f, NULL) == 0);
    CHECK_NEAR(f.expected_dn[0] - 100, 4 * base, 1e-12, 0); /* twice the light, twice the DN/e- */
    CHECK(f.exposure_us == 20000 && f.gain == 2);
    CHECK(f.timestamp_ns - t0 == 10000000 + 20000000); /* the first frame's exposure + read-out */
    CHECK(f.sequence == 1 && f.temperature_c == 25);
    cam_frame_free(&f);
    /* saturation: 10x the light overfills the ADC: clipped at full scale */
    CHECK(cam_set_exposure(cam, 100000, NULL) == 0 && cam_set_gain(cam, 1, NULL) == 0);
    CHECK(cam_capture(cam, &roi, &f, NULL) == 0);
    CHECK(f.dn[0] == 16383 && f.expected_dn[0] > 16383);
    cam_frame_free(&f);
    err_t err;
    CHECK(cam_set_exposure(cam, 0, &err) == -ERANGE && strstr(err.msg, "exposure"));
    CHECK(cam_set_gain(cam, 100, &err) == -ERANGE);
    cam_roi_t bad = {250, 250, 10, 10};
    CHECK(cam_capture(cam, &bad, &f, &err) == -EINVAL && strstr(err.msg, "outside"));
    CHECK(f.dn == NULL);
    sim_close(s);
}

/* Defocus: at z = z_focus + zR (zR = lambda / (2 NA^2) = 4.4 um) the spot radius is sqrt(2) R0,
 * and the pixel gets the box integral of that wider Airy. */
static void test_defocus(void)
{
    sim_t *s = open_sim("uniform", 1, 0);
    double zr = 0.55 / (2 * 0.25 * 0.25), R0 = sim_spot_radius0(s),
           flux = sim_config_default().flux_e;
    CHECK_NEAR(sim_spot_radius(s, zr), R0 * sqrt(2), 1e-14, 0);
    CHECK_NEAR(sim_focus_tolerance(s), zr * sqrt(1.01 * 1.01 - 1), 1e-14, 0);
    stage_pos_t c = sim_pixel_centre(s, POI, POI);
    c.z_um = -zr;
    stage_move(sim_stage(s), &c, NULL);
    cam_roi_t roi = {POI, POI, 1, 1};
    cam_frame_t f;
    CHECK(cam_capture(sim_camera(s), &roi, &f, NULL) == 0);
    CHECK_NEAR(f.expected_dn[0], 100 + electrons(flux, R0 * sqrt(2), 3, 3) / 3.153, 1e-9, 0);
    cam_frame_free(&f);
    sim_close(s);
}

static void test_interface(void)
{
    cam_t *cam;
    err_t err;
    cam_info_t *list, info;
    size_t n;
    CHECK(cam_list("sim", &list, &n, NULL) == 0 && n == 2);
    free(list);
    CHECK(cam_open("sim", "uniform", &cam, &err) == 0);
    CHECK(cam_get_info(cam, &info, NULL) == 0);
    CHECK(strcmp(info.backend, "sim") == 0 && info.width == 256 && info.pitch_um == 6);
    CHECK(sim_of_camera(cam) != NULL);
    cam_frame_t f;
    CHECK(cam_capture(cam, NULL, &f, NULL) == 0 && f.roi.width == 256 && f.roi.height == 256);
    CHECK(f.left_out_dn > 0); /* most of a 256 x 256 frame is left out */
    cam_frame_free(&f);
    cam_close(cam);
    CHECK(cam_open("sim", "map:/nonexistent.json", &cam, &err) == -ENOENT);
    cam_close(NULL);
    sim_config_t c = sim_config_default();
    c.na = 2;
    sim_t *s;
    CHECK(sim_open(&c, &s, &err) == -EINVAL && strstr(err.msg, "aperture"));
}

/* The fault switch of test_faults (ctx: its count of questions): the camera hangs at the 2nd
 * capture and fails the 4th; frame is the number of frames delivered before. */
static int fault_switch(void *ctx, unsigned long long frame)
{
    int n = ++*(int *)ctx;
    CHECK(frame == (unsigned long long)(n - 1 - (n > 2) - (n > 4)));
    return n == 2 ? SIM_FRAME_HANG : n == 4 ? SIM_FRAME_FAIL : SIM_FRAME_OK;
}

static void test_faults(void)
{
    sim_config_t c = sim_config_default();
    int asked = 0;
    c.frame_fault = fault_switch;
    c.frame_fault_ctx = &asked;
    sim_t *s;
    err_t err = {{0}};
    CHECK(sim_open(&c, &s, &err) == 0);
    cam_t *cam = sim_camera(s);
    cam_roi_t roi = {POI, POI, 1, 1};
    cam_frame_t f;
    CHECK(cam_set_timeout(cam, -1, &err) == -EINVAL);
    CHECK(cam_set_timeout(cam, 0.01, &err) == 0);
    CHECK(cam_capture(cam, &roi, &f, &err) == 0);
    cam_frame_free(&f);
    /* the hang is ended by the timeout, with the camera's error naming it */
    CHECK(cam_capture(cam, &roi, &f, &err) == -ETIMEDOUT &&
          strstr(err.msg, "no frame within 0.01 s") && strstr(err.msg, "frame 2"));
    CHECK(f.dn == NULL);
    CHECK(cam_capture(cam, &roi, &f, &err) == 0); /* the next frame comes again */
    cam_frame_free(&f);
    CHECK(cam_capture(cam, &roi, &f, &err) == -EIO && strstr(err.msg, "frame 3"));
    CHECK(cam_capture(cam, &roi, &f, &err) == 0);
    cam_frame_free(&f);
    CHECK(asked == 5);
    sim_close(s);
}

int main(void)
{
    test_uniform_vs_box();
    test_paperlike_vs_box();
    test_flux_conservation();
    test_frame_statistics();
    test_exposure_gain_saturation();
    test_defocus();
    test_interface();
    test_faults();
    CHECK_DONE();
}
