/* fidelity.c: ipsd-bench-fidelity, the evidence table for the map's scientific choices: every
 * scene family of the simulated bench, scanned by the paper's rasters at two photon levels and
 * several seeds, fitted for r = 1..R; prints per case the rms error of each r's map against the
 * simulator's truth, the r AIC, BIC, leave-one-out CV and the recommended-r rule pick
 * (fit/recommend.h), the best r in hindsight, and the Wiener baseline, then a summary per raster,
 * per scene and per configuration (scene, raster, light: the rms over the seeds against the best
 * fixed r's) (instrument/fidelity.h). --tune measures a grid of the rule's two settings instead.
 * A benchmark: it prints, it never fails on numbers.
 * Usage: ipsd-bench-fidelity [--quick] [--tune] [--r-max R] [--seeds N] [--first-seed S]
 * [--raster I] [--scene NAME] [--sigma MODEL] [--dump FILE] [--explain] (the fits' noise model,
 * default shot+read: the physically consistent one, numerics.md; seeds S..S+N-1, 1..3 by default,
 * the seeds the rule was chosen on: --first-seed 4 gives held-out ones; --dump writes every fit of
 * every case for studying rules offline; --explain prints, under every case whose recommendation
 * misses the best r by more than 1.1x, the criteria the rule weighed for each r: reduced chi2,
 * leave-one-out chi2 per point, noise, contrast, resolution error and expected error; --simcheck
 * scores the simulation-based check of the rule's pick, docs/numerics.md "The recommended r"; --krige
 * scores the kriged map, fit/krige.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/parse.h"
#include "instrument/fidelity.h"

static const char *const scenes[] = {"paperlike", "uniform", "gradient", "dip",     "deadcorner",
                                     "edge",      "softedge", "ring",   "busline", "diagedge",
                                     "bowl",      "twodips"};
static const struct raster {
    const char *name;
    int grid;
    double step;
} rasters[] = {
    {"9x9 @0.6", 9, 0.6}, {"13x13 @0.42", 13, 0.42}, {"19x19 @0.3", 19, 0.3},
    {"51x51 full", 0, 0.6},
};
static const double fluxes[] = {1.0, 0.1};

#define N_SCENES (sizeof scenes / sizeof scenes[0])
#define N_RASTERS (sizeof rasters / sizeof rasters[0])
#define N_FLUXES (sizeof fluxes / sizeof fluxes[0])
#define OK_RATIO 1.1 /* the target: a pick within 1.1x of the best map in hindsight */

/* Ratio of a pick's rms to the best in hindsight (1 = as good as can be); floor 1e-3: a flat
 * pixel's r = 1 map is exact (rms 0), and 0.1 % is below any noise. */
static double ratio(const fid_result_t *f, int r)
{
    return r > 0 && f->r_best > 0 ? f->rms[r] / fmax(f->rms[f->r_best], 1e-3) : INFINITY;
}

/* The shrunk map's ratio (fit/shrink.h): the recommended map's where there is none. */
static double ratio_shrunk(const fid_result_t *f)
{
    if (!isfinite(f->rms_shrunk)) return ratio(f, f->r_rec[0]);
    return f->r_best > 0 ? f->rms_shrunk / fmax(f->rms[f->r_best], 1e-3) : INFINITY;
}

/* How one rule did over a set of cases. */
struct score {
    int ok;
    double worst;
};

static void score_add(struct score *s, double ratio)
{
    s->ok += ratio <= OK_RATIO;
    s->worst = fmax(s->worst, ratio);
}

enum { RULE_AIC, RULE_BIC, RULE_CV, RULE_REC, RULE_SHRUNK, N_FIXED };
enum { SIM_DOWN, SIM_UP, SIM_BOTH, N_SIM }; /* --simcheck's variants (simcheck below) */

struct tally {
    int cases;
    struct score s[N_FIXED + FID_MAX_RULES];
    struct score fixed[FID_R_MAX + 1]; /* fixed[r]: always r */
    struct score sim[N_SIM];           /* --simcheck's picks */
    double wiener_sum, best_sum;
    long z_n, z_in2_rec, z_in2_shrunk; /* S_err's honesty (fidelity.h) */
    double z2_rec, z2_shrunk;
    long z_in2_rec_res, z_in2_shrunk_res; /* with the resolution error S_res */
    double z2_rec_res, z2_shrunk_res;
};

struct run {
    int quick, tune, r_max, seeds, first_seed, raster; /* raster: index + 1, 0 all */
    const char *scene;                                  /* NULL: every family */
    FILE *dump;
    int explain, simcheck, krige;
    fit_noise_t noise;
    fit_recommend_opts_t rules[FID_MAX_RULES];
    int n_rules;
};

