/* cmd_fit.c: `ips fit FILE [options]`: fits a scan file (instrument/scanfile.h) by the method of
 * the paper with the fit pipeline (fit/pipeline.h, the one ipsd's fit workers run): the sweep
 * over r with AIC/BIC model selection, optionally the F-test of the edge model, the Wiener
 * baseline and an interpolated map, printed as one JSON document (the docs/contracts.md
 * contract). Bad input: one line on stderr, exit 2; so is a part asked for that fails.
 * --pixels all fits every pixel of the file's sub-frame its raster covers, each as this command
 * fits one file (fit_pixels.h). */
#define _GNU_SOURCE /* sched_getaffinity, CPU_COUNT */
#include <errno.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/opts.h"
#include "base/parse.h"
#include "cliutil.h"
#include "commands.h"
#include "fit/pipeline.h"
#include "fit_pixels.h"
#include "fit_table.h"
#include "instrument/scanfile.h"
#include "json/fitjson.h"

#define R_LIMIT FIT_R_MAX           /* largest r fit_map accepts */
#define INTERP_LIMIT FIT_INTERP_MAX /* largest --interp grid */
#define STR_(x) #x
#define STR(x) STR_(x)
#define THREADS_LIMIT 64      /* FIT_THREADS_MAX (fit/parfor.h, internal to fit/) */
#define THREADS_DEFAULT_MAX 8 /* most threads by default: the sweep's r are only tens */

static const char usage[] =
    "usage: ips fit FILE [options]   (FILE - reads standard input)\n"
    "  --r N               fit only r = N (1..32); default: r = 1..8\n"
    "  --r-min A --r-max B fit r = A..B\n"
    "  --sigma paper|shot+read    noise model (default paper: eq. 5 as printed)\n"
    "  --ftest EDGES       F-test of the edge model, EDGES a comma list of top,left,bottom,right\n"
    "  --ftest-r N         r of the F-test (default 7)\n"
    "  --wiener            add the Wiener deconvolution baseline (needs a regular grid; it\n"
    "                      deconvolves every point of FILE and crops its map to the pixel)\n"
    "  --wiener-nsr spectral|white|X  how Wiener picks its noise-to-signal ratio: per\n"
    "                      frequency from the noise model and the data (default), one ratio\n"
    "                      mean sigma^2 / mean signal^2, or the number X > 0\n"
    "  --region inside|all|margin UM   the points fitted: spot centre inside the pixel\n"
    "                      (default, the paper's), every point, or within UM um of the pixel\n"
    "  --method linear|lm|both    linear least squares (default), the paper's LM, or both\n"
    "  --nonneg            constrain the map to S >= 0\n"
    "  --interp N          add the best-AIC map interpolated on an N x N grid\n"
    "  --full-scale DN     saturation level (points at or above are left out; <= 0: none)\n"
    "  --design-tol T      design-matrix accuracy (default 1e-12)\n"
    "  --fit-geometry      fit the spot radius and the scan-grid offset first (at --geometry-r)\n"
    "                      and fit the maps with them\n"
    "  --geometry-r N      r of the geometry fit (1..32; default: picked from the data,\n"
    "                      the smallest BIC over r = 3, 4, ...)\n"
    "  --geometry-model kriged|map  refine that fit's geometry under the kriged model\n"
    "                      (default: its likelihood over R, dx, dy with the map integrated\n"
    "                      out), or keep the r x r map's (faster, biased on smooth pixels)\n"
    "  --no-krige          leave out the kriged map (kriged_map: a Gaussian-process estimate\n"
    "                      of the sensitivity on a fine grid, the map ipsd stores as the\n"
    "                      calibration; docs/numerics.md \"The kriged map\"); --krige (the\n"
    "                      default) adds it\n"
    "  --krige-mixture     add kriged_map.mixture: the kriged map's expected error under an\n"
    "                      equal mixture of the priors of r - 1, r and r + 1 (the expected\n"
    "                      error an adaptive scan reports and stops on; two more kriged maps)\n"
    "  --threads N         fit the r of the sweep on N threads (1..64; default: the CPUs this\n"
    "                      process may run on, at most " STR(THREADS_DEFAULT_MAX) "); the results do not depend on N\n"
    "  --table             print a report for people instead of JSON\n"
    "  --pixels all        fit every pixel of the file's subframe that its raster covers,\n"
    "                      each with these options (ips simulate --write-subframe,\n"
    "                      GET /api/scans/{id}/scanfile); prints sub_px, covered, pixels[]\n"
    "Prints one JSON document: N, sigma, fits[], best_r, ftest, wiener, interp, geometry,\n"
    "kriged_map, "
    "timing_ms.\n";

