/* cmd_simulate.c: `ips simulate [options] -o FILE`: a scan by the simulated bench (instrument/
 * sim.h) written as a scan file. By default the paper's whole procedure runs (scan.h: exposure,
 * centring from a random start, focus, the 51 x 51 raster of 5 x 5 pixels with 9 x 9 sub-frames)
 * and the response of the pixel of interest at the positions inside it is written; --grid N
 * instead rasters N x N points directly inside the POI from its true centre (the paper's 9 x 9
 * of fig. 9); --write-subframe writes every raster point with the whole sub-frame read at each
 * (the scan file's `subframe`, for `ips fit --pixels all`); --adaptive scans the POI from its
 * true centre as --grid does, batch by batch where the kriged map is least sure (sim_adaptive.h,
 * fit/adapt_plan.h). Prints a JSON summary (setup errors against the truth, work, timing; an
 * adaptive scan's batches and errors). The scan's
 * options take their defaults and ranges from instrument/scan_limits.h, as the HTTP API does;
 * --dry-run checks them against the simulated bench and prints the configuration, simulating
 * nothing. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_rng.h>
#include <jansson.h>

#include "base/clock.h"
#include "base/opts.h"
#include "base/outfile.h"
#include "base/parse.h"
#include "cliutil.h"
#include "commands.h"
#include "fit/airy.h"
#include "instrument/scan.h"
#include "instrument/scan_limits.h"
#include "instrument/scanfile.h"
#include "instrument/sim.h"
#include "json/fitjson.h"
#include "sim_adaptive.h"

#define TRUTH_R_MAX 10

/* The options that set a field of scan_limits.h: usage text around the table's range and
 * default. */
static const struct {
    scan_field_id_t id;
    const char *metavar, *text, *extra; /* extra: a line under it, or NULL */
} field_usage[] = {
    {SCAN_F_SEED, "N", "seed of the noise and of the random start", NULL},
    {SCAN_F_GRID, "N", "N x N points inside the POI from its true centre, no setup", NULL},
    {SCAN_F_STEP_UM, "UM", "raster / grid step", NULL},
    {SCAN_F_AREA_PX, "N", "raster over N x N pixels", NULL},
    {SCAN_F_SUB_PX, "M", "M x M sub-frame per point", NULL},
    {SCAN_F_WAVELENGTH_NM, "NM", "wavelength of the spot", NULL},
    {SCAN_F_NA, "NA", "numerical aperture of the spot",
     "the simulated bench is dry: its NA must be below 1"},
    {SCAN_F_SPOT_RADIUS_UM, "UM", "spot radius, instead of --wavelength and --na", NULL},
    {SCAN_F_FRAMES, "K", "frames per point", NULL},
};

static void print_usage(void)
{
    fputs("usage: ips simulate [options] -o FILE\n"
          "  --scene S           uniform | paperlike | gradient | dip | deadcorner | edge |\n"
          "                      softedge | ring | busline | diagedge | bowl | twodips\n"
          "                      (each [:M], M x M cells) | map:FILE (default paperlike)\n",
          stdout);
    for (size_t i = 0; i < sizeof field_usage / sizeof field_usage[0]; i++) {
        const scan_field_t *f = &scan_fields[field_usage[i].id];
        char opt[32], range[64], def[40] = "";
        snprintf(opt, sizeof opt, "--%s %s", f->cli, field_usage[i].metavar);
        if (isfinite(f->def)) snprintf(def, sizeof def, "; default %.15g", f->def);
        printf("  %-19s %s (%s%s)\n", opt, field_usage[i].text,
               scan_field_range(f, range, sizeof range), def);
        if (field_usage[i].extra) printf("  %-19s %s\n", "", field_usage[i].extra);
    }
    fputs(
        "  --pixel DC,DR       write sub-frame pixel (DC, DR) instead of the POI (0,0)\n"
        "  --offset DX,DY      true spot position minus written position, um (default 0,0)\n"
        "  --written-radius UM spot radius written in the scan file (default the true one)\n"
        "  --peak-e E          photo-electrons of the whole spot per frame at the reference\n"
        "                      exposure on a uniform sensor (default 21500)\n"
        "  --noiseless         no photon or read noise, no ADC rounding\n"
        "  --all-points        write every point of the raster, not only those inside the\n"
        "                      pixel (positions still relative to its corner; for --region\n"
        "                      and the whole-raster Wiener baseline of ips fit)\n"
        "  --write-subframe    write every point of the raster with the whole sub-frame read at\n"
        "                      each (the scan file's subframe; positions relative to the POI's\n"
        "                      corner), for ips fit --pixels all; implies --all-points\n"
        "  --leave-out TOL     simulator leave-out tolerance, fraction of the spot's flux (1e-4)\n"
        "  --adaptive          scan the POI from its true centre (as --grid) adaptively: a\n"
        "                      coarse raster, then batches where the kriged map's posterior\n"
        "                      variance falls most, until its expected rms error reaches\n"
        "                      --target-err or --max-points are taken\n"
        "  --target-err E      stop at this expected rms error of the mean-1 map, met on two\n"
        "                      plans in a row with the same model (> 0; 0.01)\n"
        "  --max-points N      at most N points (at least the starting raster's; 300)\n"
        "  --batch B           positions a batch (>= 1; 9)\n"
        "  --start-grid N      the starting raster, N x N cell centres (2..51; 5)\n"
        "  --truth FILE        write the scene's true sub-pixel means for r = 1..10\n"
        "  --dry-run           check the options against the bench, print the configuration\n"
        "                      as JSON and simulate nothing (no -o needed)\n"
        "  -o, --output FILE   the scan file to write (required)\n",
        stdout);
}

