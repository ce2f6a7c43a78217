/* test_ptc_sim.c: the photon-transfer measurement (instrument/ptc_run.h + fit/ptc.h) on the
 * simulated bench against the simulator's known truth: for several sensors, the measured gain
 * and read noise within 2 % of the configured ones, the saturation near the clip the simulator
 * applies (ADC full scale or full well), and the analytic limit of a noise-free bench (no
 * temporal variance at all, means equal to the rounded expected DN).
 *
 * Statistics: a pair's variance from N pixels has a relative standard error sqrt(2/N); with
 * N = 128^2 = 16384 that is 1.1 % per level, and the gain is fitted through ~28 levels (~0.2 %),
 * the dark variance through 40 (read noise ~0.3 % with the gain's): 2 % is beyond 6 sigma. */
#include <math.h>
#include <stdio.h>

#include "check.h"
#include "fit/ptc.h"
#include "instrument/ptc_run.h"
#include "instrument/sim.h"

#define LEVELS 40
#define ROI 128

static sim_t *bench(double G, double rn, double full_well, int noiseless, double *flat_e)
{
    sim_config_t cfg = sim_config_default();
    cfg.scene = "uniform";
    cfg.flux_e = 0;
    cfg.noiseless = noiseless;
    cfg.sensor.gain_e_per_dn = G;
    cfg.sensor.read_noise_e = rn;
    cfg.sensor.full_well_e = full_well;
    /* saturation charge: the first of the ADC clip and the full well (sim.h) */
    *flat_e = fmin(full_well, (cfg.sensor.full_scale_dn - cfg.sensor.bias_dn) * G);
    cfg.flat_e = 0;
    sim_t *sim = NULL;
    err_t err;
    if (sim_open(&cfg, &sim, &err)) fprintf(stderr, "sim_open: %s\n", err.msg);
    return sim;
}

static int run(sim_t *sim, double flat_e, fit_ptc_level_t *lv)
{
    ptc_sim_lamp_t lamp = {sim, flat_e};
    ptc_run_config_t rc = {.roi = {0, 0, ROI, ROI}, .levels = LEVELS, .exposure_max_us = 12500};
    err_t err;
    int r = ptc_run(sim_camera(sim), ptc_sim_light, &lamp, &rc, NULL, NULL, lv, &err);
    if (r) fprintf(stderr, "ptc_run: %s\n", err.msg);
    return r;
}

static void sensor_case(double G, double rn, double full_well)
{
    double flat_e;
    sim_t *sim = bench(G, rn, full_well, 0, &flat_e);
    CHECK(sim != NULL);
    if (!sim) return;
    fit_ptc_level_t lv[LEVELS];
    CHECK(run(sim, flat_e, lv) == 0);
    fit_ptc_result_t r;
    CHECK(fit_ptc_analyse(lv, LEVELS, &r) == 0);
    printf("G %.4g e-/DN -> %.4f (%+.2f %%), read noise %.4g e- -> %.4f (%+.2f %%), "
           "saturation %.0f DN (clip %.0f), linearity %.3f %%\n",
           G, r.gain_e_per_dn, 100 * (r.gain_e_per_dn / G - 1), rn, r.read_noise_e,
           100 * (r.read_noise_e / rn - 1), r.saturation_dn, flat_e / G, r.linearity_error_pct);
    CHECK_NEAR(r.gain_e_per_dn, G, 0.02, 0);
    CHECK_NEAR(r.read_noise_e, rn, 0.02, 0);
    CHECK_NEAR(r.dark_dn, 100, 0, 0.05); /* the bias: read noise averages out over the frames */
    /* the variance peaks within a few shot-noise sigmas below the clip, and the levels are
     * 1/32 of the clip apart: 5 % */
    CHECK_NEAR(r.saturation_dn, flat_e / G, 0.05, 0);
    CHECK(r.saturation_dn <= flat_e / G);
    /* the simulator is exactly linear below the clip: only the noise of the means remains */
    CHECK(r.linearity_error_pct < 0.1);
    sim_close(sim);
}

/* No photon or read noise: A and B are the same frame, so every temporal variance is 0 exactly,
 * and each mean is the rounded expected DN (bias + flat t / t_ref / G, sim.h), which the analysis
 * refuses (no photon-transfer slope). */
static void noiseless_case(void)
{
    double flat_e, G = 3.153;
    sim_t *sim = bench(G, 5.67, 60000, 1, &flat_e);
    CHECK(sim != NULL);
    if (!sim) return;
    fit_ptc_level_t lv[LEVELS];
    CHECK(run(sim, flat_e, lv) == 0);
    for (int i = 0; i < LEVELS; i++) {
        double e = flat_e * lv[i].exposure_us / 10000;
        double want = fmin(nearbyint(100 + e / G), 16383);
        CHECK(lv[i].s2_y == 0 && lv[i].s2_dark == 0);
        CHECK(lv[i].mu_y == want);
        CHECK(lv[i].mu_dark == 100);
    }
    fit_ptc_result_t r;
    CHECK(fit_ptc_analyse(lv, LEVELS, &r) != 0);
    sim_close(sim);
}

int main(void)
{
    sensor_case(3.153, 5.67, 60000); /* the paper's sensor: ADC-clip limited */
    sensor_case(1.5, 2.5, 60000);    /* a low-noise sensor, 1.7 DN of read noise */
    sensor_case(6.0, 12.0, 60000);   /* full-well limited: 60000 e- = 10000 DN < the clip */
    noiseless_case();
    CHECK_DONE();
}