struct fit_args {
    const char *path;
    int r_min, r_max;
    fit_options_t opts;
    const char *edges_text; /* --ftest, NULL if not asked */
    unsigned edges;
    int ftest_r, wiener, interp_n;
    int have_full_scale, table;
    int fit_geometry, geometry_r, geometry_map_only;
    int all_pixels; /* --pixels all */
    double full_scale;
    fit_region_t region;
    fit_wiener_nsr_t wiener_method;
    double wiener_nsr; /* --wiener-nsr X */
    int threads;       /* --threads N */
    int krige;         /* 1 unless --no-krige */
    int krige_mix;     /* --krige-mixture */
};

enum { OPT_R = 256, OPT_R_MIN, OPT_R_MAX, OPT_SIGMA, OPT_FTEST, OPT_FTEST_R, OPT_WIENER,
       OPT_METHOD, OPT_NONNEG, OPT_INTERP, OPT_FULL_SCALE, OPT_DESIGN_TOL, OPT_TABLE, OPT_REGION,
       OPT_WIENER_NSR, OPT_FIT_GEOMETRY, OPT_GEOMETRY_R, OPT_GEOMETRY_MODEL, OPT_PIXELS, OPT_THREADS, OPT_KRIGE, OPT_NO_KRIGE, OPT_KRIGE_MIX, OPT_HELP };

static const struct option long_opts[] = {
    {"r", required_argument, NULL, OPT_R},
    {"r-min", required_argument, NULL, OPT_R_MIN},
    {"r-max", required_argument, NULL, OPT_R_MAX},
    {"sigma", required_argument, NULL, OPT_SIGMA},
    {"ftest", required_argument, NULL, OPT_FTEST},
    {"ftest-r", required_argument, NULL, OPT_FTEST_R},
    {"wiener", no_argument, NULL, OPT_WIENER},
    {"method", required_argument, NULL, OPT_METHOD},
    {"nonneg", no_argument, NULL, OPT_NONNEG},
    {"interp", required_argument, NULL, OPT_INTERP},
    {"full-scale", required_argument, NULL, OPT_FULL_SCALE},
    {"design-tol", required_argument, NULL, OPT_DESIGN_TOL},
    {"table", no_argument, NULL, OPT_TABLE},
    {"region", required_argument, NULL, OPT_REGION},
    {"wiener-nsr", required_argument, NULL, OPT_WIENER_NSR},
    {"fit-geometry", no_argument, NULL, OPT_FIT_GEOMETRY},
    {"geometry-r", required_argument, NULL, OPT_GEOMETRY_R},
    {"geometry-model", required_argument, NULL, OPT_GEOMETRY_MODEL},
    {"pixels", required_argument, NULL, OPT_PIXELS},
    {"threads", required_argument, NULL, OPT_THREADS},
    {"krige", no_argument, NULL, OPT_KRIGE},
    {"no-krige", no_argument, NULL, OPT_NO_KRIGE},
    {"krige-mixture", no_argument, NULL, OPT_KRIGE_MIX},
    {"help", no_argument, NULL, OPT_HELP},
    {NULL, 0, NULL, 0},
};

/* A word option: --sigma and --method. */
static int word_opt(int val, const char *text, struct fit_args *a, err_t *err)
{
    if (val == OPT_SIGMA) {
        if (fit_noise_parse(text, &a->opts.noise) == 0) return 0;
        return err_set(err, -EINVAL, "--sigma must be paper or shot+read (got '%s')", text);
    }
    if (strcmp(text, "linear") == 0) a->opts.method = FIT_LINEAR;
    else if (strcmp(text, "lm") == 0) a->opts.method = FIT_LM;
    else if (strcmp(text, "both") == 0) a->opts.method = FIT_BOTH;
    else return err_set(err, -EINVAL, "--method must be linear, lm or both (got '%s')", text);
    return 0;
}