struct sim_args {
    sim_config_t sim;
    scan_config_t scan;
    const char *out, *truth;
    int grid, dcol, drow, have_wavelength, have_na, have_radius, dry_run;
    int all_points; /* --all-points: every raster point, not only those inside the pixel */
    int write_subframe; /* --write-subframe: and every pixel of the sub-frame at each point */
    double offset_x, offset_y;
    double written_radius; /* --written-radius, 0: the bench's true radius */
    int adaptive;          /* --adaptive */
    int adaptive_opt;      /* the first of --target-err, --max-points, --batch, --start-grid */
    cli_adaptive_t ad;
};

enum {
    OPT_SCENE = 256,
    OPT_SEED,
    OPT_GRID,
    OPT_STEP,
    OPT_AREA,
    OPT_SUBFRAME,
    OPT_PIXEL,
    OPT_OFFSET,
    OPT_WAVELENGTH,
    OPT_NA,
    OPT_RADIUS,
    OPT_FRAMES,
    OPT_PEAK,
    OPT_NOISELESS,
    OPT_LEAVE,
    OPT_TRUTH,
    OPT_DRY_RUN,
    OPT_ALL_POINTS,
    OPT_WRITTEN_RADIUS,
    OPT_WRITE_SUBFRAME,
    OPT_ADAPTIVE,
    OPT_TARGET_ERR,
    OPT_MAX_POINTS,
    OPT_BATCH,
    OPT_START_GRID,
    OPT_HELP
};

static const struct option long_opts[] = {
    {"scene", required_argument, NULL, OPT_SCENE},
    {"seed", required_argument, NULL, OPT_SEED},
    {"grid", required_argument, NULL, OPT_GRID},
    {"step", required_argument, NULL, OPT_STEP},
    {"area", required_argument, NULL, OPT_AREA},
    {"subframe", required_argument, NULL, OPT_SUBFRAME},
    {"pixel", required_argument, NULL, OPT_PIXEL},
    {"offset", required_argument, NULL, OPT_OFFSET},
    {"wavelength", required_argument, NULL, OPT_WAVELENGTH},
    {"na", required_argument, NULL, OPT_NA},
    {"radius", required_argument, NULL, OPT_RADIUS},
    {"frames", required_argument, NULL, OPT_FRAMES},
    {"peak-e", required_argument, NULL, OPT_PEAK},
    {"noiseless", no_argument, NULL, OPT_NOISELESS},
    {"leave-out", required_argument, NULL, OPT_LEAVE},
    {"truth", required_argument, NULL, OPT_TRUTH},
    {"dry-run", no_argument, NULL, OPT_DRY_RUN},
    {"all-points", no_argument, NULL, OPT_ALL_POINTS},
    {"written-radius", required_argument, NULL, OPT_WRITTEN_RADIUS},
    {"write-subframe", no_argument, NULL, OPT_WRITE_SUBFRAME},
    {"adaptive", no_argument, NULL, OPT_ADAPTIVE},
    {"target-err", required_argument, NULL, OPT_TARGET_ERR},
    {"max-points", required_argument, NULL, OPT_MAX_POINTS},
    {"batch", required_argument, NULL, OPT_BATCH},
    {"start-grid", required_argument, NULL, OPT_START_GRID},
    {"output", required_argument, NULL, 'o'},
    {"help", no_argument, NULL, OPT_HELP},
    {NULL, 0, NULL, 0},
};

