/* fit_table.c: `ips fit --table`, the report a person reads (the JSON is for programs). */
#include "fit_table.h"

#include <math.h>

#include "fit/krige.h"
#include "fit/shrink.h"

/* Grids finer than this print as the shaded picture only (a row of numbers would not fit). */
#define NUMBERS_MAX_R 16

/* A map as rows of numbers (S +- S_err) next to a shaded picture (darker = less sensitive). */
static void print_map(FILE *f, const double *S, const double *err, int r)
{
    static const char *shade[] = {"\u2588\u2588", "\u2593\u2593", "\u2592\u2592", "\u2591\u2591",
                                  "  "};
    double lo = INFINITY, hi = -INFINITY;
    for (int c = 0; c < r * r; c++) lo = fmin(lo, S[c]), hi = fmax(hi, S[c]);
    for (int j = 0; j < r; j++) {
        fprintf(f, "    ");
        for (int i = 0; i < r && r <= NUMBERS_MAX_R; i++) fprintf(f, " %6.3f", S[j * r + i]);
        if (r <= NUMBERS_MAX_R) fprintf(f, "    ");
        for (int i = 0; i < r; i++) {
            double t = hi > lo ? (S[j * r + i] - lo) / (hi - lo) : 1;
            fprintf(f, "%s", shade[(int)fmin(4, floor(t * 5))]);
        }
        if (err) {
            double e = 0;
            for (int i = 0; i < r; i++) e = fmax(e, err[j * r + i]);
            fprintf(f, "   (max 1-sigma %.3f)", e);
        }
        fprintf(f, "\n");
    }
    fprintf(f, "    shading: %.3f (dark) .. %.3f (light); row 0 is the top edge\n", lo, hi);
}

static void print_sweep(FILE *f, const fit_sweep_t *sw)
{
    fprintf(f, "   r  params        chi2   chi2/dof         AIC         BIC   LOO chi2/N        cond"
               "  status\n");
    for (int r = sw->r_min; r <= sw->r_max; r++) {
        const fit_result_t *x = &sw->fits[r - sw->r_min];
        fprintf(f, "  %2d  %6d  %10.4g  %9.4g  %10.3f%s %10.3f%s  %10.4g%s  %10.3g  %s\n", r,
                x->params, x->chi2, x->chi2_red, x->aic, r == sw->best_aic ? "*" : " ", x->bic,
                r == sw->best_bic ? "*" : " ", x->cv_chi2 / (double)x->n_used,
                r == sw->recommended_r ? "<" : " ", x->cond, fit_status_name(x->flags));
    }
    fprintf(f, "  (* best by AIC / BIC; < recommended)\n");
    if (sw->recommended_reason[0]) fprintf(f, "  recommended %s\n", sw->recommended_reason);
    if (sw->range_edge)
        fprintf(f, "  note: AIC or BIC picked the largest r the sweep or the points allow\n");
}

/* The geometry fitted before the sweep (geometry.h), which every map below uses. */
static void print_geometry(FILE *f, const fit_geometry_t *g)
{
    fprintf(f, "\nGeometry (fitted first; the maps below use it): %s, r = %d (%s), %s\n",
            g->kriged ? "refined under the kriged model" : "the r x r map's", g->r,
            g->r_picked ? "picked from the data" : "asked", fit_geometry_status(g->flags));
    fprintf(f, "  spot radius %.4f +- %.4f um (written %.4f); offset dx %+.4f +- %.4f um, "
               "dy %+.4f +- %.4f um\n", g->R_um, g->R_err_um, g->R_written_um, g->dx_um,
            g->dx_err_um, g->dy_um, g->dy_err_um);
    if (g->kriged)
        fprintf(f, "  kriged model's chi2/(N - 1) = %.3f (p = %.3g); the r x r map's chi2/dof = "
                   "%.3f\n", g->kriged_chi2_red, g->kriged_chi2_p, g->chi2_red);
    else
        fprintf(f, "  chi2/dof = %.3f (p = %.3g); chi2 %.6g at the written geometry, %.6g fitted\n",
                g->chi2_red, g->chi2_p, g->chi2_fixed, g->chi2_fitted);
}

