/* scan.c: the paper's scan procedure over cam.h and stage.h (see scan.h): exposure, centring by
 * balancing the neighbours, focus by minimising their light, the raster, and the extraction of
 * one pixel's response as a scan file. */
#include "instrument/scan.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit.h>

#include "instrument/scanfile.h"

scan_config_t scan_config_default(void)
{
    return (scan_config_t){
        .poi_col = 0,
        .poi_row = 0,
        .start = {0, 0, 0},
        .area_px = 5,
        .step_um = 0.6,
        .subframe_px = 9,
        .frames = 12,
        .setup_frames = 4,
        .saturation_dn = 16000,
        .exposure_fill = 0.4,
        .exposure_us = 10000,
        .gain = 1,
        .do_centre = 1,
        .do_focus = 1,
        .do_exposure = 1,
        .centre_step_um = 0.5,
        .centre_tol_um = 0.05,
        .centre_max_iter = 40,
        .focus_range_um = 15,
        .focus_step_um = 2.5,
        .focus_window_um = 3,
        .focus_points = 9,
        .focus_tol_um = 0.05,
        .keep_frames = 0,
        .use_expected = 0,
        .pitch_um = NAN,
        .bias_dn = NAN,
        .gain_e_per_dn = NAN,
        .read_noise_e = NAN,
        .full_scale_dn = NAN,
        .spot_radius_um = NAN,
    };
}

int scan_points_per_axis(const scan_config_t *cfg, double pitch_um)
{
    if (!(pitch_um > 0) || !(cfg->step_um > 0) || cfg->area_px < 1) return 0;
    double n = cfg->area_px * pitch_um / cfg->step_um;
    double k = nearbyint(n);
    if (fabs(n - k) > 1e-6 * (k > 1 ? k : 1) || k < 1 || k > 100000) return 0;
    return (int)k + 1;
}

int scan_config_check(const scan_config_t *c, const cam_info_t *info, err_t *err)
{
    if (c->area_px < 1 || c->area_px > 1000)
        return err_set(err, -EINVAL, "area_px must be 1..1000 (got %d)", c->area_px);
    if (!(c->step_um > 0) || !isfinite(c->step_um))
        return err_set(err, -EINVAL, "step_um must be positive (got %g)", c->step_um);
    if (c->subframe_px < 3 || c->subframe_px % 2 == 0 || c->subframe_px > 255)
        return err_set(err, -EINVAL, "subframe_px must be odd, 3..255 (got %d)", c->subframe_px);
    if (c->frames < 1 || c->frames > 10000 || c->setup_frames < 1 || c->setup_frames > 10000)
        return err_set(err, -EINVAL, "frames and setup_frames must be 1..10000 (got %d, %d)",
                       c->frames, c->setup_frames);
    if (!(c->exposure_fill > 0 && c->exposure_fill < 1))
        return err_set(err, -EINVAL, "exposure_fill must be in (0, 1) (got %g)", c->exposure_fill);
    if (!(c->exposure_us > 0) || !(c->gain > 0) || !isfinite(c->saturation_dn))
        return err_set(err, -EINVAL, "exposure_us and gain must be positive, saturation finite");
    if (!(c->centre_step_um > 0) || !(c->centre_tol_um > 0) || c->centre_max_iter < 1 ||
        !(c->focus_range_um >= 0) || !(c->focus_step_um > 0) || !(c->focus_window_um > 0) ||
        c->focus_points < 3 || !(c->focus_tol_um > 0))
        return err_set(err, -EINVAL,
                       "centring and focus settings must be positive (focus_points"
                       " >= 3)");
    if (!isfinite(c->start.x_um) || !isfinite(c->start.y_um) || !isfinite(c->start.z_um))
        return err_set(err, -EINVAL, "start position must be finite");
    if (!info) return 0;
    int h = c->subframe_px / 2;
    if (c->poi_col - h < 0 || c->poi_row - h < 0 || c->poi_col + h >= info->width ||
        c->poi_row + h >= info->height)
        return err_set(err, -EINVAL,
                       "the %dx%d sub-frame around pixel (%d, %d) leaves the %dx%d "
                       "array",
                       c->subframe_px, c->subframe_px, c->poi_col, c->poi_row, info->width,
                       info->height);
    return 0;
}

static int stopped(const scan_hooks_t *h)
{
    return h && h->stop && atomic_load(h->stop);
}

