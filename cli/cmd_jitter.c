/* cmd_jitter.c: `ips jitter`: jitter photometry (fit/jitter.h) for one pixel's map: the relative
 * flux error intra-pixel sensitivity adds when a star (Airy or Gaussian PSF) moves with the
 * pointing jitter, and the corrected fluxes of a measured series. Prints json/jitterjson.h's
 * document, the reply of POST /api/jitter. The map comes from a file (cli/mapfile.h: a
 * Calibration, an `ips fit` document, a bare map) or is a simulated scene's truth. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/opts.h"
#include "base/parse.h"
#include "cliutil.h"
#include "commands.h"
#include "fit/airy.h"
#include "fit/jitter.h"
#include "instrument/scene.h"
#include "json/jitterjson.h"
#include "mapfile.h"

#define MAX_SAMPLES 10000000
#define NOTE_EVALS 4e7 /* ipsd's default --max-jitter-evals: ~1 s (docs/operations.md) */

static const char usage[] =
    "usage: ips jitter (--map FILE | --scene NAME) (--rms UM | --series FILE) [options]\n"
    "  The relative flux error a pixel's intra-pixel sensitivity adds to a star's photometry\n"
    "  under pointing jitter, and the corrected flux of a measured series (docs/contracts.md).\n"
    "  --map FILE        the map: a Calibration (GET /api/calibrations/{id}), an `ips fit`\n"
    "                    document (its recommended r, or --r) or {\"r\", \"S\"}\n"
    "  --scene NAME      or the simulator's scene (paperlike, dip, ...: its true map, scaled\n"
    "                    to mean 1 as fitted maps are)\n"
    "  --r R             the map's r (an `ips fit` document's fit; a scene's truth at r x r)\n"
    "  --pitch UM        pixel pitch (default 6, the paper's sensor)\n"
    "  --psf airy|gauss  the star's PSF (default airy)\n"
    "  --radius UM       Airy first-zero radius, or --wavelength NM with --na NA (eq. 1);\n"
    "                    default: the map's optics, else 550 nm and NA 0.25\n"
    "  --sigma UM        the Gaussian's standard deviation (with --psf gauss)\n"
    "  --x UM --y UM     the star's nominal position in the pixel (default its centre)\n"
    "  --rms UM          jitter: Gaussian, UM rms per axis, drawn --samples N (1000) times\n"
    "                    with --seed S (1)\n"
    "  --series FILE     or the jitter series: lines 'dx dy [measured]' (um; '#' comments);\n"
    "                    a third column is corrected by the predicted response\n"
    "  --samples-out     print every sample (dx, dy, rho, rel_err[, measured, corrected])\n"
    "  --max-evals N     refuse (exit 2) when the Airy integrals need more than N radial\n"
    "                    evaluations (ipsd's --max-jitter-evals; default 0: no limit, but a\n"
    "                    note on stderr above 2e8, a few seconds)\n";

enum { OPT_MAP = 256, OPT_SCENE, OPT_R, OPT_PITCH, OPT_PSF, OPT_RADIUS, OPT_WAVELENGTH, OPT_NA,
       OPT_SIGMA, OPT_X, OPT_Y, OPT_RMS, OPT_SAMPLES, OPT_SEED, OPT_SERIES, OPT_SAMPLES_OUT,
       OPT_MAX_EVALS, OPT_HELP };

static const struct option long_opts[] = {
    {"map", required_argument, NULL, OPT_MAP},
    {"scene", required_argument, NULL, OPT_SCENE},
    {"r", required_argument, NULL, OPT_R},
    {"pitch", required_argument, NULL, OPT_PITCH},
    {"psf", required_argument, NULL, OPT_PSF},
    {"radius", required_argument, NULL, OPT_RADIUS},
    {"wavelength", required_argument, NULL, OPT_WAVELENGTH},
    {"na", required_argument, NULL, OPT_NA},
    {"sigma", required_argument, NULL, OPT_SIGMA},
    {"x", required_argument, NULL, OPT_X},
    {"y", required_argument, NULL, OPT_Y},
    {"rms", required_argument, NULL, OPT_RMS},
    {"samples", required_argument, NULL, OPT_SAMPLES},
    {"seed", required_argument, NULL, OPT_SEED},
    {"series", required_argument, NULL, OPT_SERIES},
    {"samples-out", no_argument, NULL, OPT_SAMPLES_OUT},
    {"max-evals", required_argument, NULL, OPT_MAX_EVALS},
    {"help", no_argument, NULL, OPT_HELP},
    {NULL, 0, NULL, 0}};

struct jitter_args {
    const char *map, *scene, *series;
    int r, samples_out;
    double pitch, radius, wavelength_nm, na, sigma, x, y, rms, max_evals;
    long long samples, seed;
    fit_psf_kind_t psf;
};

