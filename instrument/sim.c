/* sim.c: the simulated optical bench (see sim.h): configuration, the spot's optics, the expected
 * image with its leave-out rule and memo, and the frames drawn from it. */
#include "instrument/sim.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

#include "base/clock.h"
#include "cam_impl.h"
#include "fit/airy.h"
#include "fit/design.h"

#define QUANTUM_UM 1e-9        /* relative positions are rounded to this before integration */
#define MEMO_MAX (1u << 20)    /* entries before the memo is emptied (~40 MB) */
#define BATCH 256              /* design rows per fit_design_build call at most */
#define ROWS_BUDGET (1u << 21) /* doubles of design rows held at once (16 MB) */

#define LEFT_OUT (-1) /* an ask's level when the pixel is not integrated */
#define MAX_LEVELS 64

/* The map at a coarser resolution k (k divides m): block means P_k S, and the size of what that
 * leaves out, S - P_k S, in the two norms the bounds need. */
struct reslevel {
    int k;
    double *map;        /* k*k */
    double l1, max_dev; /* integral of |S - P_k S| (um^2), max |S - P_k S| */
};

struct memo_entry {
    int64_t ku, kv;
    uint64_t kr;         /* bits of the radius */
    double value, bound; /* integral of S times the unit-peak Airy (um^2), and its left-out bound */
};

struct memo {
    struct memo_entry *e;
    unsigned char *used;
    size_t cap, n;
};

/* A memo miss of one capture: the relative position, the leave-out rule's choice, its memo slot. */
struct ask {
    double u, v;
    int level; /* index into sim.lv, or LEFT_OUT */
    size_t slot;
};

struct sim {
    sim_config_t cfg;
    char scene_spec[512];
    scene_t *scene;
    const double *map;
    int m;
    scene_stats_t st;
    struct reslevel lv[MAX_LEVELS]; /* ascending k; the last is k = m (nothing left out) */
    int nlv;
    double R0, zR;
    fit_design_opts_t opts;
    gsl_rng *rng;
    stage_t *stage;
    cam_t *cam; /* borrowed handle given out by sim_camera */
    double exposure_us, gain;
    struct memo memo;
    struct ask *asks; /* this capture's misses */
    size_t *pslot;    /* memo slot of each roi pixel */
    size_t *lvl_idx;  /* asks of one level */
    double *abuf, *ubuf, *vbuf;
    size_t ask_cap, n_asks;
    sim_stats_t stats;
};

sim_config_t sim_config_default(void)
{
    return (sim_config_t){
        .scene = "paperlike",
        .sensor = scene_sensor_default(),
        .wavelength_um = 0.55,
        .na = 0.25,
        .radius_um = 0,
        .z_focus_um = 0,
        .depth_um = 0,
        .flux_e = 21500,
        .ref_exposure_us = 10000,
        .readout_s = 0.02,
        .noiseless = 0,
        .leave_out_tol = 1e-4,
        .design_tol = 1e-7,
        .temperature_c = 25,
        .seed = 1,
        .stage = stage_sim_config_default(),
    };
}

/* ---- configuration ---- */

static int check_config(const sim_config_t *c, err_t *err)
{
    if (!(c->radius_um >= 0) || !isfinite(c->radius_um))
        return err_set(err, -EINVAL,
                       "spot radius must be >= 0 (got %g um; 0: from wavelength "
                       "and NA)",
                       c->radius_um);
    if (!(c->wavelength_um > 0) || !isfinite(c->wavelength_um))
        return err_set(err, -EINVAL, "wavelength must be positive (got %g um)", c->wavelength_um);
    if (!(c->na > 0 && c->na < 1))
        return err_set(err, -EINVAL, "numerical aperture must be in (0, 1) (got %g)", c->na);
    if (!(c->depth_um >= 0) || !isfinite(c->depth_um) || !isfinite(c->z_focus_um))
        return err_set(err, -EINVAL, "focus position must be finite and depth >= 0");
    if (!isfinite(c->mount_x_um) || !isfinite(c->mount_y_um))
        return err_set(err, -EINVAL, "mount offset must be finite");
    if (!(c->flux_e >= 0) || !isfinite(c->flux_e))
        return err_set(err, -EINVAL, "spot flux must be >= 0 (got %g e-)", c->flux_e);
    if (!(c->ref_exposure_us > 0) || !isfinite(c->ref_exposure_us))
        return err_set(err, -EINVAL, "reference exposure must be positive (got %g us)",
                       c->ref_exposure_us);
    if (!(c->readout_s >= 0) || !isfinite(c->readout_s))
        return err_set(err, -EINVAL, "read-out time must be >= 0 (got %g s)", c->readout_s);
    if (!(c->leave_out_tol >= 0 && c->leave_out_tol < 1))
        return err_set(err, -EINVAL, "leave-out tolerance must be in [0, 1) (got %g)",
                       c->leave_out_tol);
    if (!(c->design_tol >= 1e-15 && c->design_tol <= 1e-2))
        return err_set(err, -EINVAL, "integration accuracy must be in [1e-15, 1e-2] (got %g)",
                       c->design_tol);
    return 0;
}