static int parse(int argc, char **argv, struct run *u)
{
    *u = (struct run){.r_max = 10, .seeds = 3, .first_seed = 1, .noise = FIT_NOISE_SHOT_READ};
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--quick") == 0) u->quick = 1;
        else if (strcmp(argv[i], "--tune") == 0) u->tune = 1;
        else if (strcmp(argv[i], "--explain") == 0) u->explain = 1;
        else if (strcmp(argv[i], "--simcheck") == 0) u->simcheck = 1;
        else if (strcmp(argv[i], "--krige") == 0) u->krige = 1;
        else if (strcmp(argv[i], "--sigma") == 0 && i + 1 < argc &&
                 fit_noise_parse(argv[i + 1], &u->noise) == 0)
            i++;
        else if (strcmp(argv[i], "--r-max") == 0 && i + 1 < argc &&
                 parse_int(argv[i + 1], &u->r_max) == 0 && u->r_max >= 1 && u->r_max <= FID_R_MAX)
            i++;
        else if (strcmp(argv[i], "--seeds") == 0 && i + 1 < argc &&
                 parse_int(argv[i + 1], &u->seeds) == 0 && u->seeds >= 1)
            i++;
        else if (strcmp(argv[i], "--first-seed") == 0 && i + 1 < argc &&
                 parse_int(argv[i + 1], &u->first_seed) == 0 && u->first_seed >= 1)
            i++;
        else if (strcmp(argv[i], "--raster") == 0 && i + 1 < argc &&
                 parse_int(argv[i + 1], &u->raster) == 0 && u->raster >= 1 &&
                 u->raster <= (int)N_RASTERS)
            i++;
        else if (strcmp(argv[i], "--scene") == 0 && i + 1 < argc)
            u->scene = argv[++i];
        else if (strcmp(argv[i], "--dump") == 0 && i + 1 < argc && !u->dump &&
                 (u->dump = fopen(argv[i + 1], "w")) != NULL)
            i++;
        else {
            fprintf(stderr, "usage: ipsd-bench-fidelity [--quick] [--tune] [--r-max 1..%d] "
                            "[--seeds N] [--first-seed S] [--raster 1..%zu] [--scene NAME] "
                            "[--sigma paper|shot+read] [--dump FILE] [--explain] [--simcheck] [--krige]\n"
                            "  seeds S..S+N-1 (default 1..3); --raster: 9x9, 13x13, 19x19, "
                            "51x51 full; --dump: every fit's map, S_err and chi2 and the "
                            "case's rms by r, as text, for studying rules offline; --explain: "
                            "the rule's criteria by r under every case it misses; --krige: the kriged map too\n",
                    FID_R_MAX, N_RASTERS);
            return 2;
        }
    }
    if (u->quick) u->seeds = 1;
    u->rules[0] = fit_recommend_opts_default();
    u->n_rules = 1;
    if (u->tune) { /* a grid around the default; rules[0], the default, stays first; weight 0
                      is the rule without its step 3 (the leave-one-out pick alone) */
        static const double f[] = {0.15, 0.2, 0.25, 0.3, 0.35, 0.5};
        static const double w[] = {0, 1, 1.5, 2, 3};
        for (size_t a = 0; a < sizeof f / sizeof f[0]; a++)
            for (size_t b = 0; b < sizeof w / sizeof w[0]; b++)
                if (f[a] == 0.25 || w[b] == 2 || w[b] == 0)
                    if (u->n_rules < FID_MAX_RULES) {
                        fit_recommend_opts_t o = fit_recommend_opts_default();
                        o.noise_to_contrast = f[a];
                        o.noise_weight = w[b];
                        if (w[b] <= 0) o.escape_misfit = 0;
                        u->rules[u->n_rules++] = o;
                    }
    }
    return 0;
}

/* --explain: what the default rule weighed in the last sweep, by r (the sweep is freed before
 * fid_run returns, so the callback keeps it). */
struct explain {
    fit_recommendation_t rec;
    int r_min, r_max;
    struct {
        int has_map, flags;
        double chi2_red, cv_per_point, noise, contrast, resolution, expected;
    } by_r[FID_R_MAX + 1];
};