/* "A,B" into two numbers (integers when ints). */
static int pair(const char *name, const char *text, int ints, double *a, double *b, err_t *err)
{
    const char *comma = strchr(text, ',');
    char first[64];
    if (!comma || (size_t)(comma - text) >= sizeof first)
        return err_set(err, -EINVAL, "--%s must be two numbers A,B (got '%s')", name, text);
    memcpy(first, text, (size_t)(comma - text));
    first[comma - text] = '\0';
    int ia, ib;
    if (ints ? (parse_int(first, &ia) < 0 || parse_int(comma + 1, &ib) < 0)
             : (parse_double(first, a) < 0 || parse_double(comma + 1, b) < 0))
        return err_set(err, -EINVAL, "--%s must be two %s A,B (got '%s')", name,
                       ints ? "integers" : "numbers", text);
    if (ints) *a = ia, *b = ib;
    return 0;
}

/* A scan field's option: a number, checked against its row of scan_limits.h. */
static int field_opt(scan_field_id_t id, const char *arg, double *v, err_t *err)
{
    const scan_field_t *f = &scan_fields[id];
    char name[32];
    snprintf(name, sizeof name, "--%s", f->cli);
    if (parse_double(arg, v) < 0)
        return err_set(err, -EINVAL, "%s must be a number (got '%s')", name, arg);
    return scan_field_check(f, *v, name, err);
}

/* One option into a (opts_fn); returns 0 or -EINVAL with err. */
static int parse_opt(int c, const char *arg, void *user, err_t *err)
{
    struct sim_args *a = user;
    double v = 0, w;
    int rc = 0, iv = 0;
    switch (c) {
    case OPT_SCENE:
        a->sim.scene = arg;
        break;
    case OPT_SEED:
        if ((rc = field_opt(SCAN_F_SEED, arg, &v, err)) == 0) a->sim.seed = (unsigned long)v;
        break;
    case OPT_GRID:
        if ((rc = field_opt(SCAN_F_GRID, arg, &v, err)) == 0) a->grid = (int)v;
        break;
    case OPT_STEP:
        rc = field_opt(SCAN_F_STEP_UM, arg, &a->scan.step_um, err);
        break;
    case OPT_AREA:
        if ((rc = field_opt(SCAN_F_AREA_PX, arg, &v, err)) == 0) a->scan.area_px = (int)v;
        break;
    case OPT_SUBFRAME:
        if ((rc = field_opt(SCAN_F_SUB_PX, arg, &v, err)) == 0) a->scan.subframe_px = (int)v;
        break;
    case OPT_PIXEL:
        if ((rc = pair("pixel", arg, 1, &v, &w, err)) == 0) a->dcol = (int)v, a->drow = (int)w;
        break;
    case OPT_OFFSET:
        rc = pair("offset", arg, 0, &a->offset_x, &a->offset_y, err);
        break;
    case OPT_WAVELENGTH:
        rc = field_opt(SCAN_F_WAVELENGTH_NM, arg, &v, err);
        a->sim.wavelength_um = v * 1e-3, a->have_wavelength = 1;
        break;
    case OPT_NA:
        rc = field_opt(SCAN_F_NA, arg, &a->sim.na, err), a->have_na = 1;
        /* the simulated bench's objective is dry: sim_open refuses NA >= 1 (sim.h) */
        if (rc == 0 && !(a->sim.na < 1))
            rc = err_set(err, -EINVAL,
                         "--na must be below 1 on the simulated bench, a dry "
                         "objective (got %s)",
                         arg);
        break;
    case OPT_RADIUS:
        rc = field_opt(SCAN_F_SPOT_RADIUS_UM, arg, &a->sim.radius_um, err), a->have_radius = 1;
        break;
    case OPT_WRITTEN_RADIUS: /* what the scan file says, as a real bench's nominal radius */
        rc = field_opt(SCAN_F_SPOT_RADIUS_UM, arg, &a->written_radius, err);
        if (rc == 0 && !(a->written_radius > 0))
            rc = err_set(err, -EINVAL, "--written-radius must be above 0 (got %s)", arg);
        break;
    case OPT_FRAMES:
        if ((rc = field_opt(SCAN_F_FRAMES, arg, &v, err)) == 0) a->scan.frames = (int)v;
        break;
    case OPT_PEAK:
        rc = opts_num("peak-e", arg, 0, 1e12, &a->sim.flux_e, err);
        break;
    case OPT_NOISELESS:
        a->sim.noiseless = 1, a->scan.use_expected = 1;
        break;
    case OPT_LEAVE:
        rc = opts_num("leave-out", arg, 0, 0.5, &a->sim.leave_out_tol, err);
        break;
    case OPT_TRUTH:
        a->truth = arg;
        break;
    case OPT_ALL_POINTS: a->all_points = 1; return 0;
    case OPT_WRITE_SUBFRAME: a->write_subframe = a->all_points = 1; return 0;
    case OPT_DRY_RUN:
        a->dry_run = 1;
        break;
    case OPT_ADAPTIVE: a->adaptive = 1; return 0;
    case OPT_TARGET_ERR:
        rc = opts_num("target-err", arg, -INFINITY, INFINITY, &a->ad.target_err, err);
        if (rc == 0 && !(a->ad.target_err > 0))
            rc = err_set(err, -EINVAL, "--target-err must be above 0 (got %s)", arg);
        if (!a->adaptive_opt) a->adaptive_opt = c;
        break;
    case OPT_MAX_POINTS:
        if ((rc = opts_int32("max-points", arg, 1, SCAN_MAX_POINTS, &iv, err)) == 0)
            a->ad.max_points = (size_t)iv;
        if (!a->adaptive_opt) a->adaptive_opt = c;
        break;
    case OPT_BATCH:
        rc = opts_int32("batch", arg, 1, SCAN_MAX_POINTS, &a->ad.batch, err);
        if (!a->adaptive_opt) a->adaptive_opt = c;
        break;
    case OPT_START_GRID:
        rc = opts_int32("start-grid", arg, 2, 51, &a->ad.start_grid, err);
        if (!a->adaptive_opt) a->adaptive_opt = c;
        break;
    case 'o':
        a->out = arg;
        break;
    default:
        return err_set(err, -EINVAL, "unhandled option");
    }
    return rc;
}