/* A number strictly between 0 and 1: --design-tol. */
static int unit_opt(const char *name, const char *text, double *v, err_t *err)
{
    if (parse_double(text, v) < 0 || !(*v > 0 && *v < 1))
        return err_set(err, -EINVAL, "--%s must be a number between 0 and 1 (got '%s')", name,
                       text);
    return 0;
}

struct parse_state {
    struct fit_args *a;
    int seen[OPT_HELP - OPT_R + 1]; /* which options were given */
    int argc;
    char **argv;
};

/* --region inside|all|margin UM: "margin" takes the next word as its distance (getopt_long has
 * no two-value options; its optind is the next word to scan, and moving it past UM is how
 * getopt's own callers consume a value, glibc keeps its permutation state in optind). */
static int region_opt(const char *arg, struct parse_state *ps, err_t *err)
{
    err_t e;
    double um = 0;
    if (strcmp(arg, "margin") == 0) {
        const char *v = optind < ps->argc ? ps->argv[optind] : NULL;
        if (!v || parse_double(v, &um) < 0)
            return err_set(err, -EINVAL,
                           "--region margin needs a distance in um after it (got %s%s%s)",
                           v ? "'" : "", v ? v : "nothing", v ? "'" : "");
        optind++;
    }
    if (fit_region_parse(arg, um, &ps->a->region, &e))
        return err_set(err, -EINVAL, "--region: %s", e.msg);
    return 0;
}

/* One option with its argument (opts_fn). */
static int one_opt(int val, const char *arg, void *user, err_t *err)
{
    struct parse_state *ps = user;
    struct fit_args *a = ps->a;
    ps->seen[val - OPT_R] = 1;
    switch (val) {
    case OPT_R:
        if (opts_int32("r", arg, 1, R_LIMIT, &a->r_min, err)) return -EINVAL;
        a->r_max = a->r_min;
        return 0;
    case OPT_R_MIN: return opts_int32("r-min", arg, 1, R_LIMIT, &a->r_min, err);
    case OPT_R_MAX: return opts_int32("r-max", arg, 1, R_LIMIT, &a->r_max, err);
    case OPT_FTEST_R: return opts_int32("ftest-r", arg, 1, R_LIMIT, &a->ftest_r, err);
    case OPT_INTERP: return opts_int32("interp", arg, 1, INTERP_LIMIT, &a->interp_n, err);
    case OPT_SIGMA:
    case OPT_METHOD: return word_opt(val, arg, a, err);
    case OPT_FTEST: {
        err_t e;
        a->edges_text = arg;
        if (fit_edges_parse(arg, &a->edges, &e) < 0)
            return err_set(err, -EINVAL, "--ftest: %s", e.msg);
        return 0;
    }
    case OPT_WIENER: a->wiener = 1; return 0;
    case OPT_NONNEG: a->opts.nonneg = 1; return 0;
    case OPT_TABLE: a->table = 1; return 0;
    case OPT_FIT_GEOMETRY: a->fit_geometry = 1; return 0;
    case OPT_KRIGE: a->krige = 1; return 0;
    case OPT_NO_KRIGE: a->krige = 0; return 0;
    case OPT_KRIGE_MIX: a->krige_mix = 1; return 0;
    case OPT_GEOMETRY_R: return opts_int32("geometry-r", arg, 1, R_LIMIT, &a->geometry_r, err);
    case OPT_GEOMETRY_MODEL:
        if (strcmp(arg, "map") == 0) a->geometry_map_only = 1;
        else if (strcmp(arg, "kriged") == 0) a->geometry_map_only = 0;
        else return err_set(err, -EINVAL, "--geometry-model must be map or kriged (got '%s')", arg);
        return 0;
    case OPT_THREADS: return opts_int32("threads", arg, 1, THREADS_LIMIT, &a->threads, err);
    case OPT_PIXELS:
        if (strcmp(arg, "all") != 0)
            return err_set(err, -EINVAL, "--pixels must be all (got '%s')", arg);
        a->all_pixels = 1;
        return 0;
    case OPT_FULL_SCALE:
        a->have_full_scale = 1;
        if (parse_double(arg, &a->full_scale) < 0)
            return err_set(err, -EINVAL, "--full-scale must be a finite number (got '%s')", arg);
        return 0;
    case OPT_DESIGN_TOL: return unit_opt("design-tol", arg, &a->opts.design_tol, err);
    case OPT_REGION: return region_opt(arg, ps, err);
    case OPT_WIENER_NSR:
        if (strcmp(arg, "spectral") == 0) a->wiener_method = FIT_WIENER_NSR_SPECTRAL;
        else if (strcmp(arg, "white") == 0) a->wiener_method = FIT_WIENER_NSR_WHITE;
        else if (parse_double(arg, &a->wiener_nsr) < 0 || !(a->wiener_nsr > 0))
            return err_set(err, -EINVAL,
                           "--wiener-nsr must be spectral, white or a number > 0 (got '%s')", arg);
        else a->wiener_method = FIT_WIENER_NSR_FIXED;
        return 0;
    default: return err_set(err, -EINVAL, "unhandled option");
    }
}

