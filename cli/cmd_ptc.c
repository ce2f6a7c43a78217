/* cmd_ptc.c: `ips ptc --sim [options]`: the photon-transfer measurement (EMVA 1288) on the
 * simulated bench: a uniform flat field (sim_set_flat) at a series of exposures, a pair of flats
 * and a pair of darks at each (instrument/ptc_run.h), analysed by fit/ptc.h. Prints one JSON
 * object: the bench's true sensor constants, the measured gain, read noise, dark level,
 * saturation and linearity error, and the per-level table (docs/contracts.md). The lamp's
 * default makes the longest exposure 1.25 times the sensor's saturation charge, so the series
 * crosses saturation. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include <jansson.h>

#include "base/opts.h"
#include "cliutil.h"
#include "commands.h"
#include "fit/ptc.h"
#include "instrument/ptc_run.h"
#include "instrument/sim.h"
#include "json/fitjson.h"
#include "json/ptcjson.h"

#define DEFAULT_LEVELS 40

enum {
    OPT_SIM = 1000,
    OPT_GAIN,
    OPT_READ_NOISE,
    OPT_BIAS,
    OPT_FULL_SCALE,
    OPT_FULL_WELL,
    OPT_LEVELS,
    OPT_ROI,
    OPT_FLAT,
    OPT_SEED,
    OPT_NOISELESS,
    OPT_HELP
};

static const struct option long_opts[] = {
    {"sim", no_argument, NULL, OPT_SIM},
    {"gain", required_argument, NULL, OPT_GAIN},
    {"read-noise", required_argument, NULL, OPT_READ_NOISE},
    {"bias", required_argument, NULL, OPT_BIAS},
    {"full-scale", required_argument, NULL, OPT_FULL_SCALE},
    {"full-well", required_argument, NULL, OPT_FULL_WELL},
    {"levels", required_argument, NULL, OPT_LEVELS},
    {"roi", required_argument, NULL, OPT_ROI},
    {"flat-e", required_argument, NULL, OPT_FLAT},
    {"seed", required_argument, NULL, OPT_SEED},
    {"noiseless", no_argument, NULL, OPT_NOISELESS},
    {"help", no_argument, NULL, OPT_HELP},
    {NULL, 0, NULL, 0},
};

static const char usage[] =
    "usage: ips ptc --sim [options]\n"
    "  Photon transfer (EMVA 1288) on the simulated bench: pairs of flats and darks at LEVELS\n"
    "  exposures, the system gain, read noise, dark level, saturation and linearity, as JSON.\n"
    "  --sim               measure the simulated bench (required: the only bench for now)\n"
    "  --gain G            the simulated sensor's conversion gain, e-/DN (default 3.153)\n"
    "  --read-noise E      its read noise, e- rms (default 5.67)\n"
    "  --bias DN           its ADC offset (default 100)\n"
    "  --full-scale DN     its ADC clip (default 16383)\n"
    "  --full-well E       its full well, e- (default 60000)\n"
    "  --levels N          exposures in the series, 3..1000 (default 40)\n"
    "  --roi N             measure the N x N pixels at the array's corner (default 256: all)\n"
    "  --flat-e E          lamp: e- per pixel at the 10 ms reference exposure (default the\n"
    "                      saturation charge, min(full well, (full scale - bias) G)); the\n"
    "                      series runs to 12.5 ms\n"
    "  --seed N            seed of the noise (default 1)\n"
    "  --noiseless         no photon or read noise (the ADC rounding stays)\n";

struct ptc_args {
    int sim, levels, roi, noiseless;
    double flat_e;
    long long seed;
    scene_sensor_t sensor;
};

static int parse_opt(int c, const char *arg, void *user, err_t *err)
{
    struct ptc_args *a = user;
    scene_sensor_t *s = &a->sensor;
    switch (c) {
    case OPT_SIM:
        a->sim = 1;
        return 0;
    case OPT_NOISELESS:
        a->noiseless = 1;
        return 0;
    case OPT_GAIN:
        return opts_num("gain", arg, 1e-3, 1e4, &s->gain_e_per_dn, err);
    case OPT_READ_NOISE:
        return opts_num("read-noise", arg, 0, 1e4, &s->read_noise_e, err);
    case OPT_BIAS:
        return opts_num("bias", arg, 0, 60000, &s->bias_dn, err);
    case OPT_FULL_SCALE:
        return opts_num("full-scale", arg, 1, 65535, &s->full_scale_dn, err);
    case OPT_FULL_WELL:
        return opts_num("full-well", arg, 1, 1e9, &s->full_well_e, err);
    case OPT_LEVELS:
        return opts_int32("levels", arg, PTC_LEVELS_MIN, PTC_LEVELS_MAX, &a->levels, err);
    case OPT_ROI:
        return opts_int32("roi", arg, 2, 4096, &a->roi, err);
    case OPT_FLAT:
        return opts_num("flat-e", arg, 1e-6, 1e12, &a->flat_e, err);
    case OPT_SEED:
        return opts_int("seed", arg, 0, 4294967295LL, &a->seed, err);
    default:
        return err_set(err, -EINVAL, "unhandled option");
    }
}

static int report(const struct ptc_args *a, const sim_config_t *cfg, const fit_ptc_result_t *r,
                  const fit_ptc_level_t *lv)
{
    json_t *doc = ptcjson_result(r, lv, (size_t)a->levels);
    json_t *truth = json_pack(
        "{s:o, s:o, s:o, s:o, s:o, s:o, s:i, s:i, s:b}", "gain_e_per_dn",
        fitjson_num(cfg->sensor.gain_e_per_dn), "read_noise_e",
        fitjson_num(cfg->sensor.read_noise_e), "bias_dn", fitjson_num(cfg->sensor.bias_dn),
        "full_scale_dn", fitjson_num(cfg->sensor.full_scale_dn), "full_well_e",
        fitjson_num(cfg->sensor.full_well_e), "flat_e", fitjson_num(cfg->flat_e), "pixels",
        a->roi * a->roi, "levels", a->levels, "noiseless", a->noiseless);
    if (!doc || !truth || json_object_set_new(doc, "bench", truth)) {
        json_decref(doc);
        return cli_fail(CLI_EXIT_FAILURE, "ptc", "out of memory for the report");
    }
    int rc = json_dumpf(doc, stdout, JSON_INDENT(2) | JSON_REAL_PRECISION(17));
    json_decref(doc);
    if (rc || fputc('\n', stdout) == EOF || fflush(stdout))
        return cli_fail(CLI_EXIT_FAILURE, "ptc", "cannot write the report");
    return 0;
}

int cmd_ptc(int argc, char **argv)
{
    struct ptc_args a = {.levels = DEFAULT_LEVELS, .seed = 1};
    a.sensor = scene_sensor_default();
    a.roi = a.sensor.cols < a.sensor.rows ? a.sensor.cols : a.sensor.rows;
    err_t err;
    int first, rc = opts_parse(argc, argv, "", long_opts, OPT_HELP, "ips ptc --help", parse_opt, &a,
                               &first, &err);
    if (rc == 1) {
        fputs(usage, stdout);
        return 0;
    }
    if (rc) return cli_fail(CLI_EXIT_USAGE, "ptc", "%s", err.msg);
    if (first < argc)
        return cli_fail(CLI_EXIT_USAGE, "ptc", "unexpected argument '%s'", argv[first]);
    if (!a.sim)
        return cli_fail(CLI_EXIT_USAGE, "ptc",
                        "--sim is required (the simulated bench is the only "
                        "one ips ptc measures)");
    if (a.sensor.bias_dn >= a.sensor.full_scale_dn)
        return cli_fail(CLI_EXIT_USAGE, "ptc", "--bias (%g) must be below --full-scale (%g)",
                        a.sensor.bias_dn, a.sensor.full_scale_dn);
    if (a.roi > a.sensor.cols || a.roi > a.sensor.rows)
        return cli_fail(CLI_EXIT_USAGE, "ptc", "--roi %d exceeds the %d x %d array", a.roi,
                        a.sensor.cols, a.sensor.rows);

    sim_config_t cfg = sim_config_default();
    cfg.scene = "uniform";
    cfg.sensor = a.sensor;
    cfg.flux_e = 0; /* no spot: the lamp's flat field only */
    cfg.noiseless = a.noiseless;
    cfg.seed = (unsigned long)a.seed;
    /* the saturation charge: the ADC clip or the full well, whichever comes first (sim.h) */
    double sat_e = fmin(a.sensor.full_well_e,
                        (a.sensor.full_scale_dn - a.sensor.bias_dn) * a.sensor.gain_e_per_dn);
    cfg.flat_e = a.flat_e > 0 ? a.flat_e : sat_e;
    sim_t *sim;
    if ((rc = sim_open(&cfg, &sim, &err)) != 0)
        return cli_fail(cli_exit_code(rc), "ptc", "%s", err.msg);
    ptc_sim_lamp_t lamp = {sim, cfg.flat_e};
    ptc_run_config_t run = {.roi = {0, 0, a.roi, a.roi},
                            .levels = a.levels,
                            .exposure_max_us = 1.25 * cfg.ref_exposure_us};
    fit_ptc_level_t *lv = calloc((size_t)a.levels, sizeof *lv);
    if (!lv) {
        sim_close(sim);
        return cli_fail(CLI_EXIT_FAILURE, "ptc", "out of memory for %d levels", a.levels);
    }
    rc = ptc_run(sim_camera(sim), ptc_sim_light, &lamp, &run, NULL, NULL, lv, &err);
    sim_close(sim);
    if (rc) {
        free(lv);
        return cli_fail(cli_exit_code(rc), "ptc", "%s", err.msg);
    }
    fit_ptc_result_t r;
    rc = fit_ptc_analyse(lv, (size_t)a.levels, &r);
    if (rc) {
        free(lv);
        return cli_fail(CLI_EXIT_FAILURE, "ptc", "the photon-transfer analysis failed: %s",
                        rc == -EINVAL ? "no photon-transfer slope (noise-free frames, or too few "
                                        "levels below saturation)"
                                      : "a regression failed");
    }
    rc = report(&a, &cfg, &r, lv);
    free(lv);
    return rc;
}
