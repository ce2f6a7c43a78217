/* region.h: which spot positions of a raster a fit uses. The paper fits only the points whose
 * spot centre lies inside the pixel (its 9 x 9 inside the 6 um pixel); the model (design.h
 * integrates the Airy spot over every sub-pixel wherever the spot is) is just as valid for spots
 * outside, which see the pixel through the spot's wings and carry information on its edges.
 *   inside      the spot centre strictly inside the pixel (0, pitch)^2 (the paper's choice and
 *               the default; the same test as scan_pixel_coords of instrument/scan.h)
 *   all         every point of the raster
 *   margin UM   the spot centre within UM micrometres of the pixel: [-UM, pitch + UM]^2
 * Positions are compared with a tolerance of 1e-6 pitch, so a raster node on a pixel edge is
 * outside for `inside` and inside for `margin 0`. A point with a non-finite position is always
 * kept: the fit counts and leaves out non-finite input itself (model.h).
 * The one place ipsd selects points by region: `ips fit`, ipsd's fit jobs and the fidelity
 * harness all call fit_region_select. Pure, thread-safe. */
#ifndef IPSD_FIT_REGION_H
#define IPSD_FIT_REGION_H

#include "base/err.h"
#include "fit/scandata.h"

typedef enum fit_region_kind {
    FIT_REGION_INSIDE = 0,
    FIT_REGION_ALL = 1,
    FIT_REGION_MARGIN = 2,
} fit_region_kind_t;

#define FIT_REGION_MARGIN_MAX 1000.0 /* um: far beyond any raster's reach */

typedef struct fit_region {
    fit_region_kind_t kind;
    double margin_um; /* FIT_REGION_MARGIN only: 0..FIT_REGION_MARGIN_MAX */
} fit_region_t;

/* "inside", "all" or "margin" (static string). */
const char *fit_region_name(fit_region_kind_t kind);

/* The region named name ("inside", "all", "margin") with margin_um (read only for "margin":
 * finite, 0..FIT_REGION_MARGIN_MAX). Returns 0 or -EINVAL with err naming what is wrong. */
int fit_region_parse(const char *name, double margin_um, fit_region_t *out, err_t *err);

/* 1 when a spot centred at (x, y) um belongs to region rg of a pixel of pitch pitch_um. */
int fit_region_contains(const fit_region_t *rg, double pitch_um, double x_um, double y_um);

/* The points of a scan in a region: a scan (same constants) with owned copies of the arrays. */
typedef struct fit_scan_sel {
    fit_scan_t scan; /* its arrays point into x, y, s */
    double *x, *y, *s;
} fit_scan_sel_t;

/* Copies the points of in that belong to rg (rg NULL: inside), in their input order, into *out
 * (release with fit_scan_sel_free, also after a failure). Returns 0, -EINVAL (bad region or no
 * scan) or -ENOMEM. The selection may be empty; the fit says so. */
int fit_region_select(const fit_scan_t *in, const fit_region_t *rg, fit_scan_sel_t *out,
                      err_t *err);

void fit_scan_sel_free(fit_scan_sel_t *sel);

#endif