/* Checks the combinations of options and the positional FILE (argv[first]). */
static int check_args(int argc, char **argv, int first, struct fit_args *a, const int *seen,
                      err_t *err)
{
    if (seen[OPT_R - OPT_R] && (seen[OPT_R_MIN - OPT_R] || seen[OPT_R_MAX - OPT_R]))
        return err_set(err, -EINVAL, "give either --r or --r-min/--r-max, not both");
    if (a->r_min > a->r_max)
        return err_set(err, -EINVAL, "r-min (%d) must not exceed r-max (%d)", a->r_min, a->r_max);
    if (seen[OPT_FTEST_R - OPT_R] && !a->edges_text)
        return err_set(err, -EINVAL, "--ftest-r needs --ftest EDGES");
    if (seen[OPT_WIENER_NSR - OPT_R] && !a->wiener)
        return err_set(err, -EINVAL, "--wiener-nsr needs --wiener");
    if (seen[OPT_GEOMETRY_R - OPT_R] && !a->fit_geometry)
        return err_set(err, -EINVAL, "--geometry-r needs --fit-geometry");
    if (seen[OPT_GEOMETRY_MODEL - OPT_R] && !a->fit_geometry)
        return err_set(err, -EINVAL, "--geometry-model needs --fit-geometry");
    if (a->krige_mix && !a->krige)
        return err_set(err, -EINVAL, "--krige-mixture needs the kriged map: not with --no-krige");
    if (a->all_pixels && a->table)
        return err_set(err, -EINVAL, "--table prints one pixel's report: not with --pixels all");
    if (first >= argc) return err_set(err, -EINVAL, "missing FILE (usage: ips fit FILE [options])");
    if (first + 1 < argc)
        return err_set(err, -EINVAL, "unexpected argument '%s' after FILE", argv[first + 1]);
    a->path = strcmp(argv[first], "-") == 0 ? "/dev/stdin" : argv[first];
    return 0;
}

/* The CPUs this process may run on (its affinity mask), at most THREADS_DEFAULT_MAX. */
static int default_threads(void)
{
    cpu_set_t set;
    int n = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : 1;
    return n < 1 ? 1 : n > THREADS_DEFAULT_MAX ? THREADS_DEFAULT_MAX : n;
}

/* Parses argv into a; returns 0, -1 after printing the help, or the exit code of bad input. */
static int parse_args(int argc, char **argv, struct fit_args *a)
{
    *a = (struct fit_args){.r_min = 1, .r_max = 8, .opts = fit_options_default(), .ftest_r = 7, .krige = 1,
                           .threads = default_threads()};
    struct parse_state ps = {.a = a, .argc = argc, .argv = argv};
    err_t err;
    int first, rc = opts_parse(argc, argv, "", long_opts, OPT_HELP, "ips fit --help", one_opt, &ps,
                               &first, &err);
    if (rc == 1) {
        fputs(usage, stdout);
        return -1;
    }
    if (rc == 0) rc = check_args(argc, argv, first, a, ps.seen, &err);
    return rc ? cli_fail(CLI_EXIT_USAGE, "fit", "%s", err.msg) : 0;
}

/* ---- output ---- */