static void progress(const scan_hooks_t *h, const char *phase, size_t done, size_t total)
{
    if (h && h->progress) h->progress(phase, done, total, h->user);
}

/* ---- capturing ---- */

struct capture {
    double *mean, *var; /* w*h */
    uint16_t *raw;      /* k*w*h or NULL */
    int64_t t0_ns;
    double left_out_dn, exposure_us, gain;
    stage_pos_t reported;
};

/* Moves to pos and averages k frames of roi (Welford's running mean and variance). */
static int capture_at(cam_t *cam, stage_t *stage, const stage_pos_t *pos, const cam_roi_t *roi,
                      int k, int use_expected, struct capture *c, err_t *err)
{
    int rc = stage_move(stage, pos, err);
    if (rc == 0) rc = stage_get_position(stage, &c->reported, err);
    if (rc) return rc;
    size_t npx = (size_t)roi->width * roi->height;
    for (size_t q = 0; q < npx; q++)
        c->mean[q] = c->var[q] = 0;
    c->left_out_dn = 0;
    for (int f = 0; f < k; f++) {
        cam_frame_t fr;
        rc = cam_capture(cam, roi, &fr, err);
        if (rc) return rc;
        if (f == 0) {
            c->t0_ns = fr.timestamp_ns;
            c->exposure_us = fr.exposure_us;
            c->gain = fr.gain;
        }
        if (fr.left_out_dn > c->left_out_dn) c->left_out_dn = fr.left_out_dn;
        for (size_t q = 0; q < npx; q++) {
            double x = use_expected && fr.expected_dn ? fr.expected_dn[q] : fr.dn[q];
            double d = x - c->mean[q];
            c->mean[q] += d / (f + 1);
            c->var[q] += d * (x - c->mean[q]);
            if (c->raw) c->raw[(size_t)f * npx + q] = fr.dn[q];
        }
        cam_frame_free(&fr);
    }
    for (size_t q = 0; q < npx; q++)
        c->var[q] = k > 1 ? c->var[q] / (k - 1) : NAN;
    return 0;
}

/* The setup's state: the 3 x 3 around the POI measured at a position. */
struct setup_ctx {
    cam_t *cam;
    stage_t *stage;
    const scan_config_t *cfg;
    const scan_hooks_t *hooks;
    scan_setup_t *su;
    cam_roi_t roi3;
    double v[9], mean[9], var[9]; /* v: mean - bias */
    double peak_dn;
    int evaluations;
};

static int measure3(struct setup_ctx *x, const stage_pos_t *pos, int k, err_t *err)
{
    if (stopped(x->hooks)) return err_set(err, -ECANCELED, "scan stopped during the setup");
    struct capture c = {.mean = x->mean, .var = x->var};
    int rc = capture_at(x->cam, x->stage, pos, &x->roi3, k, x->cfg->use_expected, &c, err);
    if (rc) return rc;
    x->peak_dn = -INFINITY;
    for (int q = 0; q < 9; q++) {
        x->v[q] = x->mean[q] - x->su->bias_dn;
        if (x->mean[q] > x->peak_dn) x->peak_dn = x->mean[q];
    }
    x->evaluations++;
    return 0;
}

/* ---- exposure ---- */

static int set_exposure(struct setup_ctx *x, double us, err_t *err)
{
    cam_info_t info;
    int rc = cam_get_info(x->cam, &info, err);
    if (rc) return rc;
    if (isfinite(info.exposure_min_us) && us < info.exposure_min_us) us = info.exposure_min_us;
    if (isfinite(info.exposure_max_us) && us > info.exposure_max_us) us = info.exposure_max_us;
    rc = cam_set_exposure(x->cam, us, err);
    if (rc == 0) x->su->exposure_us = us;
    return rc;
}

/* Scales the exposure until the brightest pixel sits near exposure_fill of bias..saturation.
 * rough: one frame per look, stop once the spot is seen without saturating. */
