/* srv_fit.h: one fit as ipsd runs it: the fit pipeline of fit/pipeline.h (the model-selection
 * sweep over r, optionally the F-test of an edge model and the Wiener baseline; the same call
 * `ips fit` makes), encoded as the `ips fit` JSON document (json/fitjson.h) so that the stored
 * fits.result reads like the command-line tool's output, plus the map that becomes the
 * calibration (the kriged map, fit/krige.h, unless the params ask for the recommended map,
 * fit/recommend.h, or the shrunk one). Pure computation, thread-safe. */
#ifndef IPSD_SERVER_SRV_FIT_H
#define IPSD_SERVER_SRV_FIT_H

#include <jansson.h>
#include <stdatomic.h>

#include "base/err.h"
#include "fit/model.h" /* fit_scan_t */
#include "server/srv_params.h"

typedef struct srv_fit_out {
    json_t *result;          /* the `ips fit` document (owned) */
    int best_aic, best_bic;  /* 0: none */
    double f_value, p_value; /* NaN without an F-test */
    /* the recommended map, when there is one (r = 0: none), or the shrunk or kriged map when
     * the params asked for it and the sweep has one (map; r is then the kriged map's grid) */
    int r;
    storage_map_t map;
    double *S, *S_err; /* r*r each (owned) */
    double *S_res;     /* r*r (owned), or NULL: the map's resolution error (fit/shrink.h) */
    double I0, chi2_red;
    const char *status; /* static status word of that fit */
    /* "" or one sentence on why the map is not the one the params asked for (the document's
     * stored_map.why; the calibration's map_note) */
    char map_note[400];
} srv_fit_out_t;

/* How a running fit is watched (mapped onto the pipeline's fit_watch_t): stop (may be NULL) is
 * read before every step (each r, the F-test, Wiener), progress (may be NULL) is told the fraction
 * of the steps done after each. */
typedef struct srv_fit_hooks {
    const atomic_int *stop; /* read before each step and inside the fit's long loops */
    int (*poll)(void *user); /* also inside those loops (a test hook; may be NULL): nonzero stops */
    void (*progress)(double fraction, void *user);
    void *user;
    /* optional: poll's place-aware form, for the polls at a named place (fit/stop.h's sites) */
    int (*poll_at)(void *user, const char *site);
} srv_fit_hooks_t;

/* Fits scan as p asks (r range, options, F-test, Wiener). A failing F-test or Wiener baseline
 * (too few points, no regular grid) does not fail the fit: the document holds
 * {"error": "..."} in its place. Returns 0, -ECANCELED (stopped), -EINVAL (bad scan or options)
 * or -ENOMEM; *out is released with srv_fit_out_free (also after an error). */
int srv_fit_run(const fit_scan_t *scan, const srv_fit_params_t *p, const srv_fit_hooks_t *hooks,
                srv_fit_out_t *out, err_t *err);

void srv_fit_out_free(srv_fit_out_t *o);

#endif