/* The JSON encoding of fits is json/fitjson.h, shared with ipsd (it stores the same document). */

struct fit_run {
    scanfile_t sf;
    fit_pipeline_t pl; /* zeroed until the pipeline ran (fit_pipeline_free accepts that) */
    double ms_read;
};

static void run_free(struct fit_run *run)
{
    fit_pipeline_free(&run->pl);
    scanfile_free(&run->sf);
}

/* Reads the scan (--full-scale applied). 0 or a negative errno with err. */
static int read_scan(const struct fit_args *a, struct fit_run *run, err_t *err)
{
    double t = clock_mono_ms();
    int rc = scanfile_read(a->path, &run->sf, NULL, err);
    if (rc) return rc;
    if (run->sf.scan.n == 0) return err_set(err, -EINVAL, "%s: scan has no points", a->path);
    if (a->have_full_scale) run->sf.scan.full_scale_dn = a->full_scale;
    run->ms_read = clock_mono_ms() - t;
    return 0;
}

/* Runs the pipeline on scan as asked. A part asked for that failed fails the fit (the first in
 * the order geometry, F-test, Wiener, interpolation). 0 or a negative errno with err. */
static int run_pipeline(const struct fit_args *a, const fit_scan_t *scan, fit_pipeline_t *pl,
                        err_t *err)
{
    int rc;
    fit_pipeline_opts_t po = {.r_min = a->r_min, .r_max = a->r_max, .fit = a->opts,
                              .ftest_edges = a->edges_text ? a->edges : 0, .ftest_r = a->ftest_r,
                              .wiener = a->wiener, .interp_n = a->interp_n,
                              .region = a->region, .wiener_method = a->wiener_method,
                              .wiener_nsr = a->wiener_nsr, .fit_geometry = a->fit_geometry,
                              .geometry_r = a->geometry_r,
                              .geometry_map_only = a->geometry_map_only, .threads = a->threads,
                              .krige = a->krige, .krige_mix = a->krige_mix};
    if ((rc = fit_pipeline_run(scan, &po, NULL, pl, err))) return rc;
    const fit_part_t *parts[] = {&pl->geometry_part, &pl->ftest_part, &pl->wiener_part,
                                 &pl->interp_part};
    for (size_t i = 0; i < sizeof parts / sizeof parts[0]; i++)
        if (parts[i]->asked && parts[i]->rc)
            return err_set(err, parts[i]->rc, "%s", parts[i]->err.msg);
    return 0;
}

/* The interpolated best-AIC map, or null when no fit has a map. */
static json_t *interp_json(const fit_pipeline_t *pl)
{
    if (!pl->interp_r) return json_null();
    return json_pack("{s:i, s:i, s:o}", "r", pl->interp_r, "n", pl->interp_n, "S",
                     fitjson_array(pl->interp, (size_t)pl->interp_n * pl->interp_n));
}

/* The document of one fit: pipeline pl of scan, ms_read spent reading, t0 the start. */
static json_t *result_json(const struct fit_args *a, const fit_pipeline_t *pl,
                           const fit_scan_t *scan, double ms_read, double t0)
{
    json_t *root = fitjson_sweep(&pl->sweep, pl->n_region, &a->opts, scan->full_scale_dn);
    if (!root) return NULL;
    if (fitjson_add_region(root, &pl->region, scan->n)) {
        json_decref(root);
        return NULL;
    }
    if (pl->ftest_part.asked) json_object_set_new(root, "ftest", fitjson_ftest(&pl->ftest));
    if (pl->wiener_part.asked) json_object_set_new(root, "wiener", fitjson_wiener(&pl->wiener));
    if (pl->interp_part.asked) json_object_set_new(root, "interp", interp_json(pl));
    if (pl->geometry_part.asked)
        json_object_set_new(root, "geometry", fitjson_geometry(&pl->geometry));
    if (a->krige)
        json_object_set_new(root, "kriged_map",
                            fitjson_kriged(pl->sweep.kriged, pl->kriged_error));
    json_object_set_new(root, "timing_ms",
                        json_pack("{s:o, s:o, s:o, s:o, s:o, s:o}", "read",
                                  fitjson_num(ms_read), "sweep", fitjson_num(pl->sweep_ms),
                                  "ftest", fitjson_num(pl->ftest_part.ms), "wiener",
                                  fitjson_num(pl->wiener_part.ms), "interp",
                                  fitjson_num(pl->interp_part.ms), "total",
                                  fitjson_num(clock_mono_ms() - t0)));
    if (pl->geometry_part.asked)
        json_object_set_new(json_object_get(root, "timing_ms"), "geometry",
                            fitjson_num(pl->geometry_part.ms));
    if (pl->sweep.kriged)
        json_object_set_new(json_object_get(root, "timing_ms"), "krige",
                            fitjson_num(pl->sweep.kriged->ms));
    /* the threads the sweep could use (--threads): the context of the times above */
    json_object_set_new(json_object_get(root, "timing_ms"), "threads", json_integer(a->threads));
    return root;
}