static int parse_args(int argc, char **argv, struct sim_args *a)
{
    a->sim = sim_config_default();
    a->sim.wavelength_um = scan_fields[SCAN_F_WAVELENGTH_NM].def * 1e-3; /* the scan's defaults */
    a->sim.na = scan_fields[SCAN_F_NA].def;
    a->sim.seed = (unsigned long)scan_fields[SCAN_F_SEED].def;
    a->scan = scan_config_default();
    a->ad = cli_adaptive_default();
    err_t err;
    int first, rc = opts_parse(argc, argv, "o:", long_opts, OPT_HELP, "ips simulate --help",
                               parse_opt, a, &first, &err);
    if (rc == 1) {
        print_usage();
        return -1;
    }
    if (rc) return cli_fail(CLI_EXIT_USAGE, "simulate", "%s", err.msg);
    if (first < argc)
        return cli_fail(CLI_EXIT_USAGE, "simulate", "unexpected argument '%s'", argv[first]);
    if (!a->out && !a->dry_run) return cli_fail(CLI_EXIT_USAGE, "simulate", "-o FILE is required");
    if (a->have_radius && (a->have_wavelength || a->have_na))
        return cli_fail(CLI_EXIT_USAGE, "simulate", "give --radius or --wavelength/--na, not both");
    if (a->grid && (a->dcol || a->drow))
        return cli_fail(CLI_EXIT_USAGE, "simulate", "--pixel needs the full procedure, not --grid");
    if (a->write_subframe && a->grid)
        return cli_fail(CLI_EXIT_USAGE, "simulate",
                        "--write-subframe needs the full procedure, not --grid (the grid reads "
                        "the POI alone)");
    if (a->write_subframe && (a->dcol || a->drow))
        return cli_fail(CLI_EXIT_USAGE, "simulate",
                        "--write-subframe writes the POI's file (the sub-frame is centred on it): "
                        "not with --pixel");
    if (a->grid && a->all_points)
        return cli_fail(CLI_EXIT_USAGE, "simulate",
                        "--all-points needs the full procedure, not --grid (its points are all "
                        "inside the pixel)");
    if (a->adaptive_opt && !a->adaptive)
        return cli_fail(CLI_EXIT_USAGE, "simulate", "--%s needs --adaptive",
                        opts_name(long_opts, a->adaptive_opt));
    if (a->adaptive && (a->grid || a->all_points || a->dcol || a->drow))
        return cli_fail(CLI_EXIT_USAGE, "simulate",
                        "--adaptive chooses its own points inside the POI: not with --grid, "
                        "--all-points, --write-subframe or --pixel");
    if (a->adaptive && a->ad.max_points < (size_t)a->ad.start_grid * a->ad.start_grid)
        return cli_fail(CLI_EXIT_USAGE, "simulate",
                        "--max-points %zu is below the starting raster's %d points (--start-grid "
                        "%d)",
                        a->ad.max_points, a->ad.start_grid * a->ad.start_grid, a->ad.start_grid);
    int h = a->scan.subframe_px / 2;
    if (abs(a->dcol) > h || abs(a->drow) > h)
        return cli_fail(CLI_EXIT_USAGE, "simulate", "--pixel %d,%d is outside the %dx%d sub-frame",
                        a->dcol, a->drow, a->scan.subframe_px, a->scan.subframe_px);
    return 0;
}