static int choose_exposure(struct setup_ctx *x, int rough, err_t *err)
{
    const scan_config_t *c = x->cfg;
    double target = c->exposure_fill * (c->saturation_dn - x->su->bias_dn);
    stage_pos_t here = x->su->centre;
    for (int it = 0; it < 40; it++) {
        progress(x->hooks, "exposure", (size_t)it + 1, 0);
        int rc = measure3(x, &here, rough ? 1 : c->setup_frames, err);
        if (rc) return rc;
        double sig = x->peak_dn - x->su->bias_dn, t = x->su->exposure_us, next;
        if (x->peak_dn >= c->saturation_dn)
            next = t / 4;
        else if (sig <= 0.01 * target)
            next = t * 16;
        else if (rough) {
            x->su->peak_dn = x->peak_dn;
            return 0;
        } else
            next = t * target / sig; /* the sensor is linear in exposure */
        if (!rough && fabs(next / t - 1) < 0.02) {
            x->su->peak_dn = x->peak_dn;
            return 0;
        }
        rc = set_exposure(x, next, err);
        if (rc) return rc;
        if (x->su->exposure_us == t) { /* at the camera's limit */
            if (x->peak_dn < c->saturation_dn && sig > 0.01 * target) {
                x->su->peak_dn = x->peak_dn;
                return 0;
            }
            return err_set(err, -EIO,
                           "no usable exposure: the brightest pixel is %.0f DN at the "
                           "exposure limit %g us (saturation %g DN)",
                           x->peak_dn, t, c->saturation_dn);
        }
    }
    return err_set(err, -EIO, "the exposure did not settle in 40 tries");
}

/* ---- centring ---- */

/* The neighbours' balance: g_x = (right - left) / (right + left), g_y = (bottom - top) / ... */
static void balance(const double *v, double *gx, double *gy)
{
    double L = v[0] + v[3] + v[6], R = v[2] + v[5] + v[8];
    double T = v[0] + v[1] + v[2], B = v[6] + v[7] + v[8];
    *gx = L + R > 0 ? (R - L) / (R + L) : 0;
    *gy = T + B > 0 ? (B - T) / (B + T) : 0;
}

/* Steps a pitch at a time until the POI is the brightest of its 3 x 3. */
static int centre_coarse(struct setup_ctx *x, err_t *err)
{
    double p = x->su->pitch_um;
    for (int it = 0; it < 4; it++) {
        int rc = measure3(x, &x->su->centre, x->cfg->setup_frames, err);
        if (rc) return rc;
        int best = 4;
        for (int q = 0; q < 9; q++)
            if (x->v[q] > x->v[best]) best = q;
        if (best == 4) return 0;
        x->su->centre.x_um += (1 - best % 3) * p; /* the spot is on that neighbour: step back */
        x->su->centre.y_um += (1 - best / 3) * p;
    }
    return err_set(err, -EIO,
                   "could not bring the spot onto pixel (%d, %d): it stays brightest "
                   "elsewhere",
                   x->cfg->poi_col, x->cfg->poi_row);
}

/* One axis of the centring: a bracket [lo, hi] with g(lo) < 0 <= g(hi) (g grows with x), found by
 * stepping and narrowed by false position with the Illinois modification. */
struct axis {
    double lo, glo, hi, ghi, x;
    int have_lo, have_hi, kept; /* kept: which end stayed last time (-1 lo, +1 hi) */
};

static double axis_next(const struct axis *a, double step)
{
    if (a->have_lo && a->have_hi) return a->lo - a->glo * (a->hi - a->lo) / (a->ghi - a->glo);
    return a->have_lo ? a->lo + step : a->hi - step;
}

static void axis_update(struct axis *a, double x, double g)
{
    if (g < 0) {
        if (a->kept == 1) a->ghi /= 2; /* Illinois: the hi end stayed twice */
        a->lo = x, a->glo = g, a->have_lo = 1, a->kept = 1;
    } else {
        if (a->kept == -1) a->glo /= 2;
        a->hi = x, a->ghi = g, a->have_hi = 1, a->kept = -1;
    }
}

