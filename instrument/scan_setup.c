/* scan_setup.c: the setup of the paper's scan procedure (scan.h, section II.B) on the 3 x 3
 * pixels around the POI: the exposure (rough, then final), centring by balancing the neighbours,
 * focus by minimising their light; scan_prepare runs the steps the configuration asks for. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <gsl/gsl_errno.h>
#include <gsl/gsl_multifit.h>

#include "fit/gslerr.h"
#include "scan_int.h"

/* The exposure search (choose_exposure). */
#define EXPOSURE_TRIES 40      /* looks at most: 6 lengthenings span 16^6 = 1.7e7, 1 us to 17 s */
#define EXPOSURE_SHORTEN 4.0   /* something saturates (by how much is unknown): divide by this */
#define EXPOSURE_LENGTHEN 16.0 /* the spot is barely seen: multiply by this */
#define EXPOSURE_SEEN 0.01     /* barely seen: peak signal <= this fraction of the target */
#define EXPOSURE_SETTLED 0.02  /* final: done when the next exposure is within 2 % of this one */

/* The centring and the focus. */
#define FINE_FRAMES 4     /* the line fit and final measurements average 4 x setup_frames */
#define COARSE_TRIES 4    /* pitch steps of the coarse centring at most */
#define LINE_POINTS 7     /* points of the centring's line fit ... */
#define LINE_HALF_UM 0.3  /* ... over +- this around the bracket's root */
#define FOCUS_PARABOLAS 8 /* re-centred parabolas of the focus at most */

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
    if (scan_stopped(x->hooks)) return err_set(err, -ECANCELED, "scan stopped during the setup");
    struct scan_capture c = {.mean = x->mean, .var = x->var};
    int rc = scan_capture_at(x->cam, x->stage, pos, &x->roi3, k, x->cfg->use_expected, &c, err);
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
    for (int it = 0; it < EXPOSURE_TRIES; it++) {
        scan_progress(x->hooks, "exposure", (size_t)it + 1, 0);
        int rc = measure3(x, &here, rough ? 1 : c->setup_frames, err);
        if (rc) return rc;
        double sig = x->peak_dn - x->su->bias_dn, t = x->su->exposure_us, next;
        if (x->peak_dn >= c->saturation_dn)
            next = t / EXPOSURE_SHORTEN;
        else if (sig <= EXPOSURE_SEEN * target)
            next = t * EXPOSURE_LENGTHEN;
        else if (rough) {
            x->su->peak_dn = x->peak_dn;
            return 0;
        } else
            next = t * target / sig; /* the sensor is linear in exposure */
        if (!rough && fabs(next / t - 1) < EXPOSURE_SETTLED) {
            x->su->peak_dn = x->peak_dn;
            return 0;
        }
        rc = set_exposure(x, next, err);
        if (rc) return rc;
        if (x->su->exposure_us == t) { /* at the camera's limit */
            if (x->peak_dn < c->saturation_dn && sig > EXPOSURE_SEEN * target) {
                x->su->peak_dn = x->peak_dn;
                return 0;
            }
            return err_set(err, -EIO,
                           "no usable exposure: the brightest pixel is %.0f DN at the "
                           "exposure limit %g us (saturation %g DN)",
                           x->peak_dn, t, c->saturation_dn);
        }
    }
    return err_set(err, -EIO, "the exposure did not settle in %d tries", EXPOSURE_TRIES);
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
    for (int it = 0; it < COARSE_TRIES; it++) {
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
    enum { N = LINE_POINTS };
    double d[N], g[N], sd = 0, sg = 0, sdd = 0, sdg = 0, w = LINE_HALF_UM, gx, gy;
    stage_pos_t p = x->su->centre;
    for (int i = 0; i < N; i++) {
        d[i] = -w + 2 * w * i / (N - 1);
        if (axis == 0)
            p.x_um = x0 + d[i];
        else
            p.y_um = x0 + d[i];
        int rc = measure3(x, &p, FINE_FRAMES * x->cfg->setup_frames, err);
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
        scan_progress(x->hooks, "centre", (size_t)it + 1, 0);
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
    if ((rc = measure3(x, o, FINE_FRAMES * c->setup_frames, err)) != 0) return rc;
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
        scan_progress(x->hooks, "focus", (size_t)(k + K + 1), (size_t)(2 * K + 1));
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
    for (int it = 0; it < FOCUS_PARABOLAS; it++) { /* parabolas re-centred on their vertex */
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
    rc = focus_metric(x, zb, FINE_FRAMES * c->setup_frames, &x->su->neighbour_fraction, err);
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
    fit_gsl_policy(); /* GSL reports failures by return code, never by abort() */
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