/* The rules that need the bench (its sensor and spot), each naming the option: a usable spot
 * (eq. 1), the sub-frame on the sensor, the samples of a point, and the raster's whole steps and
 * size or the grid inside the pixel (scan_limits.h). */
static int check_on_bench(sim_t *sim, const struct sim_args *a, err_t *err)
{
    const scene_sensor_t *sn = scene_sensor(sim_scene(sim));
    const scan_config_t *c = &a->scan;
    double R = sim_spot_radius0(sim);
    int h = c->subframe_px / 2, rc;
    if (!(R > 0 && isfinite(R)))
        return err_set(err, -EINVAL, "%s: eq. 1 gives a spot radius of %g um, not a usable radius",
                       a->have_na ? "--na" : "--wavelength", R);
    if (c->poi_col - h < 0 || c->poi_row - h < 0 || c->poi_col + h >= sn->cols ||
        c->poi_row + h >= sn->rows)
        return err_set(err, -EINVAL,
                       "--subframe: the %dx%d sub-frame around pixel (%d, %d) leaves the %dx%d "
                       "sensor",
                       c->subframe_px, c->subframe_px, c->poi_col, c->poi_row, sn->cols, sn->rows);
    if ((rc = scan_check_samples(c->frames, c->subframe_px, "--frames", err))) return rc;
    if (a->grid) return scan_check_grid(sn->pitch_um, a->grid, c->step_um, "--grid", err);
    return scan_check_raster(sn->pitch_um, c->area_px, c->step_um, "--step", NULL, err);
}

/* --dry-run: what would be simulated. */
static json_t *dry_run(sim_t *sim, const struct sim_args *a)
{
    const scene_sensor_t *sn = scene_sensor(sim_scene(sim));
    const scan_config_t *c = &a->scan;
    double R = sim_spot_radius0(sim), lambda = a->sim.wavelength_um;
    double na = a->have_radius ? fit_spot_na(lambda, R) : a->sim.na;
    json_t *grid = a->grid ? json_integer(a->grid) : json_null(), *root;
    root = json_pack("{s:s, s:s, s:I, s:o, s:[ii], s:{s:f, s:f, s:f}, s:{s:i, s:f, s:i, s:i, s:i}}",
                     "scene", scene_name(sim_scene(sim)), "mode",
                     a->adaptive ? "adaptive" : a->grid ? "grid" : "procedure",
                     "seed", (json_int_t)a->sim.seed, "grid", grid, "poi", c->poi_col, c->poi_row,
                     "optics", "wavelength_nm", lambda * 1e3, "na", na, "spot_radius_um", R,
                     "raster", "area_px", c->area_px, "step_um", c->step_um, "sub_px",
                     c->subframe_px, "frames", c->frames, "points_per_axis",
                     a->grid ? a->grid : scan_axis_points(sn->pitch_um, c->area_px, c->step_um));
    if (root && a->adaptive) /* the planner's options (sim_adaptive.h) */
        json_object_set_new(root, "adaptive",
                            json_pack("{s:i, s:i, s:f, s:I}", "start_grid", a->ad.start_grid,
                                      "batch", a->ad.batch, "target_err", a->ad.target_err,
                                      "max_points", (json_int_t)a->ad.max_points));
    return root;
}