/* Least-squares root of g along one axis from n points at offsets d around x0 (line fit). */
static int line_root(struct setup_ctx *x, int axis, double x0, double *root, err_t *err)
{
    enum { N = 7 };
    double d[N], g[N], sd = 0, sg = 0, sdd = 0, sdg = 0, w = 0.3, gx, gy;
    stage_pos_t p = x->su->centre;
    for (int i = 0; i < N; i++) {
        d[i] = -w + 2 * w * i / (N - 1);
        if (axis == 0)
            p.x_um = x0 + d[i];
        else
            p.y_um = x0 + d[i];
        int rc = measure3(x, &p, 4 * x->cfg->setup_frames, err);
        if (rc) return rc;
        balance(x->v, &gx, &gy);
        g[i] = axis == 0 ? gx : gy;
        sd += d[i], sg += g[i], sdd += d[i] * d[i], sdg += d[i] * g[i];
    }
    double slope = (N * sdg - sd * sg) / (N * sdd - sd * sd), icpt = (sg - slope * sd) / N;
    if (!(slope > 0)) return err_set(err, -EIO, "the neighbours' balance does not follow the spot");
    double shift = -icpt / slope;
    *root = x0 + fmax(-2 * w, fmin(2 * w, shift));
    return 0;
}

/* Balances the neighbours: brackets per axis, narrowed by false position, then a line fit to
 * points around the root averages the noise down. */
static int centre_fine(struct setup_ctx *x, err_t *err)
{
    const scan_config_t *c = x->cfg;
    stage_pos_t *o = &x->su->centre;
    double h = c->centre_step_um, gx, gy;
    struct axis ax = {.x = o->x_um}, ay = {.x = o->y_um};
    int rc = 0, it;
    for (it = 0; it < c->centre_max_iter; it++) {
        progress(x->hooks, "centre", (size_t)it + 1, 0);
        stage_pos_t p = {ax.x, ay.x, o->z_um};
        if ((rc = measure3(x, &p, c->setup_frames, err)) != 0) return rc;
        balance(x->v, &gx, &gy);
        axis_update(&ax, ax.x, gx);
        axis_update(&ay, ay.x, gy);
        int done_x = ax.have_lo && ax.have_hi && ax.hi - ax.lo < c->centre_tol_um;
        int done_y = ay.have_lo && ay.have_hi && ay.hi - ay.lo < c->centre_tol_um;
        if (done_x && done_y) break;
        if (!done_x) ax.x = axis_next(&ax, h);
        if (!done_y) ay.x = axis_next(&ay, h);
        if (fabs(ax.x - o->x_um) > x->su->pitch_um || fabs(ay.x - o->y_um) > x->su->pitch_um)
            return err_set(err, -EIO,
                           "centring ran away (> one pitch): is the stage moving the "
                           "spot in +x, +y?");
    }
    x->su->centre_iterations = it + 1;
    double rx = ax.have_lo && ax.have_hi ? axis_next(&ax, h) : ax.x;
    double ry = ay.have_lo && ay.have_hi ? axis_next(&ay, h) : ay.x;
    o->y_um = ry;
    if ((rc = line_root(x, 0, rx, &o->x_um, err)) != 0) return rc;
    if ((rc = line_root(x, 1, ry, &o->y_um, err)) != 0) return rc;
    if ((rc = measure3(x, o, 4 * c->setup_frames, err)) != 0) return rc;
    balance(x->v, &x->su->imbalance_x, &x->su->imbalance_y);
    return 0;
}

/* ---- focus ---- */

/* Light on the 8 neighbours over the 3 x 3's total at stage z. */
static int focus_metric(struct setup_ctx *x, double z, int k, double *f, err_t *err)
{
    stage_pos_t p = x->su->centre;
    p.z_um = z;
    int rc = measure3(x, &p, k, err);
    if (rc) return rc;
    double tot = 0;
    for (int q = 0; q < 9; q++)
        tot += x->v[q];
    if (!(tot > 0)) return err_set(err, -EIO, "no light on the 3x3 around the POI at z = %g um", z);
    *f = (tot - x->v[4]) / tot;
    return 0;
}

/* Least-squares parabola f = c0 + c1 t + c2 t^2 through (t, f) by GSL; 0 or -EIO. */
static int parabola(const double *t, const double *f, int n, double c[3])
{
    gsl_matrix *X = gsl_matrix_alloc((size_t)n, 3), *cov = gsl_matrix_alloc(3, 3);
    gsl_vector *y = gsl_vector_alloc((size_t)n), *cv = gsl_vector_alloc(3);
    gsl_multifit_linear_workspace *w = gsl_multifit_linear_alloc((size_t)n, 3);
    int rc = -ENOMEM;
    if (X && cov && y && cv && w) {
        for (int i = 0; i < n; i++) {
            gsl_matrix_set(X, (size_t)i, 0, 1);
            gsl_matrix_set(X, (size_t)i, 1, t[i]);
            gsl_matrix_set(X, (size_t)i, 2, t[i] * t[i]);
            gsl_vector_set(y, (size_t)i, f[i]);
        }
        double chisq;
        rc = gsl_multifit_linear(X, y, cv, cov, &chisq, w) == GSL_SUCCESS ? 0 : -EIO;
        for (int j = 0; j < 3; j++)
            c[j] = gsl_vector_get(cv, (size_t)j);
    }
    gsl_matrix_free(X);
    gsl_matrix_free(cov);
    gsl_vector_free(y);
    gsl_vector_free(cv);
    gsl_multifit_linear_free(w);
    return rc;
}

