/* sim_adaptive.c: `ips simulate --adaptive` (sim_adaptive.h): the starting n0 x n0 raster, then
 * plan (fit/adapt_plan.h: the kriged map of the points so far, its expected rms error e under the
 * neighbouring priors, the next batch where it lowers tr Sigma most), take the batch, and again
 * until e <= target after a planned batch (the planner's stop rule), the budget is spent
 * or no candidate helps. The allowed box is the stage's travel seen from the pixel's corner. Each
 * map is scored against the scene's truth as the fidelity harness scores maps
 * (instrument/fidelity.h, fid_map_rms: the rms of the two mean-1 maps over the pixel). */
#include "sim_adaptive.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fit/adapt_plan.h"
#include "instrument/fidelity.h"
#include "instrument/scene.h"
#include "json/fitjson.h"

#define TRUTH_SAMPLES 240 /* per axis, as the fidelity harness samples */

cli_adaptive_t cli_adaptive_default(void)
{
    return (cli_adaptive_t){.start_grid = FIT_ADAPT_START_GRID,
                            .batch = FIT_ADAPT_BATCH,
                            .target_err = FIT_ADAPT_TARGET_ERR,
                            .max_points = FIT_ADAPT_MAX_POINTS};
}

/* The planner's options: the CLI's, and the stage's travel as the allowed box. */
static int plan_opts(sim_t *sim, const scan_setup_t *su, const cli_adaptive_t *ad,
                     fit_adapt_opts_t *o, err_t *err)
{
    *o = fit_adapt_opts_default();
    o->batch = ad->batch;
    o->target_err = ad->target_err;
    o->max_points = ad->max_points;
    return scan_pixel_box(sim_stage(sim), su, o->box_um, err);
}

/* The map after a batch, into that batch's entry. */
static void score(const sim_t *sim, const fit_adapt_step_t *st, json_t *entry)
{
    int m;
    const double *T = scene_map(sim_scene(sim), &m);
    double rms = fid_map_rms(st->map.S, st->map.grid, T, m, TRUTH_SAMPLES);
    json_object_set_new(entry, "fitted", json_integer((json_int_t)st->n_fitted));
    json_object_set_new(entry, "expected_err", fitjson_num(st->expected_err));
    json_object_set_new(entry, "posterior_err", fitjson_num(st->posterior_err));
    json_object_set_new(entry, "target_met", json_boolean(st->target_met));
    json_object_set_new(entry, "rms_err_truth", fitjson_num(rms));
    json_object_set_new(entry, "r", json_integer(st->r));
    json_object_set_new(entry, "grid", json_integer(st->map.grid));
    json_object_set_new(entry, "smooth", json_boolean(st->map.smooth));
    json_object_set_new(entry, "plan_ms", json_real(st->ms));
}

static json_t *batch_entry(size_t points, int added, double path_um, double predicted)
{
    return json_pack("{s:I, s:i, s:o, s:o}", "points", (json_int_t)points, "added", added,
                     "path_um", fitjson_num(path_um), "predicted_err", fitjson_num(predicted));
}

int cli_adaptive_run(sim_t *sim, const scan_config_t *cfg, const scan_setup_t *su,
                     const cli_adaptive_t *ad, scanfile_t *sf, json_t **report, err_t *err)
{
    *report = NULL;
    fit_adapt_opts_t o;
    int rc = plan_opts(sim, su, ad, &o, err);
    if (rc) return rc;
    size_t n0 = (size_t)ad->start_grid * ad->start_grid;
    double *x = malloc(sizeof(double) * n0), *y = malloc(sizeof(double) * n0);
    json_t *batches = json_array(), *root = json_object();
    if (!x || !y || !batches || !root) {
        rc = err_set(err, -ENOMEM, "out of memory");
        goto out;
    }
    int n = fit_adapt_start(su->pitch_um, ad->start_grid, o.box_um, x, y);
    if (n < 1) {
        rc = err_set(err, -EINVAL, "--start-grid: no position of the %dx%d raster is within the "
                     "stage's travel", ad->start_grid, ad->start_grid);
        goto out;
    }
    o.start_points = (size_t)n;
    if ((rc = scan_file_new(su, cfg->frames, 0, sf, err))) goto out;
    double path = 0, px = su->pitch_um / 2, py = px; /* the start's path from the centre */
    for (int k = 0; k < n; k++) path += hypot(x[k] - px, y[k] - py), px = x[k], py = y[k];
    if ((rc = scan_pixel_points(sim_camera(sim), sim_stage(sim), cfg, su, (size_t)n, x, y, NULL,
                                sf, err)))
        goto out;
    json_array_append_new(batches, batch_entry(sf->scan.n, n, path, NAN));
    fit_adapt_stop_t stop = FIT_ADAPT_GO;
    double last_expected = NAN, last_rms = NAN;
    fit_adapt_cache_t cache = {0}; /* the candidates' design rows, from plan to plan */
    while (stop == FIT_ADAPT_GO) {
        fit_adapt_step_t st;
        rc = fit_adapt_plan(&sf->scan, &o, &cache, &st, err);
        if (rc) {
            fit_adapt_step_free(&st);
            goto out;
        }
        json_t *entry = json_array_get(batches, json_array_size(batches) - 1);
        score(sim, &st, entry);
        last_expected = st.expected_err;
        last_rms = json_real_value(json_object_get(entry, "rms_err_truth"));
        stop = st.stop;
        if (stop == FIT_ADAPT_GO) {
            rc = scan_pixel_points(sim_camera(sim), sim_stage(sim), cfg, su, (size_t)st.n, st.x_um,
                                   st.y_um, NULL, sf, err);
            if (rc == 0)
                json_array_append_new(batches,
                                      batch_entry(sf->scan.n, st.n, st.path_um, st.predicted_err));
        }
        fit_adapt_step_free(&st);
        if (rc) goto out;
    }
    json_object_set_new(root, "start_grid", json_integer(ad->start_grid));
    json_object_set_new(root, "batch", json_integer(ad->batch));
    json_object_set_new(root, "target_err", json_real(ad->target_err));
    json_object_set_new(root, "max_points", json_integer((json_int_t)ad->max_points));
    json_object_set_new(root, "lattice", json_integer(o.lattice));
    json_object_set_new(root, "sigma", json_string(fit_noise_name(o.fit.noise)));
    json_object_set_new(root, "stop", json_string(fit_adapt_stop_name(stop)));
    json_object_set_new(root, "points", json_integer((json_int_t)sf->scan.n));
    json_object_set_new(root, "expected_err", fitjson_num(last_expected));
    json_object_set_new(root, "rms_err_truth", fitjson_num(last_rms));
    json_object_set_new(root, "batches", batches);
    batches = NULL;
    *report = root;
    root = NULL;
out:
    fit_adapt_cache_free(&cache);
    free(x), free(y);
    json_decref(batches);
    json_decref(root);
    return rc;
}