/* The truth file: the scene's sub-pixel means for r = 1..TRUTH_R_MAX, raw and mean-1. */
static int write_truth(const sim_t *sim, const char *path, err_t *err)
{
    const scene_t *sc = sim_scene(sim);
    int m, rc = 0;
    scene_map(sc, &m);
    json_t *root = json_object(), *maps = json_array();
    json_object_set_new(root, "scene", json_string(scene_name(sc)));
    json_object_set_new(root, "pitch_um", json_real(scene_sensor(sc)->pitch_um));
    json_object_set_new(root, "map_resolution", json_integer(m));
    json_object_set_new(
        root, "note",
        json_string("S[j*r+i]: mean sensitivity of sub-pixel column i, row j (y downward) of the "
                    "simulator's "
                    "piecewise-constant map; S_normalised has mean 1, as ips fit reports S"));
    double S[TRUTH_R_MAX * TRUTH_R_MAX];
    for (int r = 1; r <= TRUTH_R_MAX && rc == 0; r++) {
        if ((rc = scene_truth(sc, r, S, err)) != 0) break;
        double mean = 0;
        for (int c = 0; c < r * r; c++)
            mean += S[c] / (r * r);
        json_t *e = json_object(), *norm = json_array();
        json_object_set_new(e, "r", json_integer(r));
        json_object_set_new(e, "mean", json_real(mean));
        json_object_set_new(e, "S", fitjson_array(S, (size_t)r * r));
        for (int c = 0; c < r * r; c++)
            json_array_append_new(norm, json_real(S[c] / mean));
        json_object_set_new(e, "S_normalised", norm);
        json_array_append_new(maps, e);
    }
    json_object_set_new(root, "maps", maps);
    outfile_t o;
    if (rc == 0 && (rc = outfile_open(path, &o, err)) == 0) {
        if (json_dumpf(root, o.f, JSON_INDENT(1) | JSON_REAL_PRECISION(17)) != 0) {
            outfile_abort(&o);
            rc = err_set(err, -EIO, "cannot write the truth file %s", path);
        } else {
            rc = outfile_commit(&o, err);
        }
    }
    json_decref(root);
    return rc;
}

struct outcome {
    scanfile_t sf;
    json_t *adaptive; /* --adaptive: its report (sim_adaptive.h) */
    double *sub_dn; /* --write-subframe: sf.scan.n * m*m means, point after point */
    scan_setup_t su;
    stage_pos_t found; /* centre the setup found, before --offset */
    double setup_ms, raster_ms;
};

/* --grid and --adaptive: no setup; the scan starts at the POI's true centre (shifted by
 * --offset). Fills c, o->su, o->found and o->setup_ms; *t0 gets the start time. */
static int prepare_at_true_centre(sim_t *sim, const struct sim_args *a, scan_config_t *c,
                                  struct outcome *o, double *t0, err_t *err)
{
    *c = a->scan;
    c->do_centre = c->do_focus = c->do_exposure = 0;
    c->start = sim_pixel_centre(sim, c->poi_col, c->poi_row);
    *t0 = clock_mono_ms();
    int rc = scan_prepare(sim_camera(sim), sim_stage(sim), c, NULL, &o->su, err);
    o->found = o->su.centre;
    o->su.centre.x_um += a->offset_x;
    o->su.centre.y_um += a->offset_y;
    o->setup_ms = clock_mono_ms() - *t0;
    return rc;
}

/* --grid: N x N points around the POI's true centre. */
static int run_grid(sim_t *sim, const struct sim_args *a, struct outcome *o, err_t *err)
{
    scan_config_t c;
    double t0;
    int rc = prepare_at_true_centre(sim, a, &c, o, &t0, err);
    if (rc == 0)
        rc = scan_grid_pixel(sim_camera(sim), sim_stage(sim), &c, &o->su, a->grid, NULL, &o->sf,
                             err);
    o->raster_ms = clock_mono_ms() - o->setup_ms - t0;
    return rc;
}

/* --adaptive: the planner's batches from there (sim_adaptive.h). */
static int run_adaptive(sim_t *sim, const struct sim_args *a, struct outcome *o, err_t *err)
{
    scan_config_t c;
    double t0;
    int rc = prepare_at_true_centre(sim, a, &c, o, &t0, err);
    if (rc == 0) rc = cli_adaptive_run(sim, &c, &o->su, &a->ad, &o->sf, &o->adaptive, err);
    o->raster_ms = clock_mono_ms() - o->setup_ms - t0;
    return rc;
}

/* --write-subframe: every captured point's m x m means, in the order scan_extract_pixel_region
 * wrote the points (raster order, captured points only). */
