/* srv_params.h: the parameters of ipsd's jobs as they are stored in jobs.params (JSON): what a scan
 * job needs besides its scan row (the simulated scene and the noise seed), and what a fit job fits
 * (a pixel of a finished scan, or an uploaded scan file) and how (r range, noise model, F-test,
 * Wiener), with where its calibration goes. */
#ifndef IPSD_SERVER_SRV_PARAMS_H
#define IPSD_SERVER_SRV_PARAMS_H

#include <jansson.h>
#include <stdint.h>

#include "base/err.h"
#include "fit/model.h"
#include "fit/region.h"
#include "storage/storage.h" /* storage_map_t */

/* Scenes the simulated bench offers to scans. */
#define SRV_SCENES "uniform, paperlike"

/* How a scan chooses its points ("strategy"): the raster of the scan's raster parameters (the
 * default), or an adaptive scan of the POI (fit/adapt_plan.h: the starting start_grid^2 raster,
 * then batches where the kriged map is least sure until its expected error reaches target_err
 * after a planned batch, or the scan holds max_points points). Defaults: fit/adapt_plan.h's. */
typedef struct srv_strategy {
    int adaptive;       /* 0: raster */
    double target_err;  /* > 0 */
    int max_points;     /* >= start_grid^2 */
    int batch;          /* 1..SRV_ADAPT_BATCH_MAX */
    int start_grid;     /* 2..SRV_ADAPT_START_GRID_MAX */
} srv_strategy_t;

#define SRV_ADAPT_BATCH_MAX 1000
/* an adaptive scan's budget at most: every plan fits the points so far and krige solves a dense
 * system of them, so its cost grows as the cube of the points */
#define SRV_ADAPT_MAX_POINTS 10000
#define SRV_ADAPT_START_GRID_MAX 51

/* The adaptive defaults (adaptive 0: a raster until the caller says otherwise). */
srv_strategy_t srv_strategy_default(void);
/* The strategy as its JSON object ({"kind": "raster"} or {"kind": "adaptive", "target_err",
 * "max_points", "batch", "start_grid"}), new reference; NULL when out of memory. */
json_t *srv_strategy_json(const srv_strategy_t *s);

typedef struct srv_scan_params {
    char scene[32];     /* "paperlike" (default) or "uniform" */
    unsigned long seed; /* noise of the simulated frames (1) */
    int setup_none;     /* "setup": "none": no exposure, centring or focus search: the POI's
                           centre and exposure_us as given (0: the paper's procedure) */
    srv_strategy_t strategy; /* "strategy" (absent from the params of a raster scan) */
} srv_scan_params_t;

srv_scan_params_t srv_scan_params_default(void);
/* JSON object text of p (caller frees), NULL when out of memory. */
char *srv_scan_params_dump(const srv_scan_params_t *p);
/* Reads text made by srv_scan_params_dump; missing members keep their defaults. */
int srv_scan_params_parse(const char *text, srv_scan_params_t *p, err_t *err);

/* Longest "by" (a declared operator name) and "reason" of a calibration change, in bytes. */
#define SRV_BY_MAX 64
#define SRV_REASON_MAX 500

typedef struct srv_fit_params {
    int64_t scan_id;      /* the scan whose pixel is fitted; 0: an uploaded scan file */
    int dcol, drow;       /* the sub-frame pixel, offset from the POI (0, 0 for uploads) */
    int r_min, r_max;     /* 1..32 (1..8) */
    fit_options_t opts;   /* noise model (paper), method (linear), nonneg (0) */
    unsigned ftest_edges; /* F-test edges (enum fit_edge); 0: no F-test */
    int ftest_r;          /* r of the F-test (7) */
    int wiener;           /* run the Wiener baseline */
    json_t *scan_file;    /* the uploaded scan file (owned reference), NULL for a scan's pixel */
    int64_t sensor_id;    /* uploads: the sensor the calibration is of, 0: store none */
    int pixel_col, pixel_row; /* uploads: that sensor pixel */
    double wavelength_um, na; /* uploads: optics for the calibration's provenance; NaN unknown */
    /* whether the fit's map becomes its pixel's current calibration, and who asked and why (the
     * calibration's provenance, docs/api.md); "": the defaults of srv_fitter.c */
    int promote;
    char by[SRV_BY_MAX + 1];
    char reason[SRV_REASON_MAX + 1];
    fit_region_t region;  /* the points fitted (fit/region.h): inside (the paper's) */
    int fit_geometry;     /* fit R, dx, dy first (fit/geometry.h) at geometry_r (0: default) */
    int krige;            /* add the kriged map (fit/krige.h) to the result */
    int geometry_r;
    int geometry_map_only; /* "geometry_model": "map": the r x r fit's geometry, not refined
                              under the kriged model (fit/geometry.h) */
    /* every pixel of the scan's sub-frame its raster covers (instrument/scan_cover.h), one fit
     * each, instead of (dcol, drow): "pixels": "all" (server/srv_fitall.c) */
    int all_pixels;
    /* the request's gain and read noise for sigma (eq. 5), overriding the sensor's measured
     * constants (srv_ptc.h) and the scan's; NaN: not given */
    double gain_e_per_dn, read_noise_e;
    /* the map the fit offers as a calibration ("map"): the recommended r's own (default), the
     * shrunk map (fit/shrink.h) or the kriged map (fit/krige.h; it implies krige), the recommended
     * one when the sweep has none */
    storage_map_t map;
} srv_fit_params_t;

/* Defaults: r 1..8, paper noise, linear, no F-test (ftest_r 7), no Wiener, no upload, not
 * promoted. */
srv_fit_params_t srv_fit_params_default(void);
/* What the server queues when a scan finishes: its POI, r 1..8, paper noise, the F-test of the
 * paper's edge model (top, left, bottom at r = 7) and the Wiener baseline; promoted, by "ipsd",
 * for the reason "automatic fit of scan N". */
srv_fit_params_t srv_fit_params_auto(int64_t scan_id);
/* JSON object text of p (caller frees), NULL when out of memory. */
char *srv_fit_params_dump(const srv_fit_params_t *p);
/* Reads text made by srv_fit_params_dump into *p (release with srv_fit_params_free). Without a
 * "promote" member (a job queued before it existed) promote is 1, as such jobs were. */
int srv_fit_params_parse(const char *text, srv_fit_params_t *p, err_t *err);
void srv_fit_params_free(srv_fit_params_t *p);

/* Checks an uploaded scan file (the "scan" member of a fit request) as `ips fit` reads it
 * (instrument/scanfile.h): returns 0 with its pitch and number of points, or -EINVAL with err and
 * *field naming the offending key (static; NULL when not one key's fault), or -ENOMEM. */
int srv_upload_check(json_t *scan, double *pitch_um, size_t *n_points, const char **field,
                     err_t *err);

/* The comma list of edge names of a mask ("top,left,bottom"), into buf. */
const char *srv_edges_text(unsigned edges, char *buf, size_t n);

#endif
