/* scan_cube.h: one pixel's scan file cut out of a scan cube: the mean sub-frame at each spot
 * position, with the positions relative to the pixel of interest (POI), as a lab's acquisition
 * software records a raster (the FITS layout of docs/contracts.md, read by export/fitsscan.h).
 * The same cut as scan_extract_pixel (scan.h) makes of a raster of ipsd's own: positions
 * relative to the chosen pixel's corner, by default only those strictly inside it. */
#ifndef IPSD_INSTRUMENT_SCAN_CUBE_H
#define IPSD_INSTRUMENT_SCAN_CUBE_H

#include <stddef.h>

#include "base/err.h"
#include "instrument/scanfile.h"

/* A cube of n sub-frames of ncol x nrow pixels; every pointer borrowed. */
typedef struct scan_cube {
    int ncol, nrow;       /* sub-frame columns (x, rightward) and rows (y, downward) */
    size_t n;             /* spot positions */
    int poi_col, poi_row; /* the POI, 0-based in the sub-frame */
    const double *mean_dn;      /* n*nrow*ncol: position k, row j, column i at (k*nrow+j)*ncol+i */
    const double *x_um, *y_um;  /* n: spot centres relative to the POI's top-left corner */
    double pitch_um, spot_radius_um, bias_dn, gain_e_per_dn, read_noise_e, full_scale_dn;
    int frames; /* frames averaged per position */
} scan_cube_t;

/* The scan file of sub-frame pixel (dcol, drow) relative to the POI (columns right, rows down):
 * positions x - dcol pitch, y - drow pitch (exactly the cube's for the POI), the pixel's means,
 * and the cube's constants; only the positions strictly inside the pixel (scan_pixel_coords of
 * scan.h) unless all. *out is the caller's (scanfile_free). Returns 0, -EINVAL (the pixel is
 * outside the cube, or a constant is out of its range) or -ENOMEM. */
int scan_cube_pixel(const scan_cube_t *cube, int dcol, int drow, int all, scanfile_t *out,
                    err_t *err);

#endif