static int parse_opt(int c, const char *arg, void *user, err_t *err)
{
    struct jitter_args *a = user;
    switch (c) {
    case OPT_MAP: a->map = arg; return 0;
    case OPT_SCENE: a->scene = arg; return 0;
    case OPT_SERIES: a->series = arg; return 0;
    case OPT_R: return opts_int32("r", arg, 1, 256, &a->r, err);
    case OPT_PITCH: return opts_num("pitch", arg, 1e-3, 1e4, &a->pitch, err);
    case OPT_PSF: return jitterjson_psf_parse(arg, &a->psf, err);
    case OPT_RADIUS: return opts_num("radius", arg, 1e-6, 1e5, &a->radius, err);
    case OPT_WAVELENGTH: return opts_num("wavelength", arg, 1, 1e6, &a->wavelength_nm, err);
    case OPT_NA: return opts_num("na", arg, 1e-6, 1.5, &a->na, err);
    case OPT_SIGMA: return opts_num("sigma", arg, 1e-6, 1e5, &a->sigma, err);
    case OPT_X: return opts_num("x", arg, -1e4, 1e4, &a->x, err);
    case OPT_Y: return opts_num("y", arg, -1e4, 1e4, &a->y, err);
    case OPT_RMS: return opts_num("rms", arg, 0, 1e4, &a->rms, err);
    case OPT_SAMPLES: return opts_int("samples", arg, 1, MAX_SAMPLES, &a->samples, err);
    case OPT_SEED: return opts_int("seed", arg, 0, 4294967295LL, &a->seed, err);
    case OPT_SAMPLES_OUT: a->samples_out = 1; return 0;
    case OPT_MAX_EVALS: return opts_num("max-evals", arg, 0, 1e18, &a->max_evals, err);
    default: return err_set(err, -EINVAL, "unhandled option");
    }
}

/* The series file: 'dx dy [measured]' per line. Returns 0 or -EINVAL naming the line. */
static int read_series(const char *path, double **dx, double **dy, double **meas, size_t *n,
                       err_t *err)
{
    FILE *f = fopen(path, "r");
    if (!f) return err_set(err, -ENOENT, "--series %s: cannot open", path);
    char line[512];
    size_t cap = 0, lineno = 0;
    int cols = 0, ret = 0;
    *dx = *dy = *meas = NULL;
    *n = 0;
    while (!ret && fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash) *hash = 0;
        double v[3];
        int k = 0;
        char *save = NULL;
        const char *sep = " \t\r\n,";
        for (char *t = strtok_r(line, sep, &save); t; t = strtok_r(NULL, sep, &save)) {
            if (k == 3 || parse_double(t, &v[k]) < 0) {
                ret = err_set(err, -EINVAL, "--series %s line %zu: need 2 or 3 numbers", path,
                              lineno);
                break;
            }
            k++;
        }
        if (ret || k == 0) continue;
        if (k == 1 || (cols && k != cols)) {
            ret = err_set(err, -EINVAL, "--series %s line %zu: need %d numbers (got %d)", path,
                          lineno, cols ? cols : 2, k);
            break;
        }
        cols = k;
        if (*n == cap) {
            cap = cap ? 2 * cap : 256;
            if (cap > MAX_SAMPLES) {
                ret = err_set(err, -EINVAL, "--series %s: more than %d samples", path,
                              MAX_SAMPLES);
                break;
            }
            double *a = realloc(*dx, sizeof(double) * cap);
            if (a) *dx = a;
            double *b = a ? realloc(*dy, sizeof(double) * cap) : NULL;
            if (b) *dy = b;
            double *c = b ? realloc(*meas, sizeof(double) * cap) : NULL;
            if (c) *meas = c;
            if (!c) {
                ret = err_set(err, -ENOMEM, "out of memory for the series");
                break;
            }
        }
        (*dx)[*n] = v[0];
        (*dy)[*n] = v[1];
        (*meas)[*n] = k == 3 ? v[2] : NAN;
        (*n)++;
    }
    fclose(f);
    if (!ret && *n == 0) ret = err_set(err, -EINVAL, "--series %s: no samples", path);
    if (!ret && cols == 2) {
        free(*meas);
        *meas = NULL;
    }
    return ret;
}