static void explain_sweep(const fit_sweep_t *sw, struct explain *x)
{
    fit_recommend(sw, NULL, &x->rec);
    fit_recommend_opts_t o = fit_recommend_opts_default();
    x->r_min = sw->r_min;
    x->r_max = sw->r_max < FID_R_MAX ? sw->r_max : FID_R_MAX;
    for (int r = sw->r_min; r <= x->r_max; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        double noise, contrast, res = NAN;
        fit_map_noise_contrast(f, &noise, &contrast);
        x->by_r[r].has_map = f->S != NULL;
        x->by_r[r].flags = (int)f->flags;
        x->by_r[r].chi2_red = f->chi2_red;
        x->by_r[r].cv_per_point = f->cv_chi2 / (double)f->n_used;
        x->by_r[r].noise = noise * x->rec.noise_scale;
        x->by_r[r].contrast = contrast;
        x->by_r[r].expected =
            fit_map_expected_error(f, x->rec.noise_scale, o.noise_weight, NULL, &res);
        x->by_r[r].resolution = res;
    }
}

static void explain_print(const struct explain *x, const fid_result_t *f)
{
    const fit_recommendation_t *c = &x->rec;
    printf("    rule: r_cv = %d, one-SE r = %d, decided by step %d, scatter^2 %.3f%s", c->r_cv,
           c->r_se, c->step, c->noise_scale * c->noise_scale,
           c->vetoed ? ", vetoed as misfitting: r = " : "");
    if (c->vetoed) printf("%d", c->vetoed);
    printf("\n    %3s %6s %9s %9s %8s %8s %8s %8s %8s\n", "r", "flags", "chi2_red", "loo/N",
           "noise", "contrast", "resol", "expected", "rms");
    for (int r = x->r_min; r <= x->r_max; r++)
        if (x->by_r[r].has_map)
            printf("    %3d %6d %9.3f %9.3f %8.4f %8.4f %8.4f %8.4f %8.4f%s\n", r, x->by_r[r].flags,
                   x->by_r[r].chi2_red, x->by_r[r].cv_per_point, x->by_r[r].noise,
                   x->by_r[r].contrast, x->by_r[r].resolution, x->by_r[r].expected, f->rms[r],
                   r == f->r_best ? "  best" : r == c->r ? "  recommended" : "");
}

/* --simcheck: the simulation-based check of the rule's pick p, with fit/'s own model as the
 * simulator. The stand-in truth is a fitted map S_q; its noise-free data are fit q's model of
 * every point (model_dn); refitting them at r gives the bias of r against S_q exactly, because
 * the fit is linear: the mean of parametric-bootstrap refits is this one refit and their spread
 * is S_err, so no replicates are needed. Risk of r against the stand-in S_q:
 * |S_r(A S_q) - S_q|^2 + noise_r^2 (noise: rms S_err times the rule's scatter), and S_q's own
 * risk is noise_q^2. Down: stand-in S_p, p - 1 replaces p when its risk is smaller; up: stand-in
 * S_p+1, p + 1 replaces p when its own noise^2 is below p's risk; both: down, else up. */

struct sweep_ctx {
    FILE *dump;
    struct explain *explain;
    int simcheck;
    int r_sim[N_SIM];
};

static double noise2(const fit_result_t *f, double scale)
{
    double v = 0;
    for (int j = 0; j < f->r * f->r; j++) v += f->S_err[j] * f->S_err[j];
    return v / (f->r * f->r) * scale * scale;
}

/* The risk of fitting r against the stand-in fit q (NaN when either has no usable map). */
static double sim_risk(const fit_scan_t *scan, const fit_options_t *opts, const fit_sweep_t *sw,
                       int r, int q, double scale)
{
    if (r < sw->r_min || q > sw->r_max || r < 1) return NAN;
    const fit_result_t *fq = &sw->fits[q - sw->r_min], *fr = &sw->fits[r - sw->r_min];
    if (!fq->S || !fq->model_dn || !fr->S) return NAN;
    double *y = malloc(sizeof(double) * scan->n);
    if (!y) return NAN;
    for (size_t k = 0; k < scan->n; k++) /* points fit q left out keep their signal */
        y[k] = isfinite(fq->model_dn[k]) ? fq->model_dn[k] : scan->signal_dn[k];
    fit_scan_t s = *scan;
    s.signal_dn = y;
    fit_result_t f;
    err_t err;
    double risk = NAN;
    if (fit_map(&s, r, opts, &f, &err) == 0) {
        if (f.S) {
            double b = fid_map_rms(f.S, r, fq->S, q, 240);
            risk = b * b + noise2(fr, scale);
        }
        fit_result_free(&f);
    }
    free(y);
    return risk;
}

