/* fidelity.c: map error against the simulator's truth (see fidelity.h). */
#include "instrument/fidelity.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "fit/krige.h"
#include "fit/model.h"
#include "fit/shrink.h"
#include "fit/wiener.h"
#include "instrument/scan.h"
#include "instrument/scanfile.h"
#include "instrument/sim.h"

#define SAMPLES 240 /* per axis: a multiple of r = 1..6, 8, 10, 12 and of the 30-cell scenes */

/* Mean of v (n values). */
static double mean_of(const double *v, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; i++) s += v[i];
    return n ? s / (double)n : NAN;
}

double fid_map_rms(const double *S, int r, const double *T, int m, int g)
{
    double ms = mean_of(S, (size_t)r * r), mt = mean_of(T, (size_t)m * m), acc = 0;
    if (!(ms > 0) || !(mt > 0)) return NAN;
    for (int j = 0; j < g; j++)
        for (int i = 0; i < g; i++) {
            double u = (i + 0.5) / g, v = (j + 0.5) / g; /* fraction of the pitch */
            double s = S[(int)(v * r) * r + (int)(u * r)] / ms;
            double t = T[(int)(v * m) * m + (int)(u * m)] / mt;
            acc += (s - t) * (s - t);
        }
    return sqrt(acc / ((double)g * g));
}

/* The Wiener map (on the scan grid) over the pixel: bilinear between grid points, the nearest
 * grid value beyond the outermost ones, sampled like fid_map_rms; mean 1 over the pixel. */
static double wiener_rms(const fit_wiener_t *w, double p, const double *T, int m, int g)
{
    double *v = malloc(sizeof(double) * (size_t)g * g);
    if (!v) return NAN;
    for (int j = 0; j < g; j++)
        for (int i = 0; i < g; i++) {
            double fx = ((i + 0.5) / g * p - w->x0_um) / w->step_x_um;
            double fy = ((j + 0.5) / g * p - w->y0_um) / w->step_y_um;
            fx = fmin(fmax(fx, 0), w->nx - 1);
            fy = fmin(fmax(fy, 0), w->ny - 1);
            int ix = (int)fmin(floor(fx), w->nx - 2), iy = (int)fmin(floor(fy), w->ny - 2);
            if (ix < 0) ix = 0;
            if (iy < 0) iy = 0;
            double ax = w->nx > 1 ? fx - ix : 0, ay = w->ny > 1 ? fy - iy : 0;
            int ix1 = w->nx > 1 ? ix + 1 : ix, iy1 = w->ny > 1 ? iy + 1 : iy;
            v[j * g + i] = (1 - ay) * ((1 - ax) * w->S[iy * w->nx + ix] + ax * w->S[iy * w->nx + ix1]) +
                           ay * ((1 - ax) * w->S[iy1 * w->nx + ix] + ax * w->S[iy1 * w->nx + ix1]);
        }
    double rms = fid_map_rms(v, g, T, m, g); /* a g x g map sampled at its own cells */
    free(v);
    return rms;
}

/* The S_err z-scores of the recommended and the shrunk map against the truth's mean over each
 * sub-pixel (fidelity.h), both maps and the truth's means scaled to mean 1; and the same with
 * the resolution error S_res added in quadrature (fit/shrink.h). */
static void z_scores(const fit_sweep_t *sw, double scale, const double *T, int m,
                     fid_result_t *out)
{
    const fit_shrunk_t *sh = sw->shrunk;
    const fit_result_t *f = &sw->fits[sh->r - sw->r_min];
    int r = sh->r;
    double *tc = malloc(sizeof(double) * r * r), mean = 0;
    if (!tc || fit_grid_average(T, m, r, tc)) goto out; /* the truth's mean over each sub-pixel */
    for (int q = 0; q < r * r; q++) mean += tc[q] / (r * r);
    for (int q = 0; q < r * r; q++) {
        double t = tc[q] / mean, er = f->S_err[q] * scale, es = sh->S_err[q] * scale,
               b2 = sh->S_res[q] * sh->S_res[q], dr = f->S[q] - t, ds = sh->S[q] - t;
        double zr = dr / er, zs = ds / es, zrr = dr / sqrt(er * er + b2),
               zsr = ds / sqrt(es * es + b2);
        out->z_n++;
        out->z2_rec += zr * zr;
        out->z2_shrunk += zs * zs;
        out->z_in2_rec += fabs(zr) <= 2;
        out->z_in2_shrunk += fabs(zs) <= 2;
        out->z2_rec_res += zrr * zrr;
        out->z2_shrunk_res += zsr * zsr;
        out->z_in2_rec_res += fabs(zrr) <= 2;
        out->z_in2_shrunk_res += fabs(zsr) <= 2;
    }
out:
    free(tc);
}

