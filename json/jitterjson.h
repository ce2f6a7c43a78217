/* jitterjson.h: the JSON document of a jitter-photometry prediction (fit/jitter.h), the output of
 * `ips jitter` and the reply of POST /api/jitter (docs/contracts.md, docs/api.md), so both give
 * the same document for the same input. Thread-safe; the document is returned new. */
#ifndef IPSD_JSON_JITTERJSON_H
#define IPSD_JSON_JITTERJSON_H

#include <jansson.h>
#include <stddef.h>

#include "base/err.h"
#include "fit/jitter.h"

/* "airy" / "gauss" of a PSF kind, and back (-EINVAL naming the word). */
const char *jitterjson_psf_name(fit_psf_kind_t kind);
int jitterjson_psf_parse(const char *name, fit_psf_kind_t *kind, err_t *err);

/* Runs fit_jitter_run over the series (dx[k], dy[k]), k < n, corrects measured (n values, NULL:
 * none) and builds the document:
 *   {"psf": {"kind", "width_um"}, "pitch_um", "position_um": {"x", "y"},
 *    "pixels": [{"dcol", "drow", "r"}] (r null: flat), "n", "rho0", "flux0", "flat0",
 *    "err_mean", "err_rms", "err_max", "rho_mean", "rho_scatter", "flat_scatter",
 *    "samples": [{"dx_um", "dy_um", "rho", "rel_err"[, "measured", "corrected"]}]}
 * with "samples" only when with_samples (or measured) is set. *out gets the document. Returns 0
 * or the error of fit_jitter_run / fit_jitter_correct, -ENOMEM. */
int jitterjson_run(const fit_jitter_setup_t *s, const double *dx, const double *dy, size_t n,
                   const double *measured, int with_samples, json_t **out, err_t *err);

#endif