static int trusted(const fit_sweep_t *sw, int r)
{
    if (r < sw->r_min || r > sw->r_max) return 0;
    const fit_result_t *f = &sw->fits[r - sw->r_min];
    return f->S && !(f->flags & (FIT_UNDERDETERMINED | FIT_NO_SIGNAL | FIT_ILL_CONDITIONED |
                                 FIT_UNCONSTRAINED | FIT_NO_POINTS));
}

static void simcheck(const fit_scan_t *scan, const fit_options_t *opts, const fit_sweep_t *sw,
                     int r_sim[N_SIM])
{
    fit_recommendation_t rec;
    fit_recommend(sw, NULL, &rec);
    int p = rec.r, down = p, up = p;
    double sc = rec.noise_scale;
    if (p >= 2 && trusted(sw, p - 1)) {
        double rd = sim_risk(scan, opts, sw, p - 1, p, sc);
        if (rd < noise2(&sw->fits[p - sw->r_min], sc)) down = p - 1;
    }
    if (p >= 1 && trusted(sw, p + 1)) {
        double ru = sim_risk(scan, opts, sw, p, p + 1, sc);
        if (noise2(&sw->fits[p + 1 - sw->r_min], sc) < ru) up = p + 1;
    }
    r_sim[SIM_DOWN] = down;
    r_sim[SIM_UP] = up;
    r_sim[SIM_BOTH] = down != p ? down : up;
}

/* --dump: one line per fit of the sweep ("F r flags n_used params chi2 chi2_red cv_chi2
 * S[r*r] S_err[r*r]"), each followed by its normalised residuals ("R r n resid[n]", nan for a
 * point left out; they give the spread of the per-point leave-one-out terms a one-standard-error
 * rule needs), with --simcheck its three picks ("K down up both"), then the case line from main
 * ("C scene raster flux seed rms[1..r_max]"). */
static void on_sweep(const fit_scan_t *scan, const fit_options_t *opts, const fit_sweep_t *sw,
                     void *ctx)
{
    struct sweep_ctx *k = ctx;
    if (k->explain) explain_sweep(sw, k->explain);
    if (k->simcheck) simcheck(scan, opts, sw, k->r_sim);
    FILE *fp = k->dump;
    if (fp && k->simcheck)
        fprintf(fp, "K %d %d %d\n", k->r_sim[SIM_DOWN], k->r_sim[SIM_UP], k->r_sim[SIM_BOTH]);
    for (int r = sw->r_min; fp && r <= sw->r_max; r++) {
        const fit_result_t *f = &sw->fits[r - sw->r_min];
        fprintf(fp, "F %d %u %zu %d %.9g %.9g %.9g", r, f->flags, f->n_used, f->params, f->chi2,
                f->chi2_red, f->cv_chi2);
        for (int j = 0; f->S && j < r * r; j++) fprintf(fp, " %.9g", f->S[j]);
        for (int j = 0; f->S && j < r * r; j++) fprintf(fp, " %.9g", f->S_err[j]);
        fprintf(fp, "\n");
        if (!f->resid) continue;
        size_t n = f->n_used + f->n_saturated + f->n_nonfinite; /* the points fitted */
        fprintf(fp, "R %d %zu", r, n);
        for (size_t k = 0; k < n; k++) fprintf(fp, " %.6g", f->resid[k]);
        fprintf(fp, "\n");
    }
}

static void print_case(const fid_case_t *c, const char *raster, const fid_result_t *f, int r_max)
{
    printf("%-11s %-12s %5.2f %4lu %6zu | %3d %3d %3d %3d %3d | %7.4f %7.4f %7.4f %7.4f %7.4f "
           "%5.2f | %7.4f |",
           c->scene, raster, c->flux_scale, c->seed, f->n_points, f->r_aic, f->r_bic, f->r_cv,
           f->r_rec[0], f->r_best, f->r_aic ? f->rms[f->r_aic] : NAN,
           f->r_bic ? f->rms[f->r_bic] : NAN, f->r_rec[0] ? f->rms[f->r_rec[0]] : NAN,
           f->r_best ? f->rms[f->r_best] : NAN, f->rms_shrunk, f->shrunk_factor, f->rms_wiener);
    for (int r = 1; r <= r_max; r++) printf(" %.3f", f->rms[r]);
    if (isfinite(f->rms_kriged)) /* --krige: the kriged map's rms, grid, smooth part, ms, ratio */
        printf(" | kriged %.5f %d %d %.0f %.4f", f->rms_kriged, f->kriged_grid, f->kriged_smooth,
               f->kriged_ms, f->r_best > 0 ? f->rms_kriged / fmax(f->rms[f->r_best], 1e-3) : NAN);
    printf("\n");
    fflush(stdout);
}