/* The map's levels: every k dividing m, with the block means and what they leave out. */
static int build_levels(sim_t *s)
{
    int m = s->m;
    double cell = s->cfg.sensor.pitch_um * s->cfg.sensor.pitch_um / ((double)m * m);
    for (int k = 1; k <= m && s->nlv < MAX_LEVELS; k++) {
        if (m % k && k != m) continue;
        if (s->nlv == MAX_LEVELS - 1 && k != m) continue; /* keep room for k = m */
        int b = m / k;
        struct reslevel *L = &s->lv[s->nlv];
        L->k = k;
        L->map = calloc((size_t)k * k, sizeof(double));
        if (!L->map) return -ENOMEM;
        s->nlv++;
        for (int j = 0; j < m; j++)
            for (int i = 0; i < m; i++)
                L->map[(j / b) * k + i / b] += s->map[j * m + i];
        for (int c = 0; c < k * k; c++)
            L->map[c] /= (double)b * b;
        L->l1 = L->max_dev = 0;
        for (int j = 0; j < m; j++)
            for (int i = 0; i < m; i++) {
                double d = fabs(s->map[j * m + i] - L->map[(j / b) * k + i / b]);
                L->l1 += d * cell;
                if (d > L->max_dev) L->max_dev = d;
            }
    }
    return 0;
}

int sim_open(const sim_config_t *cfg, sim_t **out, err_t *err)
{
    *out = NULL;
    int rc = check_config(cfg, err);
    if (rc) return rc;
    sim_t *s = calloc(1, sizeof *s);
    if (!s) return err_set(err, -ENOMEM, "out of memory for the simulated bench");
    s->cfg = *cfg;
    snprintf(s->scene_spec, sizeof s->scene_spec, "%s", cfg->scene ? cfg->scene : "paperlike");
    s->cfg.scene = s->scene_spec;
    rc = scene_open(s->scene_spec, &cfg->sensor, &s->scene, err);
    if (rc) goto fail;
    rc = stage_open_sim(&cfg->stage, &s->stage, err);
    if (rc) goto fail;
    s->map = scene_map(s->scene, &s->m);
    s->st = *scene_stats(s->scene);
    if ((rc = build_levels(s)) != 0) {
        rc = err_set(err, rc, "out of memory for the map's levels");
        goto fail;
    }
    s->R0 = cfg->radius_um > 0 ? cfg->radius_um : fit_spot_radius_um(cfg->wavelength_um, cfg->na);
    /* quarter-wave depth of focus lambda / (2 NA^2); with R0 given, NA follows from eq. 1 */
    double na = cfg->radius_um > 0 ? 1.22 * cfg->wavelength_um / (2 * cfg->radius_um) : cfg->na;
    s->zR = cfg->depth_um > 0 ? cfg->depth_um : cfg->wavelength_um / (2 * na * na);
    s->opts = fit_design_opts_for_tol(cfg->design_tol);
    s->exposure_us = cfg->ref_exposure_us;
    s->gain = 1;
    s->rng = gsl_rng_alloc(gsl_rng_mt19937);
    s->memo.cap = 1024;
    s->memo.e = malloc(sizeof *s->memo.e * s->memo.cap);
    s->memo.used = calloc(s->memo.cap, 1);
    if (!s->rng || !s->memo.e || !s->memo.used) {
        rc = err_set(err, -ENOMEM, "out of memory for the simulated bench");
        goto fail;
    }
    gsl_rng_set(s->rng, cfg->seed);
    if ((rc = cam_sim_borrowed(s, &s->cam)) != 0) {
        rc = err_set(err, rc, "out of memory for the simulated camera");
        goto fail;
    }
    *out = s;
    return 0;
fail:
    sim_close(s);
    return rc;
}