/* One pixel of --pixels all (fit_pixels_fn): its document, as this command prints it for that
 * pixel's own scan file (timing_ms.read 0: the file was read once). */
static int fit_one(const fit_scan_t *scan, void *user, json_t **doc, err_t *err)
{
    const struct fit_args *a = user;
    double t0 = clock_mono_ms();
    fit_pipeline_t pl = {0};
    int rc = run_pipeline(a, scan, &pl, err);
    *doc = NULL;
    if (rc == 0 && !(*doc = result_json(a, &pl, scan, 0, t0)))
        rc = err_set(err, -ENOMEM, "out of memory building the output");
    fit_pipeline_free(&pl);
    return rc;
}

/* --pixels all: read, fit every covered pixel, print. */
static int cmd_fit_pixels(const struct fit_args *a, double t0)
{
    struct fit_run run = {0};
    err_t err;
    json_t *root = NULL;
    int rc = read_scan(a, &run, &err);
    if (rc == 0 && !run.sf.sub_px)
        rc = err_set(&err, -EINVAL,
                     "%s: --pixels all needs a scan file with a subframe (ips simulate "
                     "--write-subframe, GET /api/scans/{id}/scanfile)",
                     a->path);
    if (rc == 0) rc = fit_pixels_run(&run.sf, fit_one, (void *)a, &root, &err);
    run_free(&run);
    if (rc) return cli_fail(cli_exit_code(rc), "fit", "%s", err.msg);
    json_t *t = json_object_get(root, "timing_ms");
    json_object_set_new(t, "read", fitjson_num(run.ms_read));
    json_object_set_new(t, "total", fitjson_num(clock_mono_ms() - t0));
    rc = fitjson_print(root, stdout);
    json_decref(root);
    return rc ? cli_fail(CLI_EXIT_FAILURE, "fit", "writing the output failed") : 0;
}

int cmd_fit(int argc, char **argv)
{
    double t0 = clock_mono_ms();
    struct fit_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc) return rc < 0 ? 0 : rc;
    if (a.all_pixels) return cmd_fit_pixels(&a, t0);
    struct fit_run run = {0};
    err_t err;
    if ((rc = read_scan(&a, &run, &err)) == 0) rc = run_pipeline(&a, &run.sf.scan, &run.pl, &err);
    if (rc) {
        run_free(&run);
        return cli_fail(cli_exit_code(rc), "fit", "%s", err.msg);
    }
    if (a.table) {
        const fit_pipeline_t *pl = &run.pl;
        fit_table_print(stdout, a.path, &run.sf.scan, &pl->sweep,
                        pl->geometry_part.asked ? &pl->geometry : NULL,
                        pl->ftest_part.asked ? &pl->ftest : NULL,
                        pl->wiener_part.asked ? &pl->wiener : NULL,
                        a.krige && !pl->sweep.kriged ? pl->kriged_error : NULL,
                        clock_mono_ms() - t0);
        run_free(&run);
        return 0;
    }
    json_t *root = result_json(&a, &run.pl, &run.sf.scan, run.ms_read, t0);
    run_free(&run);
    if (!root) return cli_fail(CLI_EXIT_FAILURE, "fit", "out of memory building the output");
    rc = fitjson_print(root, stdout);
    json_decref(root);
    return rc ? cli_fail(CLI_EXIT_FAILURE, "fit", "writing the output failed") : 0;
}