static int focus(struct setup_ctx *x, err_t *err)
{
    const scan_config_t *c = x->cfg;
    int K = (int)floor(c->focus_range_um / c->focus_step_um + 1e-9), n = c->focus_points, rc;
    double z0 = c->start.z_um, best = INFINITY, zb = z0, f = INFINITY;
    for (int k = -K; k <= K; k++) { /* coarse sweep */
        progress(x->hooks, "focus", (size_t)(k + K + 1), (size_t)(2 * K + 1));
        if ((rc = focus_metric(x, z0 + k * c->focus_step_um, c->setup_frames, &f, err)) != 0)
            return rc;
        if (f < best) {
            best = f;
            zb = z0 + k * c->focus_step_um;
        }
    }
    double *t = malloc(sizeof(double) * 2 * (size_t)n), *fv = t ? t + n : NULL,
           w = c->focus_window_um;
    if (!t) return err_set(err, -ENOMEM, "out of memory for the focus search");
    for (int it = 0; it < 8; it++) { /* parabolas re-centred on their vertex */
        for (int i = 0; i < n; i++) {
            t[i] = -w + 2 * w * i / (n - 1);
            if ((rc = focus_metric(x, zb + t[i], c->setup_frames, &fv[i], err)) != 0) goto out;
        }
        double cf[3];
        if ((rc = parabola(t, fv, n, cf)) != 0) {
            rc = err_set(err, rc, "the focus parabola fit failed");
            goto out;
        }
        double step = cf[2] > 0 ? -cf[1] / (2 * cf[2]) : (cf[1] > 0 ? -w : w);
        step = fmax(-w, fmin(w, step));
        zb += step;
        if (fabs(step) < c->focus_tol_um) break;
    }
    x->su->centre.z_um = zb;
    rc = focus_metric(x, zb, 4 * c->setup_frames, &x->su->neighbour_fraction, err);
out:
    free(t);
    return rc;
}

/* ---- the setup ---- */

/* cfg's constants, or the camera's where cfg has NaN. */
static int settle_constants(const scan_config_t *c, const cam_info_t *in, scan_setup_t *su,
                            err_t *err)
{
    su->pitch_um = isfinite(c->pitch_um) ? c->pitch_um : in->pitch_um;
    su->bias_dn = isfinite(c->bias_dn) ? c->bias_dn : in->bias_dn;
    su->gain_e_per_dn = isfinite(c->gain_e_per_dn) ? c->gain_e_per_dn : in->gain_e_per_dn;
    su->read_noise_e = isfinite(c->read_noise_e) ? c->read_noise_e : in->read_noise_e;
    su->full_scale_dn = isfinite(c->full_scale_dn) ? c->full_scale_dn : in->full_scale_dn;
    su->spot_radius_um = c->spot_radius_um;
    if (!(su->pitch_um > 0))
        return err_set(err, -EINVAL, "pixel pitch unknown: the camera does not say; set pitch_um");
    if (!isfinite(su->bias_dn))
        return err_set(err, -EINVAL, "bias unknown: the camera does not say; set bias_dn");
    if (!(su->gain_e_per_dn > 0) || !(su->read_noise_e >= 0))
        return err_set(err, -EINVAL,
                       "gain or read noise unknown: the camera does not say; set "
                       "gain_e_per_dn and read_noise_e");
    if (!(su->spot_radius_um > 0))
        return err_set(err, -EINVAL, "spot_radius_um must be set (R of eq. 1)");
    return 0;
}