void sim_close(sim_t *s)
{
    if (!s) return;
    cam_close(s->cam);
    stage_close(s->stage);
    scene_close(s->scene);
    gsl_rng_free(s->rng);
    free(s->memo.e);
    free(s->memo.used);
    free(s->asks);
    free(s->abuf);
    free(s->ubuf);
    free(s->vbuf);
    free(s->pslot);
    free(s->lvl_idx);
    for (int l = 0; l < s->nlv; l++)
        free(s->lv[l].map);
    free(s);
}

cam_t *sim_camera(sim_t *s)
{
    return s->cam;
}
stage_t *sim_stage(sim_t *s)
{
    return s->stage;
}
const scene_t *sim_scene(const sim_t *s)
{
    return s->scene;
}
double sim_spot_radius0(const sim_t *s)
{
    return s->R0;
}
double sim_focus_tolerance(const sim_t *s)
{
    return s->zR * sqrt(1.01 * 1.01 - 1);
}

double sim_spot_radius(const sim_t *s, double z_um)
{
    double dz = (z_um - s->cfg.z_focus_um) / s->zR;
    return s->R0 * sqrt(1 + dz * dz); /* the defocus model of sim.h */
}

void sim_spot(sim_t *s, double *x, double *y, double *z)
{
    stage_pos_t p;
    stage_sim_true_position(s->stage, &p);
    *x = p.x_um + s->cfg.mount_x_um;
    *y = p.y_um + s->cfg.mount_y_um;
    *z = p.z_um;
}

stage_pos_t sim_pixel_centre(const sim_t *s, int col, int row)
{
    double p = s->cfg.sensor.pitch_um;
    return (stage_pos_t){(col + 0.5) * p - s->cfg.mount_x_um, (row + 0.5) * p - s->cfg.mount_y_um,
                         s->cfg.z_focus_um};
}

/* ---- the memo: open addressing on (relative position, radius) ---- */