/* The r of sweep sw whose map is nearest the kriged map (S, F x F), sampled like the errors:
 * given the data, the truth ~ N(S, C) under the kriged model, so E|S_r - truth|^2 = |S_r - S|^2
 * + tr C, and the nearest map is the one r a Bayesian would pick. 0 when no r has a map. */
static int posterior_pick(const fit_sweep_t *sw, const double *S, int F)
{
    int pick = 0;
    double best = INFINITY;
    for (int r = sw->r_min; r <= sw->r_max; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        double d = f->S ? fid_map_rms(f->S, r, S, F, SAMPLES) : NAN;
        if (d < best) best = d, pick = r;
    }
    return pick;
}

/* The kriged map the fit job stores (fit/krige.h, the sweep's prior fit_krige_prior_for_sweep;
 * none when the rule recommends no r): its error and S_err's honesty against the truth's mean
 * over each fine cell (both mean 1), and the sweep's r nearest it. */
static void kriged(const fit_scan_t *scan, const fit_options_t *o, const fit_sweep_t *sw, int r,
                   const double *T, int m, fid_result_t *out)
{
    fit_kriged_t k;
    err_t e;
    if (r < 1) return;
    fit_krige_prior_t pr = fit_krige_prior_for_sweep(sw);
    if (fit_krige_with(scan, &pr, o, &k, &e)) return;
    int F = k.grid;
    double *tc = malloc(sizeof(double) * F * F), mean = 0;
    out->rms_kriged = fid_map_rms(k.S, F, T, m, SAMPLES);
    out->kriged_grid = F;
    out->kriged_smooth = k.smooth;
    out->kriged_ms = k.ms;
    out->r_post = posterior_pick(sw, k.S, F);
    if (tc && fit_grid_average(T, m, F, tc) == 0) {
        for (int q = 0; q < F * F; q++) mean += tc[q] / (F * F);
        for (int q = 0; q < F * F; q++) {
            if (!(k.S_err[q] > 0)) continue; /* a flat map without freedom: exactly 1 */
            double z = (k.S[q] - tc[q] / mean) / k.S_err[q];
            out->z_n_kriged++;
            out->z2_kriged += z * z;
            out->z_in2_kriged += fabs(z) <= 2;
        }
    }
    free(tc);
    fit_kriged_free(&k);
}

/* Simulates the case's scan into *sf. */
static int simulate(const fid_case_t *c, sim_t *sim, scanfile_t *sf, err_t *err)
{
    const scene_sensor_t *sn = scene_sensor(sim_scene(sim));
    scan_config_t cfg = scan_config_default();
    cfg.poi_col = sn->cols / 2;
    cfg.poi_row = sn->rows / 2;
    cfg.spot_radius_um = sim_spot_radius0(sim);
    cfg.start = sim_pixel_centre(sim, cfg.poi_col, cfg.poi_row);
    cfg.do_centre = cfg.do_focus = cfg.do_exposure = 0; /* the truth's centre: the map is the test */
    cfg.step_um = c->step_um;
    scan_setup_t su;
    int rc;
    if (c->grid > 0) {
        rc = scan_prepare(sim_camera(sim), sim_stage(sim), &cfg, NULL, &su, err);
        if (rc == 0)
            rc = scan_grid_pixel(sim_camera(sim), sim_stage(sim), &cfg, &su, c->grid, NULL, sf,
                                 err);
        return rc;
    }
    cfg.area_px = c->area_px > 0 ? c->area_px : 5;
    cfg.subframe_px = 3; /* the POI is all the fit reads */
    scan_raster_t r;
    rc = scan_run(sim_camera(sim), sim_stage(sim), &cfg, NULL, &r, err);
    if (rc == 0) rc = scan_extract_pixel_region(&r, 0, 0, 1, sf, err); /* every point */
    scan_raster_free(&r);
    return rc;
}