int scan_prepare(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_hooks_t *hooks,
                 scan_setup_t *su, err_t *err)
{
    memset(su, 0, sizeof *su);
    su->centre = cfg->start;
    su->exposure_us = cfg->exposure_us;
    su->gain = cfg->gain;
    cam_info_t info;
    int rc = cam_get_info(cam, &info, err);
    if (rc == 0) rc = scan_config_check(cfg, &info, err);
    if (rc == 0) rc = settle_constants(cfg, &info, su, err);
    if (rc == 0) rc = cam_set_gain(cam, cfg->gain, err);
    if (rc) return rc;
    struct setup_ctx x = {.cam = cam,
                          .stage = stage,
                          .cfg = cfg,
                          .hooks = hooks,
                          .su = su,
                          .roi3 = {cfg->poi_col - 1, cfg->poi_row - 1, 3, 3}};
    rc = set_exposure(&x, cfg->exposure_us, err);
    if (rc == 0 && (cfg->do_exposure || cfg->do_centre || cfg->do_focus))
        rc = choose_exposure(&x, 1, err);
    if (rc == 0 && cfg->do_centre) rc = centre_coarse(&x, err);
    if (rc == 0 && cfg->do_centre) rc = centre_fine(&x, err);
    if (rc == 0 && cfg->do_focus) rc = focus(&x, err);
    if (rc == 0 && cfg->do_focus && cfg->do_centre) rc = centre_fine(&x, err);
    if (rc == 0 && cfg->do_exposure) rc = choose_exposure(&x, 0, err);
    su->focus_evaluations = x.evaluations;
    if (rc == 0) rc = stage_move(stage, &su->centre, err);
    return rc;
}

/* ---- the raster ---- */

stage_pos_t scan_raster_position(const scan_config_t *cfg, const scan_setup_t *su, int nx,
                                 size_t index)
{
    int ix = (int)(index % (size_t)nx), iy = (int)(index / (size_t)nx);
    double h = (nx - 1) / 2.0;
    return (stage_pos_t){su->centre.x_um + (ix - h) * cfg->step_um,
                         su->centre.y_um + (iy - h) * cfg->step_um, su->centre.z_um};
}

int scan_raster_init(scan_raster_t *r, const scan_config_t *cfg, const scan_setup_t *su, err_t *err)
{
    memset(r, 0, sizeof *r);
    int rc = scan_config_check(cfg, NULL, err);
    if (rc) return rc;
    int nx = scan_points_per_axis(cfg, su->pitch_um);
    if (nx < 1)
        return err_set(err, -EINVAL,
                       "area_px * pitch / step = %d * %g / %g is not a whole number "
                       "of steps",
                       cfg->area_px, su->pitch_um, cfg->step_um);
    size_t count = (size_t)nx * nx, mm = (size_t)cfg->subframe_px * cfg->subframe_px;
    r->cfg = *cfg;
    r->setup = *su;
    r->nx = nx;
    r->count = count;
    r->m = cfg->subframe_px;
    r->pos = calloc(count, sizeof *r->pos);
    r->mean_dn = calloc(count * mm, sizeof(double));
    r->var_dn = calloc(count * mm, sizeof(double));
    r->have = calloc(count, 1);
    if (cfg->keep_frames) r->raw = calloc(count * mm * (size_t)cfg->frames, sizeof(uint16_t));
    if (!r->pos || !r->mean_dn || !r->var_dn || !r->have || (cfg->keep_frames && !r->raw)) {
        scan_raster_free(r);
        return err_set(err, -ENOMEM, "out of memory for a raster of %zu points", count);
    }
    return 0;
}

void scan_raster_free(scan_raster_t *r)
{
    if (!r) return;
    free(r->pos);
    free(r->mean_dn);
    free(r->var_dn);
    free(r->raw);
    free(r->have);
    memset(r, 0, sizeof *r);
}

int scan_raster_put(scan_raster_t *r, const scan_point_t *pt, err_t *err)
{
    if (pt->index >= r->count || pt->width != r->m || pt->height != r->m)
        return err_set(err, -EINVAL,
                       "point %zu (%dx%d) does not fit the raster (%zu points, "
                       "%dx%d)",
                       pt->index, pt->width, pt->height, r->count, r->m, r->m);
    size_t mm = (size_t)r->m * r->m;
    r->pos[pt->index] = pt->reported;
    memcpy(r->mean_dn + pt->index * mm, pt->mean_dn, sizeof(double) * mm);
    if (pt->var_dn) memcpy(r->var_dn + pt->index * mm, pt->var_dn, sizeof(double) * mm);
    if (r->raw && pt->raw && pt->frames == r->cfg.frames)
        memcpy(r->raw + pt->index * mm * (size_t)pt->frames, pt->raw,
               sizeof(uint16_t) * mm * (size_t)pt->frames);
    if (!r->have[pt->index]) r->captured++;
    r->have[pt->index] = 1;
    return 0;
}

