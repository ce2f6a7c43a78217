/* cmd_fit.c: `ips fit FILE [options]`: fits a scan file (instrument/scanfile.h) by the method of
 * the paper (fit/model.h): the sweep over r with AIC/BIC model selection, optionally the F-test
 * of the edge model, the Wiener baseline and an interpolated map, printed as one JSON document
 * (the ARCHITECTURE.md contract). Bad input: one line on stderr, exit 2. */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cliutil.h"
#include "commands.h"
#include "fit_table.h"
#include "interp.h"
#include "fitjson.h"
#include "model.h"
#include "scanfile.h"
#include "wiener.h"

#define R_LIMIT 32        /* largest r fit_map accepts */
#define INTERP_LIMIT 4096 /* largest --interp grid */

static const char usage[] =
    "usage: ips fit FILE [options]   (FILE - reads standard input)\n"
    "  --r N               fit only r = N (1..32); default: r = 1..8\n"
    "  --r-min A --r-max B fit r = A..B\n"
    "  --sigma paper|shot+read    noise model (default paper: eq. 5 as printed)\n"
    "  --ftest EDGES       F-test of the edge model, EDGES a comma list of top,left,bottom,right\n"
    "  --ftest-r N         r of the F-test (default 7)\n"
    "  --wiener            add the Wiener deconvolution baseline (needs a regular grid)\n"
    "  --method linear|lm|both    linear least squares (default), the paper's LM, or both\n"
    "  --nonneg            constrain the map to S >= 0\n"
    "  --interp N          add the best-AIC map interpolated on an N x N grid\n"
    "  --full-scale DN     saturation level (points at or above are left out; <= 0: none)\n"
    "  --design-tol T      design-matrix accuracy (default 1e-12)\n"
    "  --table             print a report for people instead of JSON\n"
    "Prints one JSON document: N, sigma, fits[], best_r, ftest, wiener, interp, timing_ms.\n";

struct fit_args {
    const char *path;
    int r_min, r_max;
    fit_options_t opts;
    const char *edges_text; /* --ftest, NULL if not asked */
    unsigned edges;
    int ftest_r, wiener, interp_n;
    int have_full_scale, table;
    double full_scale;
};

enum { OPT_R = 256, OPT_R_MIN, OPT_R_MAX, OPT_SIGMA, OPT_FTEST, OPT_FTEST_R, OPT_WIENER,
       OPT_METHOD, OPT_NONNEG, OPT_INTERP, OPT_FULL_SCALE, OPT_DESIGN_TOL, OPT_TABLE, OPT_HELP };

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
    {"help", no_argument, NULL, OPT_HELP},
    {NULL, 0, NULL, 0},
};

static const char *opt_name(int val)
{
    for (const struct option *o = long_opts; o->name; o++)
        if (o->val == val) return o->name;
    return "?";
}

/* An int option in lo..hi: "r must be between 1 and 32 (got 40)". */
static int int_in(const char *name, const char *text, int lo, int hi, int *v)
{
    if (cli_parse_int(text, v) < 0)
        return cli_fail(CLI_EXIT_USAGE, "fit", "--%s must be an integer (got '%s')", name, text);
    if (*v < lo || *v > hi)
        return cli_fail(CLI_EXIT_USAGE, "fit", "%s must be between %d and %d (got %d)", name, lo,
                        hi, *v);
    return 0;
}

/* A finite double option, in (0, 1) when unit is set. */
static int num_opt(const char *name, const char *text, int unit, double *v)
{
    if (cli_parse_double(text, v) < 0 || (unit && !(*v > 0 && *v < 1)))
        return cli_fail(CLI_EXIT_USAGE, "fit", "--%s must be %s (got '%s')", name,
                        unit ? "a number between 0 and 1" : "a finite number", text);
    return 0;
}

/* A word option: --sigma and --method. */
static int word_opt(int val, const char *text, struct fit_args *a)
{
    if (val == OPT_SIGMA) {
        if (fit_noise_parse(text, &a->opts.noise) == 0) return 0;
        return cli_fail(CLI_EXIT_USAGE, "fit", "--sigma must be paper or shot+read (got '%s')",
                        text);
    }
    if (strcmp(text, "linear") == 0) a->opts.method = FIT_LINEAR;
    else if (strcmp(text, "lm") == 0) a->opts.method = FIT_LM;
    else if (strcmp(text, "both") == 0) a->opts.method = FIT_BOTH;
    else
        return cli_fail(CLI_EXIT_USAGE, "fit", "--method must be linear, lm or both (got '%s')",
                        text);
    return 0;
}