static int keep_subframe(const scan_raster_t *r, struct outcome *o, err_t *err)
{
    size_t mm = (size_t)r->m * r->m, k = 0;
    if (!(o->sub_dn = malloc((o->sf.scan.n ? o->sf.scan.n : 1) * mm * sizeof *o->sub_dn)))
        return err_set(err, -ENOMEM, "out of memory for the sub-frame");
    for (size_t i = 0; i < r->count; i++)
        if (r->have[i]) memcpy(o->sub_dn + k++ * mm, r->mean_dn + i * mm, mm * sizeof(double));
    return k == o->sf.scan.n ? 0 : err_set(err, -EIO, "the raster changed under the sub-frame");
}

/* The paper's procedure from a random start (seeded): up to 1.5 um off in x and y, 8 um in z. */
static int run_procedure(sim_t *sim, const struct sim_args *a, struct outcome *o, err_t *err)
{
    scan_config_t c = a->scan;
    stage_pos_t truth = sim_pixel_centre(sim, c.poi_col, c.poi_row);
    gsl_rng *rng = gsl_rng_alloc(gsl_rng_mt19937);
    if (!rng) return err_set(err, -ENOMEM, "out of memory");
    gsl_rng_set(rng, a->sim.seed ^ 0x5eedUL);
    c.start = (stage_pos_t){truth.x_um + 3 * (gsl_rng_uniform(rng) - 0.5),
                            truth.y_um + 3 * (gsl_rng_uniform(rng) - 0.5),
                            truth.z_um + 16 * (gsl_rng_uniform(rng) - 0.5)};
    gsl_rng_free(rng);
    scan_raster_t r;
    memset(&r, 0, sizeof r);
    double t0 = clock_mono_ms();
    int rc = scan_prepare(sim_camera(sim), sim_stage(sim), &c, NULL, &o->su, err);
    o->found = o->su.centre;
    /* --offset: the raster is centred that far from the found centre, the file does not know */
    o->su.centre.x_um += a->offset_x;
    o->su.centre.y_um += a->offset_y;
    o->setup_ms = clock_mono_ms() - t0;
    if (rc == 0) rc = scan_raster_init(&r, &c, &o->su, err);
    if (rc == 0)
        rc = scan_raster_run(sim_camera(sim), sim_stage(sim), &c, &o->su, 0, NULL, &r, err);
    if (rc == 0) rc = scan_extract_pixel_region(&r, a->dcol, a->drow, a->all_points, &o->sf, err);
    if (rc == 0 && a->write_subframe) rc = keep_subframe(&r, o, err);
    o->raster_ms = clock_mono_ms() - o->setup_ms - t0;
    scan_raster_free(&r);
    return rc;
}

static json_t *summary(sim_t *sim, const struct sim_args *a, const struct outcome *o)
{
    stage_pos_t truth = sim_pixel_centre(sim, a->scan.poi_col, a->scan.poi_row);
    sim_stats_t st;
    sim_get_stats(sim, &st);
    json_t *root = json_object(), *setup = json_object(), *work = json_object(),
           *timing = json_object(), *cerr = json_array();
    json_object_set_new(root, "output", json_string(a->out));
    json_object_set_new(root, "scene", json_string(scene_name(sim_scene(sim))));
    json_object_set_new(root, "mode", json_string(a->adaptive ? "adaptive"
                                                  : a->grid   ? "grid"
                                                              : "procedure"));
    json_object_set_new(root, "points", json_integer((json_int_t)o->sf.scan.n));
    json_object_set_new(root, "spot_radius_um", json_real(sim_spot_radius0(sim)));
    json_object_set_new(root, "written_spot_radius_um", json_real(o->sf.scan.spot_radius_um));
    json_object_set_new(root, "pixel", json_pack("[ii]", a->dcol, a->drow));
    json_array_append_new(cerr, json_real(o->found.x_um - truth.x_um));
    json_array_append_new(cerr, json_real(o->found.y_um - truth.y_um));
    json_object_set_new(setup, "centre_error_um", cerr);
    json_object_set_new(setup, "focus_error_um", json_real(o->found.z_um - truth.z_um));
    json_object_set_new(setup, "focus_tolerance_um", json_real(sim_focus_tolerance(sim)));
    json_object_set_new(setup, "exposure_us", json_real(o->su.exposure_us));
    json_object_set_new(setup, "peak_dn", fitjson_num(o->su.peak_dn));
    json_object_set_new(setup, "imbalance",
                        json_pack("[ff]", o->su.imbalance_x, o->su.imbalance_y));
    json_object_set_new(setup, "evaluations", json_integer(o->su.focus_evaluations));
    json_object_set_new(root, "setup", setup);
    json_object_set_new(work, "frames", json_integer((json_int_t)st.frames));
    json_object_set_new(work, "pixel_frames", json_integer((json_int_t)st.pixel_frames));
    json_object_set_new(work, "memo_hits", json_integer((json_int_t)st.hits));
    json_object_set_new(work, "integrated_full", json_integer((json_int_t)st.full));
    json_object_set_new(work, "integrated_coarse", json_integer((json_int_t)st.coarse));
    json_object_set_new(work, "integrated_uniform", json_integer((json_int_t)st.uniform));
    json_object_set_new(work, "left_out", json_integer((json_int_t)st.left_out));
    json_object_set_new(work, "max_left_out_e", json_real(st.max_left_out_e));
    json_object_set_new(root, "simulator", work);
    json_object_set_new(timing, "setup", json_real(o->setup_ms));
    json_object_set_new(timing, "raster", json_real(o->raster_ms));
    json_object_set_new(root, "timing_ms", timing);
    if (o->adaptive) json_object_set(root, "adaptive", o->adaptive);
    return root;
}