int fid_run(const fid_case_t *c, int r_max, fid_result_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (r_max < 1 || r_max > FID_R_MAX)
        return err_set(err, -EINVAL, "r_max must be 1..%d (got %d)", FID_R_MAX, r_max);
    out->r_max = r_max;
    for (int r = 0; r <= FID_R_MAX; r++)
        out->rms[r] = out->chi2_red[r] = out->cv_chi2[r] = out->serr_rms[r] = NAN;
    out->rms_wiener = out->rms_wiener_whole = out->rms_shrunk = out->shrunk_factor = NAN;
    out->rms_kriged = out->kriged_ms = NAN;
    for (int r = 0; r <= FID_R_MAX; r++) out->serr_edge[r] = out->serr_inner[r] = NAN;
    sim_config_t sc = sim_config_default();
    sc.scene = c->scene;
    sc.seed = c->seed;
    sc.flux_e *= c->flux_scale > 0 ? c->flux_scale : 1;
    sim_t *sim = NULL;
    scanfile_t sf = {0};
    fit_sweep_t sw = {0};
    fit_scan_sel_t in = {0}, fitted = {0};
    double t0 = clock_mono_ms();
    int rc = sim_open(&sc, &sim, err);
    if (rc == 0) rc = simulate(c, sim, &sf, err);
    out->sim_ms = clock_mono_ms() - t0;
    if (rc == 0) rc = fit_region_select(&sf.scan, NULL, &in, err); /* inside: the old Wiener's */
    if (rc == 0) rc = fit_region_select(&sf.scan, &c->region, &fitted, err);
    if (rc) goto done;
    out->n_raster = sf.scan.n;
    out->n_points = fitted.scan.n;
    int m;
    const double *T = scene_map(sim_scene(sim), &m);
    fit_options_t o = fit_options_default();
    o.noise = c->noise;
    t0 = clock_mono_ms();
    rc = fit_sweep_run(&fitted.scan, 1, r_max, &o, &sw, err);
    out->fit_ms = clock_mono_ms() - t0;
    if (rc) goto done;
    double best = INFINITY;
    for (int r = 1; r <= r_max; r++) {
        const fit_result_t *f = &sw.fits[r - 1];
        out->chi2_red[r] = f->chi2_red;
        out->cv_chi2[r] = f->cv_chi2;
        if (!f->S) continue;
        if (!out->r_cv || f->cv_chi2 < out->cv_chi2[out->r_cv]) out->r_cv = r;
        double v = 0;
        for (int j = 0; j < r * r; j++) v += f->S_err[j] * f->S_err[j];
        out->serr_rms[r] = sqrt(v / (r * r));
        double ve = 0, vi = 0;
        for (int j = 0; j < r; j++)
            for (int i = 0; i < r; i++) {
                double e2 = f->S_err[j * r + i] * f->S_err[j * r + i];
                if (i == 0 || j == 0 || i == r - 1 || j == r - 1) ve += e2;
                else vi += e2;
            }
        out->serr_edge[r] = sqrt(ve / (r > 1 ? 4.0 * (r - 1) : 1));
        if (r > 2) out->serr_inner[r] = sqrt(vi / ((r - 2.0) * (r - 2)));
        out->rms[r] = fid_map_rms(f->S, r, T, m, SAMPLES);
        if (out->rms[r] < best) best = out->rms[r], out->r_best = r;
    }
    if (c->on_sweep) c->on_sweep(&fitted.scan, &o, &sw, c->on_sweep_ctx);
    if (sw.shrunk) {
        out->rms_shrunk = fid_map_rms(sw.shrunk->S, sw.shrunk->r, T, m, SAMPLES);
        out->shrunk_factor = sw.shrunk->factor;
    }
    out->r_aic = sw.best_aic;
    out->r_bic = sw.best_bic;
    int n_rules = c->rules && c->n_rules > 0 ? c->n_rules : 1;
    for (int k = 0; k < n_rules && k < FID_MAX_RULES; k++) {
        fit_recommendation_t rec;
        fit_recommend(&sw, c->rules ? &c->rules[k] : NULL, &rec);
        out->r_rec[k] = rec.r;
        if (k == 0 && sw.shrunk) z_scores(&sw, rec.noise_scale, T, m, out);
        if (k == 0 && c->krige) kriged(&fitted.scan, &o, &sw, rec.r, T, m, out);
    }
    fit_wiener_t w;
    err_t we;
    if (fit_wiener_run(&in.scan, 0, &w, &we) == 0) {
        out->rms_wiener = wiener_rms(&w, sf.scan.pitch_um, T, m, SAMPLES);
        fit_wiener_free(&w);
    }
    if (fit_wiener_run_opts(&sf.scan, NULL, &w, &we) == 0) {
        out->rms_wiener_whole = wiener_rms(&w, sf.scan.pitch_um, T, m, SAMPLES);
        fit_wiener_free(&w);
    }
done:
    fit_scan_sel_free(&in);
    fit_scan_sel_free(&fitted);
    fit_sweep_free(&sw);
    scanfile_free(&sf);
    sim_close(sim);
    return rc;
}
