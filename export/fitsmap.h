/* fitsmap.h: IPS maps as a FITS file (cfitsio, written in memory), in the conventions of the
 * pixel-response (PRF) files photometry pipelines read (Kepler/TESS-style): one image HDU per
 * map with its oversampling and a linear world coordinate system for where each sample sits.
 *
 * Layout (docs/api.md, "FITS"): a primary HDU without data holding what the file shares (ORIGIN,
 * CREATOR, DATE, NMAPS, sensor and pitch), then per map two IMAGE extensions of r x r doubles,
 * EXTNAME 'S' (the sensitivity, mean 1) and 'S_ERR' (its 1-sigma), both with EXTVER = the map's
 * number 1..n, so astropy reads map k as hdul['S', k] and hdul['S_ERR', k]; after all the pairs,
 * an extension 'S_RES' (EXTVER k) for each map whose resolution error is known (the primary's
 * NRESMAPS counts them), so the pairs sit where they did before it existed. The data are the
 * stored arrays as they are: FITS axis 1 is x (sub-pixel column i), axis 2 is y (row j, row 0 at
 * the pixel's top edge, y downward as in docs/contracts.md), so data[j][i] = S[j*r + i].
 *
 * Sampling (FITS WCS Paper I, linear axes): the primary WCS gives micrometres inside the pixel,
 * CTYPEn 'PIXX'/'PIXY', CUNITn 'um', CRPIXn 0.5, CRVALn 0, CDELTn pitch / r: the outer edge of the
 * first sample (FITS pixel 0.5) is the pixel's corner, sample i covers [i, i+1] pitch / r. The
 * alternate WCS 'P' gives sensor pixel coordinates as Kepler's PRF files do (CRVALnP the pixel's
 * column / row, CDELTnP 1 / r, CUNITnP 'pixel'); OVERSAMP = r is the samples per pixel side.
 * Every map's header also carries its provenance and optics (fitsmap_t below). Thread-safe when
 * cfitsio is reentrant (Debian's is). */
#ifndef IPSD_EXPORT_FITSMAP_H
#define IPSD_EXPORT_FITSMAP_H

#include <stddef.h>
#include <stdint.h>

#include "base/err.h"

/* One map and what its header says; every pointer borrowed, strings NULL when unknown, numbers
 * NaN when unknown (the keyword is then left out), ids 0 when none. */
typedef struct fitsmap {
    int r;                    /* the map is r x r, 1..256 */
    const double *S, *S_err;  /* r*r each, row-major y then x: S[j*r + i] */
    const double *S_res;      /* r*r or NULL (not known): the resolution error (fit/shrink.h),
                                 written as extension ('S_RES', k) after every map's pair */
    double pitch_um;          /* pixel pitch (PITCH); sub-pixel size SUBPIX = pitch / r */
    int pixel_col, pixel_row; /* sensor pixel (PIXCOL, PIXROW) */
    double wavelength_um, na, spot_radius_um; /* optics of the scan (WAVELEN, NA, SPOTRAD) */
    double I0, chi2_red;          /* the fit's I0 (DN per unit-peak Airy flux) and reduced chi2 */
    const char *status;           /* fit status word (FITSTAT) */
    const char *noise_model;      /* NOISEMOD */
    const char *software_version; /* SWVERS: the ipsd that fitted the map */
    int64_t calib_id, sensor_id, scan_id, fit_id; /* CALIBID, SENSORID, SCANID, FITID */
    int64_t created_ms;      /* when the calibration was stored (CALDATE, CAL_MS); 0: unknown */
    int current;             /* 1: the pixel's current calibration; -1: unknown */
    const char *by, *reason; /* who made it the calibration, and why (CALBY, REASON) */
    const char *map; /* which map of its fit (IPSMAP): "recommended", "shrunk" or "kriged" */
} fitsmap_t;

/* What the primary header says of the whole file (strings may be NULL). */
typedef struct fitsmap_file {
    const char *creator; /* CREATOR, e.g. "ipsd 0.1.0" */
    int64_t sensor_id;   /* 0: not one sensor's file */
    const char *sensor_model, *sensor_serial;
    double pitch_um; /* NaN: maps of different pitches */
    int64_t date_ms; /* DATE of the file (ms since the epoch); 0: left out */
} fitsmap_file_t;

/* Writes maps[0..n) (n >= 1) as one FITS file into *buf (malloc'd, the caller frees) of *len
 * bytes (a multiple of 2880). Returns 0, -EINVAL naming a bad map (r outside 1..256, a NULL
 * array, a pitch <= 0), -ENOMEM, or -EIO with cfitsio's message. */
int fitsmap_write(const fitsmap_file_t *file, const fitsmap_t *maps, size_t n, void **buf,
                  size_t *len, err_t *err);

#endif