int scan_raster_run(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_setup_t *su,
                    size_t first, const scan_hooks_t *hooks, scan_raster_t *raster, err_t *err)
{
    cam_info_t info;
    int rc = cam_get_info(cam, &info, err);
    if (rc == 0) rc = scan_config_check(cfg, &info, err);
    if (rc) return rc;
    int nx = scan_points_per_axis(cfg, su->pitch_um), m = cfg->subframe_px, k = cfg->frames;
    if (nx < 1) return err_set(err, -EINVAL, "the raster is not a whole number of steps");
    size_t count = (size_t)nx * nx, mm = (size_t)m * m;
    if (first > count) return err_set(err, -EINVAL, "first point %zu beyond %zu", first, count);
    if ((rc = cam_set_gain(cam, su->gain, err)) ||
        (rc = cam_set_exposure(cam, su->exposure_us, err)))
        return rc;
    cam_roi_t roi = {cfg->poi_col - m / 2, cfg->poi_row - m / 2, m, m};
    struct capture c = {.mean = malloc(sizeof(double) * 2 * mm)};
    c.var = c.mean ? c.mean + mm : NULL;
    if (cfg->keep_frames) c.raw = malloc(sizeof(uint16_t) * mm * (size_t)k);
    if (!c.mean || (cfg->keep_frames && !c.raw)) {
        rc = err_set(err, -ENOMEM, "out of memory for a %dx%d sub-frame", m, m);
        goto out;
    }
    for (size_t i = first; i < count; i++) {
        if (stopped(hooks)) {
            rc = err_set(err, -ECANCELED, "scan stopped before raster point %zu of %zu", i, count);
            goto out;
        }
        stage_pos_t pos = scan_raster_position(cfg, su, nx, i);
        if ((rc = capture_at(cam, stage, &pos, &roi, k, cfg->use_expected, &c, err)) != 0) goto out;
        scan_point_t pt = {.index = i,
                           .count = count,
                           .ix = (int)(i % (size_t)nx),
                           .iy = (int)(i / (size_t)nx),
                           .commanded = pos,
                           .reported = c.reported,
                           .exposure_us = c.exposure_us,
                           .gain = c.gain,
                           .timestamp_ns = c.t0_ns,
                           .frames = k,
                           .width = m,
                           .height = m,
                           .mean_dn = c.mean,
                           .var_dn = c.var,
                           .raw = c.raw,
                           .left_out_dn = c.left_out_dn};
        if (raster && (rc = scan_raster_put(raster, &pt, err)) != 0) goto out;
        if (hooks && hooks->point && hooks->point(&pt, hooks->user) != 0) {
            rc = err_set(err, -ECANCELED, "scan stopped by the point handler at point %zu", i);
            goto out;
        }
        progress(hooks, "raster", i + 1, count);
    }
out:
    free(c.mean);
    free(c.raw);
    return rc;
}

int scan_run(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_hooks_t *hooks,
             scan_raster_t *raster, err_t *err)
{
    scan_setup_t su;
    memset(raster, 0, sizeof *raster);
    int rc = scan_prepare(cam, stage, cfg, hooks, &su, err);
    if (rc == 0) rc = scan_raster_init(raster, cfg, &su, err);
    if (rc == 0) rc = scan_raster_run(cam, stage, cfg, &su, 0, hooks, raster, err);
    return rc;
}

/* ---- scan files ---- */

int scan_file_new(const scan_setup_t *su, int frames, size_t n, scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    if (n) {
        out->x_um = malloc(sizeof(double) * n);
        out->y_um = malloc(sizeof(double) * n);
        out->signal_dn = malloc(sizeof(double) * n);
        if (!out->x_um || !out->y_um || !out->signal_dn) {
            scanfile_free(out);
            return err_set(err, -ENOMEM, "out of memory for a scan of %zu points", n);
        }
    }
    out->scan = (fit_scan_t){.n = n,
                             .x_um = out->x_um,
                             .y_um = out->y_um,
                             .signal_dn = out->signal_dn,
                             .pitch_um = su->pitch_um,
                             .spot_radius_um = su->spot_radius_um,
                             .bias_dn = su->bias_dn,
                             .gain_e_per_dn = su->gain_e_per_dn / su->gain,
                             .read_noise_e = su->read_noise_e,
                             .frames = frames,
                             .full_scale_dn = su->full_scale_dn};
    return 0;
}