static void tally_case(struct tally *k, const fid_result_t *f, int n_rules)
{
    k->cases++;
    score_add(&k->s[RULE_AIC], ratio(f, f->r_aic));
    score_add(&k->s[RULE_BIC], ratio(f, f->r_bic));
    score_add(&k->s[RULE_CV], ratio(f, f->r_cv));
    score_add(&k->s[RULE_REC], ratio(f, f->r_rec[0]));
    score_add(&k->s[RULE_SHRUNK], ratio_shrunk(f));
    for (int i = 0; i < n_rules; i++) score_add(&k->s[N_FIXED + i], ratio(f, f->r_rec[i]));
    for (int r = 1; r <= f->r_max; r++)
        score_add(&k->fixed[r], isfinite(f->rms[r]) ? ratio(f, r) : INFINITY);
    k->best_sum += f->r_best ? f->rms[f->r_best] : 0;
    k->wiener_sum += isfinite(f->rms_wiener) ? f->rms_wiener : 0;
    k->z_n += f->z_n, k->z_in2_rec += f->z_in2_rec, k->z_in2_shrunk += f->z_in2_shrunk;
    k->z2_rec += f->z2_rec, k->z2_shrunk += f->z2_shrunk;
    k->z_in2_rec_res += f->z_in2_rec_res, k->z_in2_shrunk_res += f->z_in2_shrunk_res;
    k->z2_rec_res += f->z2_rec_res, k->z2_shrunk_res += f->z2_shrunk_res;
}

/* The kriged map (--krige, fit/krige.h) over a set of cases: within 1.1x of the best r, its
 * mean ratio beside the shrunk map's, S_err's honesty, cost. */
struct ktally {
    int n, ok, smooth, ok_post;
    double worst, sum, sum_shrunk, ms_sum, ms_max, z2, worst_post;
    long z_n, z_in2;
};

static double ratio_kriged(const fid_result_t *f)
{
    return f->r_best > 0 && isfinite(f->rms_kriged)
               ? f->rms_kriged / fmax(f->rms[f->r_best], 1e-3)
               : INFINITY;
}

static void ktally_add(struct ktally *k, const fid_result_t *f)
{
    double q = ratio_kriged(f);
    k->n++;
    k->ok += q <= OK_RATIO;
    k->worst = fmax(k->worst, q);
    k->sum += q;
    k->sum_shrunk += ratio_shrunk(f);
    k->smooth += f->kriged_smooth;
    k->ok_post += ratio(f, f->r_post) <= OK_RATIO;
    k->worst_post = fmax(k->worst_post, ratio(f, f->r_post));
    if (isfinite(f->kriged_ms)) k->ms_sum += f->kriged_ms, k->ms_max = fmax(k->ms_max, f->kriged_ms);
    k->z2 += f->z2_kriged, k->z_n += f->z_n_kriged, k->z_in2 += f->z_in2_kriged;
}

static void ktally_print(const char *name, const struct ktally *k)
{
    if (!k->n) return;
    printf("  %-12s %5d | %4d/%-4d %7.2f   %6.3f   %6.3f | %4d | %6.3f %5.1f%% | %8.1f %8.1f"
           " | %4d/%-4d %7.2f\n",
           name, k->n, k->ok, k->n, k->worst, k->sum / k->n, k->sum_shrunk / k->n, k->smooth,
           k->z_n ? sqrt(k->z2 / (double)k->z_n) : NAN,
           k->z_n ? 100.0 * (double)k->z_in2 / (double)k->z_n : NAN, k->ms_sum / k->n, k->ms_max,
           k->ok_post, k->n, k->worst_post);
}

/* Adds tally k into sum. */
static void tally_sum(struct tally *sum, const struct tally *k)
{
    sum->cases += k->cases;
    sum->best_sum += k->best_sum;
    sum->wiener_sum += k->wiener_sum;
    sum->z_n += k->z_n, sum->z_in2_rec += k->z_in2_rec, sum->z_in2_shrunk += k->z_in2_shrunk;
    sum->z2_rec += k->z2_rec, sum->z2_shrunk += k->z2_shrunk;
    sum->z_in2_rec_res += k->z_in2_rec_res, sum->z_in2_shrunk_res += k->z_in2_shrunk_res;
    sum->z2_rec_res += k->z2_rec_res, sum->z2_shrunk_res += k->z2_shrunk_res;
    for (int i = 0; i < N_FIXED + FID_MAX_RULES; i++) {
        sum->s[i].ok += k->s[i].ok;
        sum->s[i].worst = fmax(sum->s[i].worst, k->s[i].worst);
    }
    for (int r = 0; r <= FID_R_MAX; r++) {
        sum->fixed[r].ok += k->fixed[r].ok;
        sum->fixed[r].worst = fmax(sum->fixed[r].worst, k->fixed[r].worst);
    }
}