static uint64_t mix(uint64_t x)
{ /* splitmix64's finaliser */
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

static size_t slot_of(const struct memo *mo, int64_t ku, int64_t kv, uint64_t kr)
{
    size_t h = (size_t)mix((uint64_t)ku * 0x9e3779b97f4a7c15ULL ^ mix((uint64_t)kv) ^ (kr >> 7));
    size_t i = h & (mo->cap - 1);
    while (mo->used[i] && !(mo->e[i].ku == ku && mo->e[i].kv == kv && mo->e[i].kr == kr))
        i = (i + 1) & (mo->cap - 1);
    return i;
}

/* Makes room for `more` entries: doubles the table, or empties it at MEMO_MAX. */
static int memo_reserve(struct memo *mo, size_t more)
{
    if ((mo->n + more) * 10 < mo->cap * 7) return 0;
    size_t cap = mo->cap;
    while ((mo->n + more) * 10 >= cap * 7 && cap < MEMO_MAX)
        cap *= 2;
    if ((mo->n + more) * 10 >= cap * 7) { /* full: forget everything */
        memset(mo->used, 0, mo->cap);
        mo->n = 0;
        return more * 10 < mo->cap * 7 ? 0 : -ENOMEM;
    }
    struct memo_entry *e = malloc(sizeof *e * cap);
    unsigned char *used = calloc(cap, 1);
    if (!e || !used) {
        free(e);
        free(used);
        return -ENOMEM;
    }
    struct memo old = *mo;
    mo->e = e;
    mo->used = used;
    mo->cap = cap;
    for (size_t i = 0; i < old.cap; i++)
        if (old.used[i]) {
            size_t j = slot_of(mo, old.e[i].ku, old.e[i].kv, old.e[i].kr);
            mo->used[j] = 1;
            mo->e[j] = old.e[i];
        }
    free(old.e);
    free(old.used);
    return 0;
}

/* ---- integration ---- */

/* The leave-out rule of sim.h for a spot at (u, v) relative to the pixel [0, p]^2: the level to
 * integrate with (LEFT_OUT or an index into s->lv) and the bound of what it leaves out. */
static int choose_level(const sim_t *s, double a, double total, double tol, double u, double v,
                        double *bound)
{
    double p = s->cfg.sensor.pitch_um;
    double dx = u < 0 ? -u : (u > p ? u - p : 0), dy = v < 0 ? -v : (v > p ? v - p : 0);
    double d = hypot(dx, dy), q, pin;
    double env = fit_airy_envelope(a, d); /* I <= env(d) everywhere on the pixel */
    fit_radial(a * d, &q, &pin);          /* the pixel lies outside the disc of radius d */
    double whole = s->st.max * fmin(p * p * env, total * q);
    if (tol > 0 && whole < tol) {
        *bound = whole;
        return LEFT_OUT;
    }
    for (int l = 0; l < s->nlv; l++) {
        /* |sum_c (S - P_k S)_c A_c| <= sum_c |S - P_k S|_c A_c, and A_c <= area_c env(d),
         * sum_c A_c <= total q */
        double b = fmin(s->lv[l].l1 * env, s->lv[l].max_dev * total * q);
        if (b == 0 || (tol > 0 && b < tol) || l == s->nlv - 1) {
            *bound = l == s->nlv - 1 ? 0 : b;
            return l;
        }
    }
    *bound = 0;
    return s->nlv - 1;
}

static int grow(sim_t *s, size_t n)
{
    if (n <= s->ask_cap) return 0;
    size_t cap = n > 2 * s->ask_cap ? n : 2 * s->ask_cap;
    struct ask *a = realloc(s->asks, sizeof *a * cap);
    if (a) s->asks = a;
    size_t *ps = realloc(s->pslot, sizeof(size_t) * cap);
    if (ps) s->pslot = ps;
    size_t *li = realloc(s->lvl_idx, sizeof(size_t) * cap);
    if (li) s->lvl_idx = li;
    if (!a || !ps || !li) return -ENOMEM;
    s->ask_cap = cap;
    return 0;
}

/* Integrates the asks of level l (the k x k design row dotted with the block-mean map P_k S)
 * into their memo slots. */
static int integrate_level(sim_t *s, double R, int l, err_t *err)
{
    const struct reslevel *L = &s->lv[l];
    size_t kk = (size_t)L->k * L->k, n = 0;
    for (size_t q = 0; q < s->n_asks; q++)
        if (s->asks[q].level == l) s->lvl_idx[n++] = q;
    if (n == 0) return 0;
    size_t mm = (size_t)s->m * s->m, batch = ROWS_BUDGET / mm;
    batch = batch < 1 ? 1 : batch > BATCH ? BATCH : batch;
    if (!s->abuf) s->abuf = malloc(sizeof(double) * batch * mm);
    if (!s->ubuf) s->ubuf = malloc(sizeof(double) * batch);
    if (!s->vbuf) s->vbuf = malloc(sizeof(double) * batch);
    if (!s->abuf || !s->ubuf || !s->vbuf)
        return err_set(err, -ENOMEM, "out of memory for the design rows");
    for (size_t k0 = 0; k0 < n; k0 += batch) {
        size_t nb = n - k0 < batch ? n - k0 : batch;
        for (size_t b = 0; b < nb; b++) {
            s->ubuf[b] = s->asks[s->lvl_idx[k0 + b]].u;
            s->vbuf[b] = s->asks[s->lvl_idx[k0 + b]].v;
        }
        int rc = fit_design_build(R, s->cfg.sensor.pitch_um, L->k, s->ubuf, s->vbuf, nb, &s->opts,
                                  s->abuf, NULL, err);
        if (rc) return rc;
        for (size_t b = 0; b < nb; b++) {
            const double *row = s->abuf + b * kk;
            double acc = 0;
            for (size_t c = 0; c < kk; c++)
                acc += row[c] * L->map[c];
            s->memo.e[s->asks[s->lvl_idx[k0 + b]].slot].value = acc;
        }
    }
    if (L->k == s->m)
        s->stats.full += n;
    else if (L->k == 1)
        s->stats.uniform += n;
    else
        s->stats.coarse += n;
    return 0;
}

/* Fills integ[] (S times the unit-peak Airy over each roi pixel, um^2) and bnd[] (the bound of
 * what was left out) for a spot at sensor (xs, ys) of radius R. */
static int integrate_roi(sim_t *s, double xs, double ys, double R, const cam_roi_t *roi,
                         double *integ, double *bnd, err_t *err)
{
    double p = s->cfg.sensor.pitch_um, a = fit_airy_a(R), total = fit_airy_total(a);
    double tol = s->cfg.leave_out_tol * total;
    size_t npx = (size_t)roi->width * roi->height, nmiss = 0;
    uint64_t kr;
    memcpy(&kr, &R, sizeof kr);
    /* room for every pixel up front: no rehash while slots are held */
    if (grow(s, npx) || memo_reserve(&s->memo, npx))
        return err_set(err, -ENOMEM, "out of memory for the pixel memo");
    for (size_t idx = 0; idx < npx; idx++) {
        int col = roi->col + (int)(idx % (size_t)roi->width);
        int row = roi->row + (int)(idx / (size_t)roi->width);
        int64_t ku = llround((xs - col * p) / QUANTUM_UM);
        int64_t kv = llround((ys - row * p) / QUANTUM_UM);
        size_t slot = slot_of(&s->memo, ku, kv, kr);
        s->pslot[idx] = slot;
        s->stats.lookups++;
        if (s->memo.used[slot]) { /* known, or asked earlier in this roi */
            s->stats.hits++;
            continue;
        }
        double u = ku * QUANTUM_UM, v = kv * QUANTUM_UM, bound;
        struct ask *q = &s->asks[nmiss++];
        *q = (struct ask){.u = u, .v = v, .slot = slot};
        q->level = choose_level(s, a, total, tol, u, v, &bound);
        s->stats.left_out += q->level == LEFT_OUT;
        s->memo.used[slot] = 1;
        s->memo.n++;
        s->memo.e[slot] = (struct memo_entry){ku, kv, kr, 0.0, bound};
    }
    s->n_asks = nmiss;
    int rc = 0;
    for (int l = 0; l < s->nlv && rc == 0; l++)
        rc = integrate_level(s, R, l, err);
    if (rc) { /* drop the half-filled entries */
        memset(s->memo.used, 0, s->memo.cap);
        s->memo.n = 0;
        return rc;
    }
    for (size_t idx = 0; idx < npx; idx++) {
        integ[idx] = s->memo.e[s->pslot[idx]].value;
        bnd[idx] = s->memo.e[s->pslot[idx]].bound;
    }
    return 0;
}

/* ---- the camera ---- */

int sim_expected(sim_t *s, double xs, double ys, double R_um, const cam_roi_t *roi, double *e_out,
                 double *left_out_e, err_t *err)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    cam_roi_t r;
    int rc = cam_roi_check(roi, sn->cols, sn->rows, &r, err);
    if (rc) return rc;
    if (!(R_um > 0) || !isfinite(R_um) || !isfinite(xs) || !isfinite(ys) || fabs(xs) > 1e8 ||
        fabs(ys) > 1e8)
        return err_set(err, -EINVAL, "spot at (%g, %g) um with radius %g um is not usable", xs, ys,
                       R_um);
    size_t npx = (size_t)r.width * r.height;
    double *bnd = malloc(sizeof(double) * npx);
    if (!bnd) return err_set(err, -ENOMEM, "out of memory for %zu pixels", npx);
    double t0 = clock_mono_s();
    rc = integrate_roi(s, xs, ys, R_um, &r, e_out, bnd, err);
    s->stats.integrate_s += clock_mono_s() - t0;
    if (rc == 0) {
        /* electrons = flux (t / t_ref) * integral / whole-plane integral (sim.h photometry) */
        double scale = s->cfg.flux_e * (s->exposure_us / s->cfg.ref_exposure_us) /
                       fit_airy_total(fit_airy_a(R_um));
        double worst = 0;
        for (size_t k = 0; k < npx; k++) {
            e_out[k] *= scale;
            if (bnd[k] * scale > worst) worst = bnd[k] * scale;
        }
        if (left_out_e) *left_out_e = worst;
    }
    free(bnd);
    return rc;
}