int scan_pixel_coords(const scan_setup_t *su, int dcol, int drow, double sx, double sy, double *x,
                      double *y)
{
    double p = su->pitch_um, eps = 1e-6 * p; /* the pixel spans [o, o + p] in stage coordinates */
    *x = sx - (su->centre.x_um - p / 2 + dcol * p);
    *y = sy - (su->centre.y_um - p / 2 + drow * p);
    return *x > eps && *x < p - eps && *y > eps && *y < p - eps;
}

int scan_extract_pixel(const scan_raster_t *r, int dcol, int drow, scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    int h = r->m / 2;
    if (abs(dcol) > h || abs(drow) > h)
        return err_set(err, -EINVAL, "pixel (%+d, %+d) is outside the %dx%d sub-frame", dcol, drow,
                       r->m, r->m);
    size_t n = 0, at = (size_t)(h + drow) * r->m + (size_t)(h + dcol), mm = (size_t)r->m * r->m;
    for (int pass = 0; pass < 2; pass++) {
        size_t k = 0;
        for (size_t i = 0; i < r->count; i++) {
            double x, y;
            if (!r->have[i] ||
                !scan_pixel_coords(&r->setup, dcol, drow, r->pos[i].x_um, r->pos[i].y_um, &x, &y))
                continue;
            if (pass == 1) {
                out->x_um[k] = x;
                out->y_um[k] = y;
                out->signal_dn[k] = r->mean_dn[i * mm + at];
            }
            k++;
        }
        if (pass == 0) {
            n = k;
            int rc = scan_file_new(&r->setup, r->cfg.frames, n, out, err);
            if (rc) return rc;
        }
    }
    return 0;
}

int scan_grid_pixel(cam_t *cam, stage_t *stage, const scan_config_t *cfg, const scan_setup_t *su,
                    int n, const scan_hooks_t *hooks, scanfile_t *out, err_t *err)
{
    memset(out, 0, sizeof *out);
    double p = su->pitch_um, half = (n - 1) / 2.0 * cfg->step_um;
    if (n < 1 || n > 1000)
        return err_set(err, -EINVAL, "grid must be 1..1000 points a side (got %d)", n);
    if (!(half < p / 2 * (1 - 1e-9)))
        return err_set(err, -EINVAL,
                       "a %dx%d grid in %g um steps spans %g um: it must fit inside "
                       "the %g um pixel",
                       n, n, cfg->step_um, 2 * half, p);
    int rc = scan_file_new(su, cfg->frames, (size_t)n * n, out, err);
    if (rc == 0) rc = cam_set_gain(cam, su->gain, err);
    if (rc == 0) rc = cam_set_exposure(cam, su->exposure_us, err);
    if (rc) goto fail;
    cam_roi_t roi = {cfg->poi_col, cfg->poi_row, 1, 1};
    double mean, var;
    struct capture c = {.mean = &mean, .var = &var};
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            if (stopped(hooks)) {
                rc = err_set(err, -ECANCELED, "scan stopped in the grid");
                goto fail;
            }
            double x = p / 2 + (i - (n - 1) / 2.0) * cfg->step_um;
            double y = p / 2 + (j - (n - 1) / 2.0) * cfg->step_um;
            stage_pos_t pos = {su->centre.x_um - p / 2 + x, su->centre.y_um - p / 2 + y,
                               su->centre.z_um};
            rc = capture_at(cam, stage, &pos, &roi, cfg->frames, cfg->use_expected, &c, err);
            if (rc) goto fail;
            size_t k = (size_t)j * n + (size_t)i;
            out->x_um[k] = c.reported.x_um - (su->centre.x_um - p / 2);
            out->y_um[k] = c.reported.y_um - (su->centre.y_um - p / 2);
            out->signal_dn[k] = mean;
            progress(hooks, "raster", k + 1, (size_t)n * n);
        }
    return 0;
fail:
    scanfile_free(out);
    return rc;
}
