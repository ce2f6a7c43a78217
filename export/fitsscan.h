/* fitsscan.h: a spot scan read from a FITS file (cfitsio, from memory): the cube a lab's
 * acquisition software writes, one mean sub-frame per spot position, with the positions in a
 * binary table and the sensor constants of the scan file in the primary header. The reader of
 * `ips import-fits`; the layout is the scan-cube contract of docs/contracts.md ("FITS scan cube"):
 *
 *   primary HDU: an image, NAXIS = 3, NAXIS1 x NAXIS2 x NAXIS3 = sub-frame columns x rows x
 *     points; plane k (FITS axis 3 index k + 1) is the mean of NCOMBINE frames at position k, in
 *     DN with the bias included (any BITPIX; BSCALE / BZERO applied; NaN or BLANK: non-finite).
 *     FITS axis 1 is the sensor column (x, rightward), axis 2 the row (y, downward).
 *     Keywords: PITCH [um], SPOTRAD [um], BIAS [DN], GAIN [e-/DN], RDNOISE [e-], NCOMBINE
 *     (frames per point), POICOL, POIROW (the pixel of interest as 1-based FITS pixel numbers
 *     along axes 1 and 2); optional SATURATE [DN] (the ADC full scale, default 16383) and
 *     EXPTIME [s].
 *   extension EXTNAME = 'POSITIONS': a binary table of NAXIS3 rows, row k the spot centre of
 *     plane k: X_UM, Y_UM [um] relative to the POI's top-left corner (the scan file's frame,
 *     y downward); optional NCOMBINE and EXPTIME per row, which must then be the same in every
 *     row (a scan file has one frame count, and the fit one exposure).
 *
 * This room knows nothing of scan files (it depends on base/ only): it hands back plain arrays,
 * and instrument/scan_cube.h cuts a pixel's scan file out of them. Thread-safe when cfitsio is
 * reentrant (Debian's is). */
#ifndef IPSD_EXPORT_FITSSCAN_H
#define IPSD_EXPORT_FITSSCAN_H

#include <stddef.h>

#include "base/err.h"

typedef struct fitsscan {
    int ncol, nrow;          /* sub-frame size: NAXIS1, NAXIS2 */
    size_t n;                /* spot positions: NAXIS3 = the table's rows */
    int poi_col, poi_row;    /* the POI, 0-based in the sub-frame (POICOL - 1, POIROW - 1) */
    double *mean_dn;         /* n * nrow * ncol: plane k, row j, column i at (k*nrow + j)*ncol + i */
    double *x_um, *y_um;     /* n each: spot centres relative to the POI's corner */
    double pitch_um, spot_radius_um, bias_dn, gain_e_per_dn, read_noise_e;
    double full_scale_dn;    /* SATURATE, or 16383 when absent */
    int frames;              /* NCOMBINE */
    double exptime_s;        /* EXPTIME (header or the table's), NaN when not given */
} fitsscan_t;

/* Reads the scan cube of len bytes at buf into *out (owned arrays: fitsscan_free). On error *out
 * is zeroed and err names what is wrong in one line (the keyword, the axis, the column, the
 * row). Returns 0, -EINVAL (not FITS, or not the layout above: also SIMPLE = F, a BSCALE,
 * BZERO, TSCALn or TZEROn that is not a finite number, a table whose columns do not fill its
 * NAXIS1 exactly), or -ENOMEM. */
int fitsscan_read(const void *buf, size_t len, fitsscan_t *out, err_t *err);

/* The same, refusing with -E2BIG a cube of more than max_points points (NAXIS3) before anything
 * is allocated: a small file can claim a million points of one byte each. */
int fitsscan_read_capped(const void *buf, size_t len, size_t max_points, fitsscan_t *out,
                         err_t *err);

/* Releases what *s owns and zeroes it; accepts NULL and a zeroed struct. */
void fitsscan_free(fitsscan_t *s);

#endif