int sim_info(sim_t *s, cam_info_t *info)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    memset(info, 0, sizeof *info);
    snprintf(info->backend, sizeof info->backend, "sim");
    snprintf(info->id, sizeof info->id, "%.127s", s->scene_spec);
    snprintf(info->model, sizeof info->model, "ipsd simulated bench");
    info->width = sn->cols;
    info->height = sn->rows;
    info->pitch_um = sn->pitch_um;
    info->gain_e_per_dn = sn->gain_e_per_dn;
    info->read_noise_e = sn->read_noise_e;
    info->bias_dn = sn->bias_dn;
    info->full_scale_dn = sn->full_scale_dn;
    info->exposure_min_us = 1;
    info->exposure_max_us = 60e6;
    info->gain_min = 1;
    info->gain_max = 16;
    return 0;
}

int sim_set_exposure(sim_t *s, double exposure_us, err_t *err)
{
    if (!(exposure_us >= 1 && exposure_us <= 60e6))
        return err_set(err, -ERANGE,
                       "exposure %g us is outside the simulated camera's range "
                       "[1, 6e7] us",
                       exposure_us);
    s->exposure_us = exposure_us;
    return 0;
}

int sim_set_gain(sim_t *s, double gain, err_t *err)
{
    if (!(gain >= 1 && gain <= 16))
        return err_set(err, -ERANGE,
                       "analogue gain %g is outside the simulated camera's range "
                       "[1, 16]",
                       gain);
    s->gain = gain;
    return 0;
}

