/* test_stage.c: the motion stage interface and the simulated stage (instrument/stage.h): moves,
 * limits, homing, the virtual clock, the positioning error's statistics and the thermal drift's
 * warm-up curve (the paper pre-warms its lamp for 4 h). */
#include <errno.h>
#include <math.h>
#include <string.h>


#include "check.h"
#include "instrument/stage.h"

static void test_moves(void)
{
    stage_t *st;
    err_t err;
    CHECK(stage_open("nope", NULL, &st, &err) == -EINVAL && strstr(err.msg, "nope"));
    CHECK(stage_open("sim", NULL, &st, &err) == 0);
    stage_pos_t p, t = {1234.5, -20.25, 3.0}, truth;
    CHECK(stage_get_position(st, &p, NULL) == 0 && p.x_um == 0 && p.y_um == 0 && p.z_um == 0);
    double t0, t1;
    CHECK(stage_sim_clock(st, &t0) == 0);
    CHECK(stage_move(st, &t, NULL) == 0);
    CHECK(stage_get_position(st, &p, NULL) == 0);
    CHECK(p.x_um == t.x_um && p.y_um == t.y_um && p.z_um == t.z_um);
    CHECK(stage_sim_true_position(st, &truth) == 0 && truth.x_um == t.x_um); /* no errors set */
    /* the clock: settle 0.05 s + distance / 1000 um/s */
    CHECK(stage_sim_clock(st, &t1) == 0);
    CHECK_NEAR(t1 - t0, 0.05 + sqrt(1234.5 * 1234.5 + 20.25 * 20.25 + 9) / 1000, 1e-12, 0);
    CHECK(stage_sim_advance(st, 2.5) == 0 && stage_sim_clock(st, &t0) == 0);
    CHECK_NEAR(t0, t1 + 2.5, 1e-12, 0);
    CHECK(stage_sim_advance(st, -1) == -EINVAL);
    /* outside the travel: refused, and the stage stays */
    stage_limits_t lim;
    CHECK(stage_get_limits(st, &lim, NULL) == 0);
    stage_pos_t far = {lim.max.x_um + 1, 0, 0};
    CHECK(stage_move(st, &far, &err) == -ERANGE && strstr(err.msg, "x ="));
    far = (stage_pos_t){0, 0, NAN};
    CHECK(stage_move(st, &far, &err) == -EINVAL);
    CHECK(stage_get_position(st, &p, NULL) == 0 && p.x_um == t.x_um);
    CHECK(stage_home(st, NULL) == 0 && stage_get_position(st, &p, NULL) == 0);
    CHECK(p.x_um == 0 && p.y_um == 0 && p.z_um == 0);
    stage_close(st);
    stage_close(NULL);
    stage_sim_config_t bad = stage_sim_config_default();
    bad.position_sigma_um = -1;
    CHECK(stage_open_sim(&bad, &st, &err) == -EINVAL);
}

/* The positioning error: independent N(0, sigma) per axis and move. Sample mean by a z test,
 * sample variance by the chi-square statistic (n-1) s^2 / sigma^2 ~ chi2(n-1) as a z score. */
static void test_positioning_error(void)
{
    stage_sim_config_t cfg = stage_sim_config_default();
    cfg.position_sigma_um = 0.1;
    cfg.seed = 7;
    stage_t *st;
    CHECK(stage_open_sim(&cfg, &st, NULL) == 0);
    int n = 4000;
    double sum[3] = {0}, sq[3] = {0};
    for (int k = 0; k < n; k++) {
        stage_pos_t t = {k % 17, -(k % 5), 0.5 * (k % 3)}, tr;
        CHECK(stage_move(st, &t, NULL) == 0);
        stage_sim_true_position(st, &tr);
        double e[3] = {tr.x_um - t.x_um, tr.y_um - t.y_um, tr.z_um - t.z_um};
        for (int a = 0; a < 3; a++)
            sum[a] += e[a], sq[a] += e[a] * e[a];
    }
    for (int a = 0; a < 3; a++) {
        double mean = sum[a] / n, var = (sq[a] - n * mean * mean) / (n - 1);
        double z_mean = mean / (0.1 / sqrt(n));
        double z_var = ((n - 1) * var / 0.01 - (n - 1)) / sqrt(2.0 * (n - 1));
        CHECK(fabs(z_mean) < 4);
        CHECK(fabs(z_var) < 4);
    }
    stage_close(st);
}

/* Drift d(t) = A (1 - exp(-t / tau)) from switching the lamp on. */
static void test_drift(void)
{
    stage_sim_config_t cfg = stage_sim_config_default();
    cfg.drift_um[0] = 2, cfg.drift_um[1] = -1, cfg.drift_um[2] = 5;
    cfg.drift_tau_s = 3600;
    stage_t *st;
    CHECK(stage_open_sim(&cfg, &st, NULL) == 0);
    stage_pos_t tr;
    stage_sim_true_position(st, &tr);
    CHECK(tr.x_um == 0 && tr.z_um == 0); /* just switched on */
    stage_sim_advance(st, 3600);
    stage_sim_true_position(st, &tr);
    CHECK_NEAR(tr.x_um, 2 * (1 - exp(-1.0)), 1e-12, 0);
    CHECK_NEAR(tr.y_um, -1 * (1 - exp(-1.0)), 1e-12, 0);
    CHECK_NEAR(tr.z_um, 5 * (1 - exp(-1.0)), 1e-12, 0);
    stage_close(st);
    /* pre-warmed 4 h: a 1 h scan then sees the drift move by A e^-4 (1 - e^-1) < 1.2 % of A,
     * against 63 % for a cold start */
    cfg.prewarm_s = 4 * 3600;
    CHECK(stage_open_sim(&cfg, &st, NULL) == 0);
    stage_pos_t a, b;
    stage_sim_true_position(st, &a);
    stage_sim_advance(st, 3600);
    stage_sim_true_position(st, &b);
    CHECK_NEAR(b.z_um - a.z_um, 5 * exp(-4.0) * (1 - exp(-1.0)), 1e-12, 0);
    CHECK(fabs(b.z_um - a.z_um) < 0.012 * 5);
    stage_close(st);
}

int main(void)
{
    test_moves();
    test_positioning_error();
    test_drift();
    CHECK_DONE();
}
