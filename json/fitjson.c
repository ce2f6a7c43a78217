/* fitjson.c: JSON encoding of fit results, the `ips fit` output schema (see fitjson.h). */
#include "json/fitjson.h"

#include "json/jdump.h"

#include <errno.h>
#include <math.h>

json_t *fitjson_num(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

json_t *fitjson_array(const double *v, size_t n)
{
    if (!v) return json_null();
    json_t *a = json_array();
    for (size_t k = 0; a && k < n; k++)
        json_array_append_new(a, fitjson_num(v[k]));
    return a;
}

json_t *fitjson_int_or_null(int v)
{
    return v ? json_integer(v) : json_null();
}

static const struct {
    unsigned bit;
    const char *name;
} flag_names[] = {
    {FIT_NO_POINTS, "no_points"},
    {FIT_UNDERDETERMINED, "underdetermined"},
    {FIT_NO_SIGNAL, "no_signal"},
    {FIT_ILL_CONDITIONED, "ill_conditioned"},
    {FIT_UNCONSTRAINED, "unconstrained"},
    {FIT_POOR_FIT, "poor_fit"},
    {FIT_LM_NOT_GLOBAL, "lm_not_global"},
    {FIT_LM_NOT_CONVERGED, "lm_not_converged"},
    {FIT_NONFINITE, "nonfinite_input"},
    {FIT_SATURATED, "saturated"},
};

json_t *fitjson_flags(unsigned flags)
{
    json_t *a = json_array();
    for (size_t i = 0; a && i < sizeof flag_names / sizeof flag_names[0]; i++)
        if (flags & flag_names[i].bit) json_array_append_new(a, json_string(flag_names[i].name));
    return a;
}

/* The counters and cost of one fit, added to its object o. */
static void fit_details(json_t *o, const fit_result_t *f, fit_method_t method)
{
    json_object_set_new(o, "n_used", json_integer((json_int_t)f->n_used));
    json_object_set_new(o, "n_saturated", json_integer((json_int_t)f->n_saturated));
    json_object_set_new(o, "n_nonfinite", json_integer((json_int_t)f->n_nonfinite));
    json_object_set_new(o, "n_unconstrained", json_integer((json_int_t)f->n_unconstrained));
    json_object_set_new(o, "cv_chi2", fitjson_num(f->cv_chi2));
    json_object_set_new(o, "chi2_p", fitjson_num(f->chi2_p));
    /* one per input point, in input order (the used ones, the saturated and the non-finite) */
    json_object_set_new(o, "residuals",
                        fitjson_array(f->resid, f->n_used + f->n_saturated + f->n_nonfinite));
    /* the fitted model M_k + bias (DN) at the same points, comparable with the scan's signal_dn */
    json_object_set_new(o, "model_dn",
                        fitjson_array(f->model_dn, f->n_used + f->n_saturated + f->n_nonfinite));
    if (method != FIT_LINEAR) {
        json_object_set_new(o, "lm_chi2", fitjson_num(f->lm_chi2));
        json_object_set_new(o, "lm_iterations", json_integer(f->lm_iterations));
    }
    json_object_set_new(o, "design",
                        json_pack("{s:I, s:I, s:o, s:I}", "entries", (json_int_t)f->design.entries,
                                  "skipped", (json_int_t)f->design.skipped, "max_skipped_bound",
                                  fitjson_num(f->design.max_skipped_bound), "radial_evals",
                                  (json_int_t)f->design.radial_evals));
    json_object_set_new(o, "timing_ms",
                        json_pack("{s:o, s:o}", "design", fitjson_num(f->design_ms), "solve",
                                  fitjson_num(f->solve_ms)));
}

json_t *fitjson_fit(const fit_result_t *f, fit_method_t method)
{
    size_t m = (size_t)f->r * f->r;
    json_t *o = json_pack("{s:i, s:o, s:i, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:s, s:o}", "r",
                          f->r, "chi2", fitjson_num(f->chi2), "params", f->params, "aic",
                          fitjson_num(f->aic), "bic", fitjson_num(f->bic), "I0", fitjson_num(f->I0),
                          "I0_err", fitjson_num(f->I0_err), "S", fitjson_array(f->S, m), "S_err",
                          fitjson_array(f->S_err, m), "cond", fitjson_num(f->cond), "chi2_red",
                          fitjson_num(f->chi2_red), "status", fit_status_name(f->flags), "flags",
                          fitjson_flags(f->flags));
    if (o) fit_details(o, f, method);
    return o;
}

json_t *fitjson_ftest(const fit_ftest_t *t)
{
    static const struct {
        unsigned bit;
        const char *name;
    } edge_names[] = {{FIT_EDGE_TOP, "top"},
                      {FIT_EDGE_LEFT, "left"},
                      {FIT_EDGE_BOTTOM, "bottom"},
                      {FIT_EDGE_RIGHT, "right"}};
    json_t *edges = json_array();
    for (size_t i = 0; edges && i < sizeof edge_names / sizeof edge_names[0]; i++)
        if (t->edges & edge_names[i].bit)
            json_array_append_new(edges, json_string(edge_names[i].name));
    return json_pack("{s:i, s:o, s:o, s:i, s:o, s:i, s:o, s:o, s:I, s:s, s:o}", "r", t->r, "edges",
                     edges, "chi2_H0", fitjson_num(t->chi2_h0), "params_H0", t->params_h0,
                     "chi2_H1", fitjson_num(t->chi2_h1), "params_H1", t->params_h1, "F",
                     fitjson_num(t->F), "p_value", fitjson_num(t->p_value), "N", (json_int_t)t->n,
                     "status", fit_status_name(t->flags), "flags", fitjson_flags(t->flags));
}

int fitjson_add_region(json_t *root, const fit_region_t *rg, size_t n_raster)
{
    int margin = rg->kind == FIT_REGION_MARGIN;
    json_t *add = json_pack("{s:s, s:o, s:I}", "region", fit_region_name(rg->kind), "margin_um",
                            margin ? fitjson_num(rg->margin_um) : json_null(), "n_raster",
                            (json_int_t)n_raster);
    return add && json_object_update_new(root, add) == 0 ? 0 : -ENOMEM;
}

json_t *fitjson_wiener(const fit_wiener_t *w)
{
    json_t *o = json_pack("{s:i, s:i, s:[o, o], s:o, s:o, s:o, s:o}", "nx", w->nx, "ny", w->ny,
                          "step_um", fitjson_num(w->step_x_um), fitjson_num(w->step_y_um),
                          "x0_um", fitjson_num(w->x0_um), "y0_um", fitjson_num(w->y0_um), "nsr",
                          fitjson_num(w->nsr), "S", fitjson_array(w->S, (size_t)w->nx * w->ny));
    /* additions: how nsr was chosen, which points were deconvolved and whether S is cropped */
    if (o && json_object_update_new(
                 o, json_pack("{s:s, s:s, s:[i, i], s:b, s:o}", "nsr_method",
                              fit_wiener_nsr_name(w->nsr_method), "region", "all", "raster",
                              w->raster_nx, w->raster_ny, "cropped", w->cropped,
                              "signal_fraction", fitjson_num(w->signal_fraction)))) {
        json_decref(o);
        return NULL;
    }
    return o;
}

json_t *fitjson_geometry(const fit_geometry_t *g)
{
    json_t *o = json_pack("{s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o}", "spot_radius_um",
                          fitjson_num(g->R_um), "spot_radius_um_err", fitjson_num(g->R_err_um),
                          "dx_um", fitjson_num(g->dx_um), "dx_um_err", fitjson_num(g->dx_err_um),
                          "dy_um", fitjson_num(g->dy_um), "dy_um_err", fitjson_num(g->dy_err_um),
                          "chi2_fixed", fitjson_num(g->chi2_fixed), "chi2_fitted",
                          fitjson_num(g->chi2_fitted));
    if (!o) return NULL;
    json_object_set_new(o, "r", json_integer(g->r));
    json_object_set_new(o, "model", json_string(g->kriged ? "kriged" : "map"));
    json_object_set_new(o, "kriged_fit",
                        g->kriged ? json_pack("{s:o, s:o, s:o}", "chi2", fitjson_num(g->kriged_chi2),
                                              "chi2_red", fitjson_num(g->kriged_chi2_red), "chi2_p",
                                              fitjson_num(g->kriged_chi2_p))
                        : g->kriged_error[0] ? json_pack("{s:s}", "error", g->kriged_error)
                                             : json_null());
    json_object_set_new(o, "status", json_string(fit_geometry_status(g->flags)));
    json_object_set_new(o, "N", json_integer((json_int_t)g->n_used));
    json_object_set_new(o, "params", json_integer(g->params));
    json_object_set_new(o, "chi2_red", fitjson_num(g->chi2_red));
    json_object_set_new(o, "chi2_p", fitjson_num(g->chi2_p));
    json_object_set_new(o, "bic", fitjson_num(g->bic));
    json_object_set_new(o, "r_from", json_string(g->r_picked ? "data" : "asked"));
    json_object_set_new(o, "r_tried", g->r_picked ? json_pack("[i, i]", g->r_first, g->r_last)
                                                  : json_null());
    json_object_set_new(o, "written_spot_radius_um", fitjson_num(g->R_written_um));
    json_object_set_new(o, "correlation",
                        json_pack("{s:o, s:o, s:o}", "R_dx", fitjson_num(g->corr[0]), "R_dy",
                                  fitjson_num(g->corr[1]), "dx_dy", fitjson_num(g->corr[2])));
    json_object_set_new(o, "iterations", json_integer(g->iterations));
    json_object_set_new(o, "evaluations", json_integer(g->evaluations));
    return o;
}

json_t *fitjson_shrunk(const fit_shrunk_t *s)
{
    if (!s || s->r < 1) return json_null();
    size_t m = (size_t)s->r * s->r;
    return json_pack("{s:i, s:i, s:o, s:o, s:o, s:o, s:o, s:o, s:o}", "r", s->r, "toward_r",
                     s->toward_r, "factor", fitjson_num(s->factor), "detail_rms",
                     fitjson_num(s->detail), "noise_rms", fitjson_num(s->noise), "tau",
                     fitjson_num(s->tau), "S", fitjson_array(s->S, m), "S_err",
                     fitjson_array(s->S_err, m), "S_res", fitjson_array(s->S_res, m));
}

json_t *fitjson_kriged(const fit_kriged_t *k, const char *why_not)
{
    if (!k || k->grid < 1)
        return why_not && why_not[0] ? json_pack("{s:s}", "error", why_not) : json_null();
    size_t m = (size_t)k->grid * k->grid;
    json_t *levels = json_array();
    for (int i = 0; levels && i < k->n_levels; i++)
        json_array_append_new(levels, json_pack("{s:i, s:o}", "q", k->level_q[i], "sd",
                                                fitjson_num(k->level_sd[i])));
    json_t *o = json_pack("{s:i, s:i, s:b, s:o, s:o, s:o, s:o, s:o, s:i, s:o, s:o}", "grid", k->grid,
                     "r", k->r, "smooth", k->smooth, "likelihood_ratio", fitjson_num(k->lr),
                     "amplitude", fitjson_num(k->amplitude), "length_um",
                     fitjson_num(k->length_um), "levels", levels, "log_likelihood",
                     fitjson_num(k->log_lik), "evaluations", k->evaluations, "S",
                     fitjson_array(k->S, m), "S_err", fitjson_array(k->S_err, m));
    if (o && k->mix_n > 0) {
        json_t *pri = json_array();
        for (int i = 0; pri && i < k->mix_n; i++)
            json_array_append_new(pri, json_pack("{s:i, s:o, s:o, s:o, s:o}", "r", k->mix_r[i],
                                                 "map_err", fitjson_num(k->mix_map_err[i]), "spread",
                                                 fitjson_num(k->mix_spread[i]), "log_likelihood",
                                                 fitjson_num(k->mix_log_lik[i]), "weight",
                                                 fitjson_num(k->mix_weight[i])));
        json_object_set_new(o, "mixture", json_pack("{s:o, s:o}", "expected_err",
                                                    fitjson_num(k->mix_err), "priors", pri));
    }
    return o;
}

json_t *fitjson_sweep(const fit_sweep_t *sw, size_t n_points, const fit_options_t *opts,
                      double full_scale_dn)
{
    static const char *const methods[] = {"linear", "lm", "both"};
    json_t *fits = json_array();
    for (int r = sw->r_min; fits && r <= sw->r_max; r++)
        json_array_append_new(fits, fitjson_fit(&sw->fits[r - sw->r_min], opts->method));
    json_t *root = json_pack("{s:I, s:I, s:s, s:s, s:b, s:o, s:o, s:o, s:{s:o, s:o}, s:o, s:s, s:b}",
                     "N", (json_int_t)sw->fits[0].n_used, "n_points", (json_int_t)n_points,
                     "sigma", fit_noise_name(opts->noise), "method", methods[opts->method],
                     "nonneg", opts->nonneg, "design_tol", fitjson_num(opts->design_tol),
                     "full_scale_dn", fitjson_num(full_scale_dn), "fits", fits, "best_r", "aic",
                     fitjson_int_or_null(sw->best_aic), "bic", fitjson_int_or_null(sw->best_bic),
                     "recommended_r", fitjson_int_or_null(sw->recommended_r),
                     "recommended_reason", sw->recommended_reason, "range_edge", sw->range_edge);
    if (root) json_object_set_new(root, "shrunk_map", fitjson_shrunk(sw->shrunk));
    return root;
}

int fitjson_print(const json_t *root, FILE *f)
{
    /* json_dumpf(root, f, JSON_INDENT(2) | JSON_REAL_PRECISION(17))'s text, faster (jdump.h) */
    if (jdump_file(root, f, 2) || fputc('\n', f) == EOF ||
        fflush(f) == EOF)
        return -EIO;
    return 0;
}