/* A configuration (scene, raster, light) over its seeds: the quadratic mean of each map's rms
 * over the seeds, so the best fixed r in hindsight is judged on the error a lab can expect of a
 * scene, not on one noise realisation (the per-case best r also chases the noise: numerics.md,
 * "The recommended r", "Per configuration"). */
struct conf {
    int seeds;
    double rms2[FID_R_MAX + 1]; /* sums of rms^2 over the seeds (NaN once one is missing) */
    double rec2, shrunk2;       /* the recommended map's, the shrunk map's (else the former) */
};

struct conf_tally {
    int n, ok_rec, ok_shrunk;
    double worst_rec, worst_shrunk;
    char worst_rec_name[48], worst_shrunk_name[48];
};

static void conf_add(struct conf *k, const fid_result_t *f)
{
    double rec = f->r_rec[0] > 0 ? f->rms[f->r_rec[0]] : NAN;
    double shr = isfinite(f->rms_shrunk) ? f->rms_shrunk : rec;
    k->seeds++;
    for (int r = 1; r <= f->r_max; r++) k->rms2[r] += f->rms[r] * f->rms[r];
    k->rec2 += rec * rec;
    k->shrunk2 += shr * shr;
}

/* Scores configuration k (name: for the worst) against its best fixed r; prints it when either
 * map is more than 1.05x that r's. */
static void conf_close(const struct conf *k, int r_max, const char *name, struct conf_tally *t)
{
    if (!k->seeds) return;
    int rb = 0;
    for (int r = 1; r <= r_max; r++)
        if (isfinite(k->rms2[r]) && (!rb || k->rms2[r] < k->rms2[rb])) rb = r;
    if (!rb) return;
    double best = fmax(sqrt(k->rms2[rb] / k->seeds), 1e-3); /* floor: as ratio() */
    double qr = sqrt(k->rec2 / k->seeds) / best, qs = sqrt(k->shrunk2 / k->seeds) / best;
    qr = isfinite(qr) ? qr : INFINITY;
    qs = isfinite(qs) ? qs : INFINITY;
    t->n++;
    t->ok_rec += qr <= OK_RATIO;
    t->ok_shrunk += qs <= OK_RATIO;
    if (qr > t->worst_rec) {
        t->worst_rec = qr;
        snprintf(t->worst_rec_name, sizeof t->worst_rec_name, "%s", name);
    }
    if (qs > t->worst_shrunk) {
        t->worst_shrunk = qs;
        snprintf(t->worst_shrunk_name, sizeof t->worst_shrunk_name, "%s", name);
    }
    if (qr > 1.05 || qs > 1.05)
        printf("  configuration %s over %d seeds: recommended map %.3fx, shrunk map %.3fx the "
               "best fixed r = %d (rms %.4f)\n", name, k->seeds, qr, qs, rb, best);
}

/* One row: the rules, the best fixed r (most cases within OK_RATIO, then the smallest worst
 * ratio), the mean rms of the best map and of Wiener. */
static void print_row(const char *name, const struct tally *k, int r_max)
{
    int rf = 1;
    for (int r = 2; r <= r_max; r++)
        if (k->fixed[r].ok > k->fixed[rf].ok ||
            (k->fixed[r].ok == k->fixed[rf].ok && k->fixed[r].worst < k->fixed[rf].worst))
            rf = r;
    printf("%-12s %5d |", name, k->cases);
    for (int i = 0; i < N_FIXED; i++) printf(" %3d/%-3d %6.2f |", k->s[i].ok, k->cases, k->s[i].worst);
    printf(" r=%-2d %3d/%-3d %7.2f |", rf, k->fixed[rf].ok, k->cases, k->fixed[rf].worst);
    printf(" %8.4f %8.4f\n", k->cases ? k->best_sum / k->cases : NAN,
           k->cases ? k->wiener_sum / k->cases : NAN);
}

static void print_header(const char *what)
{
    printf("%-12s %5s | %14s | %14s | %14s | %14s | %14s | %19s | %8s %8s\n", what, "cases",
           "AIC", "BIC", "LOO-CV", "recommended", "shrunk", "best fixed r", "best", "Wiener");
}

