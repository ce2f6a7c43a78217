/* scan_limits.h: a scan's defaults and limits, defined once. Every interface that takes a scan
 * (the HTTP API, `ips simulate`, scan.h's scan_config_check, the storage checks, the served
 * OpenAPI document and through it the dashboard's form) reads them from here.
 *
 * The constants are plain macros so that storage/ (which links no instrument code) can use them
 * from this header alone; scan_fields[] is the same numbers as a table that code can iterate
 * (scan_limits.c). Why the limits are what they are: docs/instrument.md, "A scan's limits".
 *
 * Combined rules (beyond each field's own range):
 *   - a raster point holds frames x sub_px^2 samples: at most SCAN_MAX_POINT_SAMPLES;
 *   - points per axis nx = area_px * pitch / step_um + 1 must be a whole number (to 1e-6), and
 *     nx^2 <= SCAN_MAX_POINTS;
 *   - the spot radius from eq. 1 (fit/airy.h) must be finite and > 0, and the NA solved from a
 *     given radius within the NA's range;
 *   - a direct grid inside the POI (scan_grid_pixel) must fit strictly inside it. */
#ifndef IPSD_INSTRUMENT_SCAN_LIMITS_H
#define IPSD_INSTRUMENT_SCAN_LIMITS_H

#include <stddef.h>

#include "base/err.h"

/* ---- defaults: the paper's scan (section II.B) ---- */
#define SCAN_DEFAULT_WAVELENGTH_NM 550.0 /* illumination */
#define SCAN_DEFAULT_NA 0.25             /* objective; R = 1.342 um by eq. 1 */
#define SCAN_DEFAULT_AREA_PX 5           /* n: raster over n x n pixels */
#define SCAN_DEFAULT_STEP_UM 0.6         /* raster step: 10 steps a 6 um pixel */
#define SCAN_DEFAULT_SUB_PX 9            /* m: sub-frame m x m read at every point */
#define SCAN_DEFAULT_FRAMES 12           /* k: frames averaged per point */
#define SCAN_DEFAULT_SETUP_FRAMES 4      /* frames per evaluation while centring, focusing */
#define SCAN_DEFAULT_EXPOSURE_US 10000.0 /* starting exposure; the setup adjusts it */
#define SCAN_DEFAULT_SEED 1              /* noise of the simulated bench */

/* ---- each field's range (min inclusive unless said "> min") ---- */
#define SCAN_WAVELENGTH_NM_MAX 1e5 /* > 0 */
#define SCAN_NA_MAX 1.7            /* > 0; oil immersion reaches ~1.5, 1.7 with special media */
#define SCAN_RADIUS_UM_MAX 1000.0  /* > 0 */
#define SCAN_AREA_PX_MIN 1         /* odd */
#define SCAN_AREA_PX_MAX 999
#define SCAN_STEP_UM_MAX 1000.0 /* > 0 */
#define SCAN_SUB_PX_MIN 3       /* odd: the POI and its 8 neighbours at least */
#define SCAN_SUB_PX_MAX 255
#define SCAN_FRAMES_MIN 1
#define SCAN_FRAMES_MAX 10000
#define SCAN_EXPOSURE_US_MAX 1e9 /* > 0 */
#define SCAN_SEED_MIN 0
#define SCAN_SEED_MAX 4294967295.0 /* 2^32 - 1 */
#define SCAN_GRID_MIN 1            /* a direct grid inside the POI (scan_grid_pixel) */
#define SCAN_GRID_MAX 1000         /* grid^2 <= SCAN_MAX_POINTS */

/* ---- combined rules ---- */
#define SCAN_MAX_POINTS 1000000           /* raster points (nx^2) */
#define SCAN_MAX_POINT_SAMPLES (1L << 26) /* frames x sub_px^2 of one raster point */

/* The fields, in the order of scan_fields[]. */
typedef enum scan_field_id {
    SCAN_F_WAVELENGTH_NM,
    SCAN_F_NA,
    SCAN_F_SPOT_RADIUS_UM,
    SCAN_F_AREA_PX,
    SCAN_F_STEP_UM,
    SCAN_F_SUB_PX,
    SCAN_F_FRAMES,
    SCAN_F_EXPOSURE_US,
    SCAN_F_SEED,
    SCAN_F_SETUP_FRAMES,
    SCAN_F_GRID,
    SCAN_NFIELDS
} scan_field_id_t;

typedef struct scan_field {
    const char *api; /* member path in the scan request ("raster.area_px"); NULL: not there */
    const char *cli; /* `ips simulate --NAME`; NULL: no option */
    int integer;     /* whole numbers only */
    double min, max; /* the range; min excluded when open_min */
    int open_min;
    int odd;          /* odd numbers only */
    double def;       /* default; NaN: none (e.g. the radius comes from eq. 1) */
    const char *unit; /* "nm", "um", "px", "us", "" */
    const char *description;
} scan_field_t;

extern const scan_field_t scan_fields[SCAN_NFIELDS];

/* The field whose api path is path, or NULL. */
const scan_field_t *scan_field_by_api(const char *path);

/* Checks v against f (whole, range, odd). name is what the message calls the field ("--area",
 * "raster.area_px", "area_px"). Returns 0 or -EINVAL with err: "NAME must be an odd integer in
 * 1..999 (got 4)", "NAME must be > 0 and <= 1000 (got 0)". */
int scan_field_check(const scan_field_t *f, double v, const char *name, err_t *err);

/* "odd integer 1..999", "number > 0 and <= 1000": the range in words (for usage texts). */
const char *scan_field_range(const scan_field_t *f, char *buf, size_t size);

/* Raster points per axis for a pitch, area and step: area_px * pitch / step + 1, or 0 when that
 * is not a whole number of steps (to 1e-6) or an argument is not positive. */
int scan_axis_points(double pitch_um, int area_px, double step_um);

/* The raster rules: whole steps and at most SCAN_MAX_POINTS points. step_name names the step in
 * the message ("raster.step_um", "--step"). *nx (may be NULL) gets the points per axis. Returns 0
 * or -EINVAL with err. */
int scan_check_raster(double pitch_um, int area_px, double step_um, const char *step_name, int *nx,
                      err_t *err);

/* The sample rule: frames x sub_px^2 <= SCAN_MAX_POINT_SAMPLES. frames_name names the frames in the
 * message. Returns 0 or -EINVAL with err. */
int scan_check_samples(int frames, int sub_px, const char *frames_name, err_t *err);

/* The grid rule (scan_grid_pixel): n points a side in step_um steps lie strictly inside one pixel
 * of pitch_um, (n - 1) step < pitch. name names the grid in the message. Returns 0 or -EINVAL. */
int scan_check_grid(double pitch_um, int n, double step_um, const char *name, err_t *err);

#endif