/* One option with its argument; seen[] records which were given. */
static int one_opt(int val, const char *arg, struct fit_args *a, int *seen)
{
    err_t err;
    seen[val - OPT_R] = 1;
    switch (val) {
    case OPT_R:
        if (int_in("r", arg, 1, R_LIMIT, &a->r_min)) return CLI_EXIT_USAGE;
        a->r_max = a->r_min;
        return 0;
    case OPT_R_MIN: return int_in("r-min", arg, 1, R_LIMIT, &a->r_min);
    case OPT_R_MAX: return int_in("r-max", arg, 1, R_LIMIT, &a->r_max);
    case OPT_FTEST_R: return int_in("ftest-r", arg, 1, R_LIMIT, &a->ftest_r);
    case OPT_INTERP: return int_in("interp", arg, 1, INTERP_LIMIT, &a->interp_n);
    case OPT_SIGMA:
    case OPT_METHOD: return word_opt(val, arg, a);
    case OPT_FTEST:
        a->edges_text = arg;
        if (fit_edges_parse(arg, &a->edges, &err) < 0)
            return cli_fail(CLI_EXIT_USAGE, "fit", "--ftest: %s", err.msg);
        return 0;
    case OPT_WIENER: a->wiener = 1; return 0;
    case OPT_NONNEG: a->opts.nonneg = 1; return 0;
    case OPT_TABLE: a->table = 1; return 0;
    case OPT_FULL_SCALE:
        a->have_full_scale = 1;
        return num_opt("full-scale", arg, 0, &a->full_scale);
    case OPT_DESIGN_TOL: return num_opt("design-tol", arg, 1, &a->opts.design_tol);
    default: return CLI_EXIT_USAGE;
    }
}

/* Checks the combinations of options and the positional FILE. */
static int check_args(int argc, char **argv, struct fit_args *a, const int *seen)
{
    if (seen[OPT_R - OPT_R] && (seen[OPT_R_MIN - OPT_R] || seen[OPT_R_MAX - OPT_R]))
        return cli_fail(CLI_EXIT_USAGE, "fit", "give either --r or --r-min/--r-max, not both");
    if (a->r_min > a->r_max)
        return cli_fail(CLI_EXIT_USAGE, "fit", "r-min (%d) must not exceed r-max (%d)", a->r_min,
                        a->r_max);
    if (seen[OPT_FTEST_R - OPT_R] && !a->edges_text)
        return cli_fail(CLI_EXIT_USAGE, "fit", "--ftest-r needs --ftest EDGES");
    if (optind >= argc)
        return cli_fail(CLI_EXIT_USAGE, "fit", "missing FILE (usage: ips fit FILE [options])");
    if (optind + 1 < argc)
        return cli_fail(CLI_EXIT_USAGE, "fit", "unexpected argument '%s' after FILE",
                        argv[optind + 1]);
    a->path = strcmp(argv[optind], "-") == 0 ? "/dev/stdin" : argv[optind];
    return 0;
}

/* Parses argv into a; returns 0, -1 after printing the help, or the exit code of bad input. */
static int parse_args(int argc, char **argv, struct fit_args *a)
{
    *a = (struct fit_args){.r_min = 1, .r_max = 8, .opts = fit_options_default(), .ftest_r = 7};
    int seen[OPT_HELP - OPT_R + 1] = {0}, c;
    opterr = 0;
    optind = 1;
    while ((c = getopt_long(argc, argv, ":", long_opts, NULL)) != -1) {
        if (c == OPT_HELP) {
            fputs(usage, stdout);
            return -1;
        }
        if (c == ':')
            return cli_fail(CLI_EXIT_USAGE, "fit", "--%s needs a value", opt_name(optopt));
        if (c == '?' && optopt >= OPT_R) /* a value given to a flag: --wiener=1 */
            return cli_fail(CLI_EXIT_USAGE, "fit", "--%s takes no value", opt_name(optopt));
        if (c == '?' && optopt)
            return cli_fail(CLI_EXIT_USAGE, "fit", "unknown option '-%c' (see ips fit --help)",
                            optopt);
        if (c == '?')
            return cli_fail(CLI_EXIT_USAGE, "fit", "unknown option '%s' (see ips fit --help)",
                            argv[optind - 1]);
        int rc = one_opt(c, optarg, a, seen);
        if (rc) return rc;
    }
    return check_args(argc, argv, a, seen);
}

/* ---- output ---- */

/* The JSON encoding of fits is json/fitjson.h, shared with ipsd (it stores the same document). */

struct fit_run {
    scanfile_t sf;
    fit_sweep_t sweep;
    fit_ftest_t ftest;
    fit_wiener_t wiener;
    int have_sweep, have_ftest, have_wiener;
    int interp_r;   /* r of the interpolated map, 0 if none */
    double *interp; /* interp_n^2 values */
    double ms_read, ms_sweep, ms_ftest, ms_wiener, ms_interp;
};

static void run_free(struct fit_run *run)
{
    if (run->have_sweep) fit_sweep_free(&run->sweep);
    if (run->have_wiener) fit_wiener_free(&run->wiener);
    free(run->interp);
    scanfile_free(&run->sf);
}