static void print_summary(const struct tally *t, const struct tally *ts,
                          const struct conf_tally *ct, const struct run *u)
{
    printf("\nsummary: picks within %.1fx of the best r in hindsight (cases ok / all) and the "
           "worst ratio; mean rms of the best map and of Wiener\n", OK_RATIO);
    print_header("raster");
    struct tally all = {0};
    for (size_t ri = 0; ri < N_RASTERS; ri++) {
        tally_sum(&all, &t[ri]);
        print_row(rasters[ri].name, &t[ri], u->r_max);
    }
    print_row("all", &all, u->r_max);
    if (all.z_n) {
        printf("S_err against the truth's sub-pixel means (cases with a shrunk map, %ld "
               "sub-pixels): recommended map rms z %.3f, |z| <= 2 in %.1f %%; shrunk map rms z "
               "%.3f, |z| <= 2 in %.1f %% (Gaussian: 1, 95.4 %%)\n", all.z_n,
               sqrt(all.z2_rec / (double)all.z_n), 100.0 * (double)all.z_in2_rec / (double)all.z_n,
               sqrt(all.z2_shrunk / (double)all.z_n),
               100.0 * (double)all.z_in2_shrunk / (double)all.z_n);
        printf("With the resolution error S_res added in quadrature: recommended map rms z %.3f, "
               "|z| <= 2 in %.1f %%; shrunk map rms z %.3f, |z| <= 2 in %.1f %%\n",
               sqrt(all.z2_rec_res / (double)all.z_n),
               100.0 * (double)all.z_in2_rec_res / (double)all.z_n,
               sqrt(all.z2_shrunk_res / (double)all.z_n),
               100.0 * (double)all.z_in2_shrunk_res / (double)all.z_n);
    }
    if (ct->n)
        printf("Per configuration (scene, raster, light; the quadratic mean of the rms over its "
               "seeds): the recommended map within %.1fx of the best fixed r in %d / %d (worst "
               "%.2fx, %s), the shrunk map in %d / %d (worst %.2fx, %s)\n", OK_RATIO, ct->ok_rec,
               ct->n, ct->worst_rec, ct->worst_rec_name, ct->ok_shrunk, ct->n, ct->worst_shrunk,
               ct->worst_shrunk_name);
    printf("\n");
    print_header("scene");
    for (size_t si = 0; si < N_SCENES; si++) print_row(scenes[si], &ts[si], u->r_max);
    printf("\nS_err's honesty by scene (rms z, %% with |z| <= 2): recommended map alone, with "
           "S_res; shrunk map alone, with S_res\n");
    for (size_t si = 0; si < N_SCENES; si++) {
        const struct tally *k = &ts[si];
        if (!k->z_n) continue;
        double n = (double)k->z_n;
        printf("  %-12s %6ld sub-pixels  %5.2f %5.1f%%  %5.2f %5.1f%%   %5.2f %5.1f%%  %5.2f "
               "%5.1f%%\n", scenes[si], k->z_n, sqrt(k->z2_rec / n), 100 * k->z_in2_rec / n,
               sqrt(k->z2_rec_res / n), 100 * k->z_in2_rec_res / n, sqrt(k->z2_shrunk / n),
               100 * k->z_in2_shrunk / n, sqrt(k->z2_shrunk_res / n),
               100 * k->z_in2_shrunk_res / n);
    }
    if (!u->tune) return;
    printf("\nrule settings noise_to_contrast, noise_weight (0: steps 1-2 only): cases within "
           "%.1fx of the best, worst ratio, over all rasters (the first row is the default)\n",
           OK_RATIO);
    for (int i = 0; i < u->n_rules; i++)
        printf("  %.2f %.1f  %3d/%-3d %8.2f\n", u->rules[i].noise_to_contrast,
               u->rules[i].noise_weight, all.s[N_FIXED + i].ok, all.cases,
               all.s[N_FIXED + i].worst);
}

