/* api_router.c: the route table of the API and the matching of a request path against it. A
 * pattern segment {name} matches one decimal integer (a leading '-' allowed); handlers check the
 * range. The table is the single list of routes: the OpenAPI test compares it with the document. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "api_int.h"

static const api_route_t routes[] = {
    {"GET", "/api/health", api_h_health, 0},
    {"GET", "/api/openapi.json", api_h_openapi, 0},
    {"GET", "/api/sensors", api_h_sensors_list, 0},
    {"POST", "/api/sensors", api_h_sensors_create, 1},
    {"GET", "/api/sensors/{id}", api_h_sensor_get, 0},
    {"GET", "/api/sensors/{id}/pixels/{col}/{row}/calibration", api_h_pixel_calib, 0},
    {"GET", "/api/sensors/{id}/pixels/{col}/{row}/history", api_h_pixel_history, 0},
    {"GET", "/api/scans", api_h_scans_list, 0},
    {"POST", "/api/scans", api_h_scans_create, 1},
    {"GET", "/api/scans/{id}", api_h_scan_get, 0},
    {"POST", "/api/scans/{id}/cancel", api_h_scan_cancel, 0},
    {"POST", "/api/scans/{id}/resume", api_h_scan_resume, 0},
    {"GET", "/api/scans/{id}/pixels/{dcol}/{drow}", api_h_scan_pixel, 0},
    {"GET", "/api/scans/{id}/scanfile", api_h_scan_scanfile, 0},
    {"GET", "/api/scans/{id}/points/{index}", api_h_scan_point, 0},
    {"GET", "/api/scans/{id}/fits", api_h_scan_fits_list, 0},
    {"POST", "/api/scans/{id}/fits", api_h_scan_fit_create, 1},
    {"GET", "/api/scans/{id}/coverage", api_h_scan_coverage, 0},
    {"POST", "/api/fits", api_h_fit_upload, 1},
    {"GET", "/api/fits/{id}", api_h_fit_get, 0},
    {"GET", "/api/fits/{id}/interp", api_h_fit_interp, 0},
    {"POST", "/api/fits/{id}/promote", api_h_fit_promote, 1},
    {"GET", "/api/calibrations", api_h_calibs_search, 0},
    {"GET", "/api/calibrations/{id}", api_h_calib_get, 0},
    {"GET", "/api/calibrations/{id}/interp", api_h_calib_interp, 0},
    {"GET", "/api/jobs", api_h_jobs_list, 0},
    {"GET", "/api/jobs/{id}", api_h_job_get, 0},
    {"POST", "/api/jobs/{id}/cancel", api_h_job_cancel, 0},
    {"GET", "/api/events", api_h_events, 0},
    {"POST", "/api/events/ticket", api_h_events_ticket, 0},
    {"POST", "/api/backup", api_h_backup, API_BODY_OPTIONAL},
    {"GET", "/api/calibrations/{id}/map.fits", api_h_calib_fits, 0},
    {"GET", "/api/sensors/{id}/pixels/{col}/{row}/calibration.fits", api_h_pixel_calib_fits, 0},
    {"GET", "/api/sensors/{id}/calibrations.fits", api_h_sensor_calibs_fits, 0},
    {"POST", "/api/jitter", api_h_jitter, 1},
    {"POST", "/api/sensors/{id}/ptc", api_h_sensor_ptc_create, 1},
    {"GET", "/api/sensors/{id}/ptc", api_h_sensor_ptc, 0},
    {"GET", "/api/ptc/{id}", api_h_ptc_get, 0},
};
#define N_ROUTES (sizeof routes / sizeof routes[0])

/* POSTs that only compute and store nothing: they need what a read needs, not a write token. */
int api_route_computes_only(const api_route_t *r)
{
    return r && !strcmp(r->method, "POST") &&
           (!strcmp(r->pattern, "/api/jitter") || !strcmp(r->pattern, "/api/events/ticket"));
}

const api_route_info_t *api_route_list(size_t *n)
{
    static api_route_info_t info[N_ROUTES];
    for (size_t i = 0; i < N_ROUTES; i++)
        info[i] = (api_route_info_t){routes[i].method, routes[i].pattern};
    *n = N_ROUTES;
    return info;
}

/* One integer path segment [s, e): at most 15 digits, optional '-'. */
static int segment_int(const char *s, const char *e, int64_t *v)
{
    const char *p = s + (*s == '-');
    if (p == e || e - p > 15) return -EINVAL;
    for (const char *c = p; c < e; c++)
        if (*c < '0' || *c > '9') return -EINVAL;
    *v = strtoll(s, NULL, 10);
    return 0;
}

/* Does path match pattern? Fills arg with the {name} segments. */
static int match(const char *pattern, const char *path, int64_t *arg)
{
    const char *p = pattern, *u = path;
    int n = 0;
    while (*p && *u) {
        if (*p == '{') {
            const char *pe = strchr(p, '}'), *ue = strchr(u, '/');
            if (!ue) ue = u + strlen(u);
            if (!pe || n >= API_MAX_ARGS || segment_int(u, ue, &arg[n])) return 0;
            n++;
            p = pe + 1;
            u = ue;
        } else if (*p++ != *u++) {
            return 0;
        }
    }
    return *p == 0 && *u == 0;
}

const api_route_t *api_route_find(const char *method, const char *path, int64_t *arg,
                                  int *path_known)
{
    int64_t scratch[API_MAX_ARGS];
    /* HEAD is GET without the body (libmicrohttpd drops the body) */
    if (strcmp(method, "HEAD") == 0) method = "GET";
    *path_known = 0;
    for (size_t i = 0; i < N_ROUTES; i++) {
        if (!match(routes[i].pattern, path, scratch)) continue;
        if (strcmp(routes[i].method, method) == 0) {
            memcpy(arg, scratch, sizeof scratch);
            return &routes[i];
        }
        *path_known = 1;
    }
    return NULL;
}

const char *api_route_allow(const char *path, char *buf, size_t n)
{
    int64_t scratch[API_MAX_ARGS];
    size_t at = 0;
    buf[0] = 0;
    for (size_t i = 0; i < N_ROUTES; i++)
        if (match(routes[i].pattern, path, scratch) && at < n)
            at += (size_t)snprintf(buf + at, n - at, "%s%s", at ? ", " : "", routes[i].method);
    return buf;
}
