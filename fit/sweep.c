/* sweep.c: model selection, the fits for a range of r and the best r by AIC and by BIC
 * (section IV: AIC = N ln(chi2/N) + 2p, BIC = N ln(chi2/N) + p ln N). */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "fit/model.h"

int fit_sweep_run(const fit_scan_t *scan, int r_min, int r_max, const fit_options_t *opts,
                  fit_sweep_t *out, err_t *err)
{
    out->fits = NULL;
    out->best_aic = out->best_bic = 0;
    out->r_min = r_min;
    out->r_max = r_max;
    if (r_min < 1 || r_max > 32 || r_min > r_max)
        return err_set(err, -EINVAL, "r range must satisfy 1 <= r-min <= r-max <= 32 (got %d..%d)",
                       r_min, r_max);
    out->fits = calloc((size_t)(r_max - r_min + 1), sizeof *out->fits);
    if (!out->fits) return err_set(err, -ENOMEM, "out of memory");
    double best_aic = INFINITY, best_bic = INFINITY;
    for (int r = r_min; r <= r_max; r++) {
        fit_result_t *f = &out->fits[r - r_min];
        int rc = fit_map(scan, r, opts, f, err);
        if (rc) {
            fit_sweep_free(out);
            return rc;
        }
        if (!f->S) continue; /* no map: not a candidate */
        if (f->aic < best_aic) best_aic = f->aic, out->best_aic = r;
        if (f->bic < best_bic) best_bic = f->bic, out->best_bic = r;
    }
    return 0;
}

void fit_sweep_free(fit_sweep_t *sw)
{
    if (!sw || !sw->fits) return;
    for (int r = sw->r_min; r <= sw->r_max; r++) fit_result_free(&sw->fits[r - sw->r_min]);
    free(sw->fits);
    sw->fits = NULL;
}