void fit_table_print(FILE *f, const char *path, const fit_scan_t *scan, const fit_sweep_t *sw,
                     const fit_geometry_t *geometry, const fit_ftest_t *ftest, const fit_wiener_t *wiener,
                     const char *kriged_error, double total_ms)
{
    const fit_result_t *first = &sw->fits[0];
    fprintf(f, "%s: %zu points (%zu used), pitch %g um, spot radius %g um, %d frames\n", path,
            scan->n, first->n_used, scan->pitch_um, scan->spot_radius_um, scan->frames);
    if (geometry) print_geometry(f, geometry);
    fprintf(f, "\nModel selection (weighted chi-square, eq. 4; AIC/BIC with p = r*r + 1)\n");
    print_sweep(f, sw);
    int best = sw->recommended_r;
    if (best) {
        const fit_result_t *b = &sw->fits[best - sw->r_min];
        fprintf(f, "\nIPS map, r = %d (recommended), mean 1; I0 = %.6g +- %.2g DN/um^2\n", best,
                b->I0, b->I0_err);
        print_map(f, b->S, b->S_err, best);
    } else {
        fprintf(f, "\nNo fit produced a map.\n");
    }
    const fit_shrunk_t *sh = sw->shrunk;
    if (sh) {
        fprintf(f, "\nShrunk map, r = %d: the detail over r = %d kept where it stands above the "
                   "noise (%.0f %% kept; detail rms %.3g, its noise %.3g), mean 1\n", sh->r,
                sh->toward_r, 100 * sh->factor, sh->detail, sh->noise);
        print_map(f, sh->S, sh->S_err, sh->r);
        double v = 0;
        for (int j = 0; j < sh->r * sh->r; j++) v += sh->S_res[j] * sh->S_res[j];
        fprintf(f, "Resolution error of r = %d's sub-pixel values (structure finer than the grid, "
                   "fit/shrink.h): S_res rms %.3g; add it in quadrature to S_err\n",
                sh->r, sqrt(v / (sh->r * sh->r)));
    }
    const fit_kriged_t *kr = sw->kriged;
    if (kr) {
        fprintf(f, "\nKriged map, %d x %d (fit/krige.h: a Gaussian process with r = %d's grids in "
                   "its prior; ", kr->grid, kr->grid, kr->r);
        if (kr->smooth)
            fprintf(f, "smooth part kept, likelihood ratio %.1f, amplitude %.3g, length %.3g um",
                    kr->lr, kr->amplitude, kr->length_um);
        else
            fprintf(f, "no smooth part, likelihood ratio %.1f < %.2f", kr->lr, FIT_KRIGE_LR);
        fprintf(f, "; %.0f ms), mean 1%s\n", kr->ms,
                kr->grid > NUMBERS_MAX_R ? ", as a picture (the numbers: the JSON's kriged_map)"
                                         : "");
        print_map(f, kr->S, kr->S_err, kr->grid);
    } else if (kriged_error) {
        fprintf(f, "\nNo kriged map: %s\n", kriged_error);
    }
    if (ftest) {
        fprintf(f, "\nF-test at r = %d: H0 (edge sub-pixels free, the rest one S0) p0 = %d, "
                   "H1 p1 = %d\n", ftest->r, ftest->params_h0, ftest->params_h1);
        fprintf(f, "  chi2_H0 = %.6g  chi2_H1 = %.6g  F = %.4f  p = %.3g  -> %s\n",
                ftest->chi2_h0, ftest->chi2_h1, ftest->F, ftest->p_value,
                ftest->p_value < 0.05 ? "the structure in the centre is significant"
                                      : "no significant structure in the centre");
    }
    if (wiener) {
        fprintf(f, "\nWiener deconvolution baseline on the %d x %d scan grid (nsr %.3g):\n",
                wiener->nx, wiener->ny, wiener->nsr);
        if (wiener->nx == wiener->ny) print_map(f, wiener->S, NULL, wiener->nx);
    }
    fprintf(f, "\nTotal time %.2f ms\n", total_ms);
}