/* The best-AIC map on an n x n grid (none when no fit has a map). */
static int run_interp(const struct fit_args *a, struct fit_run *run, err_t *err)
{
    int r = run->sweep.best_aic;
    if (!r) return 0;
    run->interp = malloc(sizeof(double) * (size_t)a->interp_n * a->interp_n);
    if (!run->interp) return err_set(err, -ENOMEM, "out of memory");
    run->interp_r = r;
    return fit_interp_bicubic(run->sweep.fits[r - run->sweep.r_min].S, r, a->interp_n,
                              run->interp, err);
}

/* Reads the scan and runs the sweep and what was asked for. 0 or a negative errno with err. */
static int run_all(const struct fit_args *a, struct fit_run *run, err_t *err)
{
    double t = cli_now_ms();
    int rc = scanfile_read(a->path, &run->sf, NULL, err);
    if (rc) return rc;
    if (run->sf.scan.n == 0) return err_set(err, -EINVAL, "%s: scan has no points", a->path);
    if (a->have_full_scale) run->sf.scan.full_scale_dn = a->full_scale;
    run->ms_read = cli_now_ms() - t;
    t = cli_now_ms();
    if ((rc = fit_sweep_run(&run->sf.scan, a->r_min, a->r_max, &a->opts, &run->sweep, err)))
        return rc;
    run->have_sweep = 1;
    run->ms_sweep = cli_now_ms() - t;
    if (a->edges_text) {
        t = cli_now_ms();
        const fit_sweep_t *sw = &run->sweep; /* reuse the sweep's linear fit as H1 */
        if (a->opts.method == FIT_LINEAR && a->ftest_r >= sw->r_min && a->ftest_r <= sw->r_max)
            rc = fit_ftest_with_h1(&run->sf.scan, &sw->fits[a->ftest_r - sw->r_min], a->edges,
                                   &a->opts, &run->ftest, err);
        else
            rc = fit_ftest_run(&run->sf.scan, a->ftest_r, a->edges, &a->opts, &run->ftest, err);
        if (rc) return rc;
        run->have_ftest = 1;
        run->ms_ftest = cli_now_ms() - t;
    }
    if (a->wiener) {
        t = cli_now_ms();
        if ((rc = fit_wiener_run(&run->sf.scan, 0, &run->wiener, err))) return rc;
        run->have_wiener = 1;
        run->ms_wiener = cli_now_ms() - t;
    }
    if (a->interp_n) {
        t = cli_now_ms();
        if ((rc = run_interp(a, run, err))) return rc;
        run->ms_interp = cli_now_ms() - t;
    }
    return 0;
}

/* The interpolated best-AIC map, or null when no fit has a map. */
static json_t *interp_json(int n, const struct fit_run *run)
{
    if (!run->interp_r) return json_null();
    return json_pack("{s:i, s:i, s:o}", "r", run->interp_r, "n", n, "S",
                     fitjson_array(run->interp, (size_t)n * n));
}

static json_t *result_json(const struct fit_args *a, const struct fit_run *run, double t0)
{
    json_t *root = fitjson_sweep(&run->sweep, run->sf.scan.n, &a->opts, run->sf.scan.full_scale_dn);
    if (!root) return NULL;
    if (run->have_ftest) json_object_set_new(root, "ftest", fitjson_ftest(&run->ftest));
    if (run->have_wiener) json_object_set_new(root, "wiener", fitjson_wiener(&run->wiener));
    if (a->interp_n) json_object_set_new(root, "interp", interp_json(a->interp_n, run));
    json_object_set_new(root, "timing_ms",
                        json_pack("{s:o, s:o, s:o, s:o, s:o, s:o}", "read",
                                  fitjson_num(run->ms_read), "sweep", fitjson_num(run->ms_sweep),
                                  "ftest", fitjson_num(run->ms_ftest), "wiener",
                                  fitjson_num(run->ms_wiener), "interp",
                                  fitjson_num(run->ms_interp), "total",
                                  fitjson_num(cli_now_ms() - t0)));
    return root;
}

int cmd_fit(int argc, char **argv)
{
    double t0 = cli_now_ms();
    struct fit_args a;
    int rc = parse_args(argc, argv, &a);
    if (rc) return rc < 0 ? 0 : rc;
    struct fit_run run = {0};
    err_t err;
    if ((rc = run_all(&a, &run, &err))) {
        run_free(&run);
        return cli_fail(cli_exit_code(rc), "fit", "%s", err.msg);
    }
    if (a.table) {
        fit_table_print(stdout, a.path, &run.sf.scan, &run.sweep,
                        run.have_ftest ? &run.ftest : NULL, run.have_wiener ? &run.wiener : NULL,
                        cli_now_ms() - t0);
        run_free(&run);
        return 0;
    }
    json_t *root = result_json(&a, &run, t0);
    run_free(&run);
    if (!root) return cli_fail(CLI_EXIT_FAILURE, "fit", "out of memory building the output");
    rc = fitjson_print(root, stdout);
    json_decref(root);
    return rc ? cli_fail(CLI_EXIT_FAILURE, "fit", "writing the output failed") : 0;
}