int cmd_jitter(int argc, char **argv)
{
    struct jitter_args a = {.pitch = 6.0, .radius = NAN, .wavelength_nm = NAN, .na = NAN,
                            .sigma = NAN, .x = NAN, .y = NAN, .rms = NAN, .samples = 1000,
                            .seed = 1, .psf = FIT_PSF_AIRY};
    err_t err;
    int first, rc = opts_parse(argc, argv, "", long_opts, OPT_HELP, "ips jitter --help",
                               parse_opt, &a, &first, &err);
    if (rc == 1) {
        fputs(usage, stdout);
        return 0;
    }
    if (rc) return cli_fail(CLI_EXIT_USAGE, "jitter", "%s", err.msg);
    if (first < argc)
        return cli_fail(CLI_EXIT_USAGE, "jitter", "unexpected argument '%s'", argv[first]);
    if (!a.map == !a.scene)
        return cli_fail(CLI_EXIT_USAGE, "jitter", "give one of --map FILE or --scene NAME");
    if (isnan(a.rms) == !a.series)
        return cli_fail(CLI_EXIT_USAGE, "jitter", "give one of --rms UM or --series FILE");
    if (isnan(a.wavelength_nm) != isnan(a.na))
        return cli_fail(CLI_EXIT_USAGE, "jitter", "--wavelength and --na go together");
    if (a.psf == FIT_PSF_GAUSS && !(a.sigma > 0))
        return cli_fail(CLI_EXIT_USAGE, "jitter", "--psf gauss needs --sigma UM");
    if (a.psf == FIT_PSF_AIRY && !isnan(a.sigma))
        return cli_fail(CLI_EXIT_USAGE, "jitter", "--sigma is for --psf gauss");

    /* the map */
    mapfile_t mf = {0};
    double *truth = NULL, *dx = NULL, *dy = NULL, *meas = NULL;
    size_t n = 0;
    fit_jitter_pixel_t px = {0, 0, 0, NULL};
    double map_radius = NAN;
    if (a.map) {
        rc = mapfile_read(a.map, a.r, &mf, &err);
        if (rc) goto fail;
        px.r = mf.maps[0].r;
        px.S = mf.maps[0].S;
        map_radius = mf.maps[0].spot_radius_um;
    } else {
        scene_sensor_t sn = scene_sensor_default();
        sn.pitch_um = a.pitch;
        scene_t *sc = NULL;
        rc = scene_open(a.scene, &sn, &sc, &err);
        if (rc) goto fail;
        int m;
        scene_map(sc, &m);
        px.r = a.r ? a.r : m;
        truth = malloc(sizeof(double) * (size_t)px.r * px.r);
        rc = truth ? scene_truth(sc, px.r, truth, &err) : err_set(&err, -ENOMEM, "out of memory");
        scene_close(sc);
        if (rc) goto fail;
        /* to mean 1, as fitted maps and calibrations are (rho is relative to the mean) */
        double sum = 0;
        for (int k = 0; k < px.r * px.r; k++) sum += truth[k];
        for (int k = 0; k < px.r * px.r; k++) truth[k] *= px.r * px.r / sum;
        px.S = truth;
    }

    /* the PSF: given, else the map's optics, else the paper's (550 nm, NA 0.25) */
    fit_jitter_setup_t s = {.pitch_um = a.pitch, .pixels = &px, .n_pixels = 1,
                            .x0_um = isnan(a.x) ? a.pitch / 2 : a.x,
                            .y0_um = isnan(a.y) ? a.pitch / 2 : a.y};
    s.psf.kind = a.psf;
    if (a.psf == FIT_PSF_GAUSS) s.psf.width_um = a.sigma;
    else if (a.radius > 0) s.psf.width_um = a.radius;
    else if (a.wavelength_nm > 0) s.psf.width_um = fit_spot_radius_um(a.wavelength_nm / 1000, a.na);
    else if (map_radius > 0) s.psf.width_um = map_radius;
    else s.psf.width_um = fit_spot_radius_um(0.55, 0.25); /* eq. 1 */

    /* the jitter */
    if (a.series) {
        rc = read_series(a.series, &dx, &dy, &meas, &n, &err);
    } else {
        n = (size_t)a.samples;
        dx = malloc(sizeof(double) * n);
        dy = malloc(sizeof(double) * n);
        rc = dx && dy ? fit_jitter_draw(a.rms, n, (unsigned long)a.seed, dx, dy, &err)
                      : err_set(&err, -ENOMEM, "out of memory");
    }
    if (rc) goto fail;
    /* the Airy integrals' cost (fit_jitter_cost): a tiny spot jittered far from the pixel
     * crosses thousands of rings per sample; ipsd refuses such requests, here the user decides */
    double evals = fit_jitter_cost(&s, dx, dy, n);
    if ((a.max_evals > 0 && evals > a.max_evals) || evals > NOTE_EVALS) {
        double reach = fit_jitter_reach(dx, dy, n);
        if (a.max_evals > 0 && evals > a.max_evals) {
            rc = err_set(&err, -EINVAL,
                         "--max-evals %.3g: %zu samples reaching %.3g spot radii from the star's "
                         "position need about %.3g radial evaluations",
                         a.max_evals, n, reach / s.psf.width_um, evals);
            goto fail;
        }
        fprintf(stderr,
                "ips jitter: note: %zu samples reaching %.3g spot radii need about %.3g radial "
                "evaluations (ipsd refuses more than 4e7 by default; this may take %.0f s or "
                "more)\n",
                n, reach / s.psf.width_um, evals, evals / NOTE_EVALS);
    }
    json_t *doc;
    rc = jitterjson_run(&s, dx, dy, n, meas, a.samples_out, &doc, &err);
    if (rc) goto fail;
    if (a.map && mf.maps[0].id)
        json_object_set_new(doc, "calibration_ids", json_pack("[I]", (json_int_t)mf.maps[0].id));
    rc = json_dumpf(doc, stdout, JSON_INDENT(1) | JSON_REAL_PRECISION(17));
    json_decref(doc);
    putchar('\n');
    if (rc) {
        rc = -EIO;
        err_set(&err, rc, "cannot write the document");
    }
fail:
    mapfile_free(&mf);
    free(truth);
    free(dx);
    free(dy);
    free(meas);
    return rc ? cli_fail(cli_exit_code(rc), "jitter", "%s", err.msg) : 0;
}