int main(int argc, char **argv)
{
    struct run u;
    if (parse(argc, argv, &u)) return 2;
    struct tally t[N_RASTERS], ts[N_SCENES];
    memset(t, 0, sizeof t);
    memset(ts, 0, sizeof ts);
    static struct explain ex;
    struct sweep_ctx sctx = {.dump = u.dump, .explain = u.explain ? &ex : NULL,
                             .simcheck = u.simcheck};
    struct tally sim_all = {0};
    struct ktally kt[N_SCENES + 1];
    memset(kt, 0, sizeof kt);
    struct conf_tally ct = {0};
    double t0 = clock_mono_s();
    printf("map rms error against the simulator's truth (mean-1 maps, 240 x 240 samples)\n");
    printf("%-11s %-12s %5s %4s %6s | %3s %3s %3s %3s %3s | %7s %7s %7s %7s %7s %5s | %7s | rms "
           "by r = 1..%d\n", "scene", "raster", "flux", "seed", "N", "AIC", "BIC", "CV", "rec",
           "bst", "rmsAIC", "rmsBIC", "rmsRec", "rmsBest", "rmsShr", "c", "Wiener", u.r_max);
    for (size_t ri = 0; ri < N_RASTERS; ri++)
        for (size_t si = 0; si < N_SCENES; si++)
            for (size_t fi = 0; fi < (u.quick ? 1 : N_FLUXES); fi++) {
                struct conf conf = {0};
                for (int seed = u.first_seed; seed < u.first_seed + u.seeds; seed++) {
                    if ((u.raster && (int)ri + 1 != u.raster) ||
                        (u.scene && strcmp(u.scene, scenes[si]) != 0))
                        continue;
                    fid_case_t c = {.scene = scenes[si], .grid = rasters[ri].grid,
                                    .step_um = rasters[ri].step, .area_px = 5,
                                    .flux_scale = fluxes[fi], .seed = (unsigned long)seed,
                                    .noise = u.noise, .rules = u.rules,
                                    .n_rules = u.n_rules,
                                    .on_sweep = u.dump || u.explain || u.simcheck ? on_sweep
                                                                                  : NULL,
                                    .on_sweep_ctx = &sctx, .krige = u.krige};
                    fid_result_t f;
                    err_t err;
                    if (fid_run(&c, u.r_max, &f, &err)) {
                        printf("%-11s %-12s %5.2f %4d  error: %s\n", c.scene, rasters[ri].name,
                               c.flux_scale, seed, err.msg);
                        continue;
                    }
                    print_case(&c, rasters[ri].name, &f, u.r_max);
                    if (u.dump) {
                        fprintf(u.dump, "C %s %zu %g %d", c.scene, ri, c.flux_scale, seed);
                        for (int r = 1; r <= u.r_max; r++) fprintf(u.dump, " %.9g", f.rms[r]);
                        fprintf(u.dump, "\n");
                        fflush(u.dump);
                    }
                    if (u.simcheck) {
                        sim_all.cases++;
                        for (int k = 0; k < N_SIM; k++)
                            score_add(&sim_all.sim[k], ratio(&f, sctx.r_sim[k]));
                    }
                    tally_case(&t[ri], &f, u.n_rules);
                    tally_case(&ts[si], &f, u.n_rules);
                    conf_add(&conf, &f);
                    if (u.krige) {
                        ktally_add(&kt[si], &f);
                        ktally_add(&kt[N_SCENES], &f);
                        if (ratio_kriged(&f) > OK_RATIO)
                            printf("  ^ kriged map %.2fx the best r = %d (rms %.5f)\n",
                                   ratio_kriged(&f), f.r_best, f.rms_kriged);
                    }
                    if (ratio(&f, f.r_rec[0]) > OK_RATIO) {
                        printf("  ^ recommended r = %d is %.2fx the best r = %d\n", f.r_rec[0],
                               ratio(&f, f.r_rec[0]), f.r_best);
                        if (u.explain) explain_print(&ex, &f);
                    }
                }
                char name[48];
                snprintf(name, sizeof name, "%s %s %.1f", scenes[si], rasters[ri].name,
                         fluxes[fi]);
                conf_close(&conf, u.r_max, name, &ct);
            }
    print_summary(t, ts, &ct, &u);
    if (u.krige) {
        printf("\nkriged map (fit/krige.h) against the best r in hindsight: cases within %.1fx, "
               "worst; mean ratio of the kriged and of the shrunk map; cases with the smooth part; "
               "S_err against the truth's fine-cell means (rms z, within 2 sigma); ms mean, max; "
               "the one r nearest the kriged map (the Bayes pick of one grid): within %.1fx, "
               "worst\n",
               OK_RATIO, OK_RATIO);
        for (size_t si = 0; si < N_SCENES; si++) ktally_print(scenes[si], &kt[si]);
        ktally_print("all", &kt[N_SCENES]);
    }
    if (u.simcheck) {
        static const char *const names[N_SIM] = {"down", "up", "down, else up"};
        printf("\nsimulation-based check of the recommended r (cases within %.1fx, worst):\n",
               OK_RATIO);
        for (int k = 0; k < N_SIM; k++)
            printf("  %-14s %4d/%-4d %8.2f\n", names[k], sim_all.sim[k].ok, sim_all.cases,
                   sim_all.sim[k].worst);
    }
    printf("\ntotal %.1f s\n", clock_mono_s() - t0);
    if (u.dump) fclose(u.dump);
    return 0;
}