/* One pixel's DN from its expected charge (sim.h: Poisson, full well, read noise, gain, bias,
 * rounding, clipping). */
static uint16_t draw_dn(sim_t *s, double lambda_e)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    double e = lambda_e;
    if (!s->cfg.noiseless) {
        /* far above the full well the pixel clips whatever the draw: skip the costly draw */
        e = lambda_e > 100 * sn->full_well_e ? lambda_e
            : lambda_e > 0                   ? (double)gsl_ran_poisson(s->rng, lambda_e)
                                             : 0;
    }
    if (e > sn->full_well_e) e = sn->full_well_e;
    if (!s->cfg.noiseless && sn->read_noise_e > 0)
        e += gsl_ran_gaussian_ziggurat(s->rng, sn->read_noise_e);
    double dn = nearbyint(sn->bias_dn + e * s->gain / sn->gain_e_per_dn);
    return (uint16_t)(dn < 0 ? 0 : dn > sn->full_scale_dn ? sn->full_scale_dn : dn);
}

int sim_capture(sim_t *s, const cam_roi_t *roi, cam_frame_t *f, err_t *err)
{
    const scene_sensor_t *sn = &s->cfg.sensor;
    cam_roi_t r;
    int rc = cam_roi_check(roi, sn->cols, sn->rows, &r, err);
    if (rc) return rc;
    size_t npx = (size_t)r.width * r.height;
    f->roi = r;
    f->dn = malloc(sizeof(uint16_t) * npx);
    f->expected_dn = malloc(sizeof(double) * npx);
    if (!f->dn || !f->expected_dn)
        return err_set(err, -ENOMEM, "out of memory for a %dx%d frame", r.width, r.height);
    double xs, ys, zs, left_e = 0;
    sim_spot(s, &xs, &ys, &zs);
    rc = sim_expected(s, xs, ys, sim_spot_radius(s, zs), &r, f->expected_dn, &left_e, err);
    if (rc) return rc;
    double t0 = clock_mono_s(), dn_per_e = s->gain / sn->gain_e_per_dn;
    for (size_t k = 0; k < npx; k++) {
        double lambda = f->expected_dn[k];
        f->dn[k] = draw_dn(s, lambda);
        f->expected_dn[k] = sn->bias_dn + lambda * dn_per_e;
    }
    s->stats.noise_s += clock_mono_s() - t0;
    s->stats.frames++;
    s->stats.pixel_frames += npx;
    if (left_e > s->stats.max_left_out_e) s->stats.max_left_out_e = left_e;
    f->left_out_dn = left_e * dn_per_e;
    f->exposure_us = s->exposure_us;
    f->gain = s->gain;
    double t; /* the frame's timestamp is the start of its exposure, as libcamera's */
    stage_sim_clock(s->stage, &t);
    f->timestamp_ns = (int64_t)llround(t * 1e9);
    stage_sim_advance(s->stage, s->exposure_us * 1e-6 + s->cfg.readout_s);
    f->temperature_c = s->cfg.temperature_c;
    return 0;
}

void sim_get_stats(const sim_t *s, sim_stats_t *stats)
{
    *stats = s->stats;
}

void sim_reset_stats(sim_t *s)
{
    memset(&s->stats, 0, sizeof s->stats);
}
