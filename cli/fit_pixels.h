/* fit_pixels.h: `ips fit FILE --pixels all`: every pixel of a scan file's sub-frame
 * (instrument/scanfile.h `subframe`) that its raster covers (the server's rule,
 * instrument/scan_cover.h through instrument/scanfile_sub.h), each fitted by the caller's fit of
 * one pixel (the document `ips fit` prints for that pixel's own scan file), gathered into one
 * JSON document (docs/contracts.md): sub_px, step_um, n_raster, covered, not_covered, fitted,
 * failed, pixels[] {dcol, drow, status fitted | failed | not_covered, n_inside, reason, fit},
 * timing_ms {fit, total}. */
#ifndef IPSD_CLI_FIT_PIXELS_H
#define IPSD_CLI_FIT_PIXELS_H

#include <jansson.h>

#include "base/err.h"
#include "instrument/scanfile.h"

/* Fits one pixel's scan: 0 with *doc (owned by the caller), -ENOMEM (the run stops) or another
 * negative errno with err (that pixel "failed", with err's message as its reason). */
typedef int (*fit_pixels_fn)(const fit_scan_t *scan, void *user, json_t **doc, err_t *err);

/* The document of every pixel of sf's sub-frame, row by row from the top left. sf must have a
 * subframe. Returns 0 with *out (the caller's), or -ENOMEM. */
int fit_pixels_run(const scanfile_t *sf, fit_pixels_fn fit, void *user, json_t **out,
                   err_t *err);

#endif
