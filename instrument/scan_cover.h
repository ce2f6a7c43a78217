/* scan_cover.h: which pixels of a scan's sub-frame its raster covers well enough to be fitted
 * ("every pixel a scan covers"), decided by the raster alone.
 *
 * The rule (docs/instrument.md, "Which pixels a raster covers"): sub-frame pixel (dcol, drow) is
 * covered when
 *   1. the raster's spot positions reach each of the pixel's four edges to within half a raster
 *      step (min x <= step/2, max x >= pitch - step/2 in the pixel's frame, the same in y), so the
 *      positions strictly inside the pixel sample it edge to edge at the raster's resolution, and
 *   2. at least SCAN_COVER_MIN_INSIDE positions lie strictly inside the pixel (the points the
 *      paper's fit takes: with fewer not even an r = 2 map has as many points as unknowns).
 * No margin of a spot radius beyond the pixel is asked for: the paper's 5 x 5-pixel raster ends on
 * the outer pixels' edges, and the paper fits those pixels from the points inside them. So the
 * paper's raster (5 x 5 pixels, 0.6 um steps on 6 um pixels) covers exactly its 25 pixels, each
 * with 9 x 9 = 81 positions inside; the rest of a 9 x 9 sub-frame is "not_covered". */
#ifndef IPSD_INSTRUMENT_SCAN_COVER_H
#define IPSD_INSTRUMENT_SCAN_COVER_H

#include <stddef.h>

#include "instrument/scan.h"

#define SCAN_COVER_MIN_INSIDE 4

typedef struct scan_cover {
    int covered;     /* 1: fit it; 0: status "not_covered" with reason */
    size_t n_inside; /* raster positions strictly inside the pixel */
    double x_min_um, x_max_um, y_min_um, y_max_um; /* the raster's extent in the pixel's frame */
    char reason[200];                              /* why not covered ("" when covered) */
} scan_cover_t;

/* The coverage of sub-frame pixel (dcol, drow) by the n stage positions (sx, sy) of a raster of
 * step step_um with setup su (positions relative to the pixel by scan_pixel_coords). */
void scan_pixel_cover(const scan_setup_t *su, int dcol, int drow, double step_um, const double *sx,
                      const double *sy, size_t n, scan_cover_t *out);

#endif