/* The scan file's `adaptive` (an addition to the scan-file contract): the starting raster and the
 * points each batch added, in the file's order. 0 or -1 when out of memory. */
static int adaptive_note(json_t *report, json_t *extra)
{
    json_t *added = json_array(), *b;
    size_t i;
    json_array_foreach(json_object_get(report, "batches"), i, b)
        json_array_append(added, json_object_get(b, "added"));
    return json_object_set_new(extra, "adaptive",
                               json_pack("{s:O, s:o}", "start_grid",
                                         json_object_get(report, "start_grid"), "batches", added));
}

int cmd_simulate(int argc, char **argv)
{
    struct sim_args a = {0};
    int rc = parse_args(argc, argv, &a);
    if (rc) return rc < 0 ? 0 : rc;
    err_t err;
    sim_t *sim = NULL;
    struct outcome o;
    memset(&o, 0, sizeof o);
    if ((rc = sim_open(&a.sim, &sim, &err)) != 0)
        return cli_fail(cli_exit_code(rc), "simulate", "%s", err.msg);
    const scene_sensor_t *sn = scene_sensor(sim_scene(sim));
    a.scan.poi_col = sn->cols / 2;
    a.scan.poi_row = sn->rows / 2;
    a.scan.spot_radius_um = a.written_radius > 0 ? a.written_radius : sim_spot_radius0(sim);
    if ((rc = check_on_bench(sim, &a, &err)) != 0) {
        sim_close(sim);
        return cli_fail(CLI_EXIT_USAGE, "simulate", "%s", err.msg);
    }
    if (a.dry_run) {
        json_t *root = dry_run(sim, &a);
        int code = root && fitjson_print(root, stdout) == 0 ? 0 : CLI_EXIT_FAILURE;
        json_decref(root);
        sim_close(sim);
        return code;
    }
    rc = a.adaptive ? run_adaptive(sim, &a, &o, &err)
         : a.grid   ? run_grid(sim, &a, &o, &err)
                    : run_procedure(sim, &a, &o, &err);
    json_t *extra = NULL;
    if (rc == 0) {
        extra = json_pack(
            "{s:s}", "description",
            "ips simulate: a scan of one pixel by the simulated bench (instrument/sim.h)");
        if (extra && o.sub_dn &&
            json_object_set_new(extra, "subframe",
                                scanfile_subframe_json(a.scan.subframe_px, a.scan.step_um,
                                                       o.sub_dn, o.sf.scan.n)))
            rc = err_set(&err, -ENOMEM, "out of memory writing the sub-frame");
        if (rc == 0 && extra && o.adaptive && adaptive_note(o.adaptive, extra))
            rc = err_set(&err, -ENOMEM, "out of memory writing the adaptive scan's batches");
        if (rc == 0) rc = scanfile_write(a.out, &o.sf.scan, extra, &err);
    }
    if (rc == 0 && a.truth) rc = write_truth(sim, a.truth, &err);
    int code = 0;
    if (rc)
        code = cli_fail(rc == -ECANCELED || rc == -EIO ? CLI_EXIT_FAILURE : cli_exit_code(rc),
                        "simulate", "%s", err.msg);
    else {
        json_t *root = summary(sim, &a, &o);
        if (fitjson_print(root, stdout) != 0) code = CLI_EXIT_FAILURE;
        json_decref(root);
    }
    json_decref(extra);
    json_decref(o.adaptive);
    free(o.sub_dn);
    scanfile_free(&o.sf);
    sim_close(sim);
    return code;
}
