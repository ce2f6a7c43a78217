/* srv_ptc.h: photon-transfer jobs (EMVA 1288): what a request asks of a measurement
 * (the series of exposures and the pixels measured), queueing it for the instrument's worker,
 * and the sensor's measured constants a fit uses for its sigma (eq. 5). Thread-safe. */
#ifndef IPSD_SERVER_SRV_PTC_H
#define IPSD_SERVER_SRV_PTC_H

#include <stdint.h>

#include <jansson.h>

#include "base/err.h"
#include "fit/scandata.h"
#include "server/srv.h"
#include "storage/storage.h"

#define SRV_PTC_LEVELS_DEFAULT 40
#define SRV_PTC_ROI_DEFAULT 256 /* the N x N pixels at the array's corner (capped by the array) */
/* The largest region the simulated bench can capture at once: floor(sqrt(SIM_CAPTURE_PX_MAX)) */
#define SRV_PTC_ROI_MAX 856
/* Levels a series needs for the photon-transfer slope: 4 below saturation, and the default lamp
 * (the saturation charge at the reference exposure, 10 of the series' 12.5 ms) saturates the
 * top fifth, so 6 without flat_e (measured: 3 never gives a slope, 4-5 only with a dimmer lamp) */
#define SRV_PTC_LEVELS_MIN 4
#define SRV_PTC_LEVELS_MIN_DEFAULT_LAMP 6

typedef struct srv_ptc_params {
    int64_t sensor_id;
    int levels;         /* exposures in the series (4..1000; 6.. with the default lamp) */
    int roi_px;         /* N: the N x N pixels at the array's corner measured (2..856) */
    double flat_e;      /* the simulated lamp, e- per pixel at the reference exposure; 0: the
                         * sensor's saturation charge (the series then crosses saturation) */
    unsigned long seed; /* noise of the simulated frames */
} srv_ptc_params_t;

srv_ptc_params_t srv_ptc_params_default(int64_t sensor_id);
/* JSON object text of p (caller frees), NULL when out of memory. */
char *srv_ptc_params_dump(const srv_ptc_params_t *p);
/* Reads text made by srv_ptc_params_dump; missing members keep their defaults. -EINVAL. */
int srv_ptc_params_parse(const char *text, srv_ptc_params_t *p, err_t *err);

/* Queues a photon-transfer measurement of p->sensor_id (the roi is capped by the sensor's array)
 * for the instrument's worker (the scan worker, which takes scans and measurements in the order
 * queued), wakes it and publishes the queued job. -ENOENT (sensor), -ENOTSUP (the bench has no
 * lamp ipsd can switch: only the simulated bench does), -EINVAL, -ESHUTDOWN when stopping. */
int srv_ptc_submit(srv_t *srv, storage_t *st, const srv_ptc_params_t *p, int64_t *job_id,
                   err_t *err);

/* The gain and read noise a fit of sensor_id's data uses for sigma: the sensor's newest
 * photon-transfer measurement (*ptc_id its id), else *ptc_id = 0 and the values are left as
 * they are (the scan's own constants). Returns 0 or a storage error. */
int srv_ptc_constants(storage_t *st, int64_t sensor_id, double *gain_e_per_dn, double *read_noise_e,
                      int64_t *ptc_id, err_t *err);

/* Where the gain and read noise of a fit's sigma (eq. 5) came from, and their values. */
typedef struct srv_noise_source {
    char name[32];  /* "request", "ptc #ID", "sensor" (the scan's, from the sensor row when it
                     * was scanned) or "scan file" (an upload's own) */
    int64_t ptc_id; /* the measurement used; 0: none */
    double gain_e_per_dn, read_noise_e;
} srv_noise_source_t;

/* Sets scan's gain and read noise for a fit of it: the request's (p; either may be given, the
 * other then comes from below), else the newest photon-transfer measurement of sensor_id (0:
 * none, an upload), else the scan's own. src says which. Returns 0 or a storage error. */
int srv_fit_noise(storage_t *st, const srv_fit_params_t *p, int64_t sensor_id, fit_scan_t *scan,
                  srv_noise_source_t *src, err_t *err);

/* Adds "noise_source" (src->name) and "noise_constants" {gain_e_per_dn, read_noise_e, ptc_id}
 * to a fit document. 0 or -ENOMEM. */
int srv_fit_noise_record(json_t *doc, const srv_noise_source_t *src);

#endif
