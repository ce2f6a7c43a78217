/* sweep.c: model selection, the fits for a range of r and the best r by AIC and by BIC: the fit
 * pipeline (pipeline.c, where the one sweep loop is) asked for the sweep only, over every point
 * given (region all: a caller that wants a region selects it first, fit/region.h). */
#include <stdlib.h>

#include "fit/model.h"
#include "fit/pipeline.h"
#include "fit/krige.h"
#include "fit/shrink.h"

int fit_sweep_run(const fit_scan_t *scan, int r_min, int r_max, const fit_options_t *opts,
                  fit_sweep_t *out, err_t *err)
{
    fit_pipeline_opts_t po = fit_pipeline_opts_default();
    po.r_min = r_min;
    po.r_max = r_max;
    po.region.kind = FIT_REGION_ALL; /* the caller chose the points (fit_region_select) */
    if (opts) po.fit = *opts;
    fit_pipeline_t pl;
    int rc = fit_pipeline_run(scan, &po, NULL, &pl, err);
    *out = (fit_sweep_t){.r_min = r_min, .r_max = r_max};
    if (rc == 0) *out = pl.sweep; /* the fits move to out; the pipeline holds nothing else */
    return rc;
}

void fit_sweep_free(fit_sweep_t *sw)
{
    if (!sw) return;
    fit_shrunk_free(sw->shrunk);
    free(sw->shrunk);
    sw->shrunk = NULL;
    fit_kriged_free(sw->kriged);
    free(sw->kriged);
    sw->kriged = NULL;
    if (!sw->fits) return;
    for (int r = sw->r_min; r <= sw->r_max; r++) fit_result_free(&sw->fits[r - sw->r_min]);
    free(sw->fits);
    sw->fits = NULL;
}
