/* mapfile.h: IPS maps read from a JSON file for `ips export` and `ips jitter`: a Calibration of
 * the API (GET /api/calibrations/{id}, .../calibration), a page of them ({"items": [...]}, GET
 * /api/calibrations?sensor=N), an `ips fit` document (the fit of its recommended r, or of a
 * chosen r), or a bare map ({"r": m, "S": [...]} or an array of m*m numbers, as the simulator's
 * map: scenes read). One owner; strings and arrays stay valid until mapfile_free. */
#ifndef IPSD_CLI_MAPFILE_H
#define IPSD_CLI_MAPFILE_H

#include <stddef.h>
#include <stdint.h>

#include "base/err.h"

typedef struct mapfile_map {
    int r;
    double *S, *S_err; /* r*r each (S_err NaN where the file has none) */
    double *S_res;     /* r*r or NULL (the file does not say): the resolution error, a
                          Calibration's S_res or, for an `ips fit` document, its shrunk_map's
                          S_res when that map has the r read (fit/shrink.h) */
    int col, row;      /* sensor pixel; 0 when the file does not say */
    double wavelength_um, na, spot_radius_um, I0, chi2_red;            /* NaN: unknown */
    const char *status, *noise_model, *software_version, *by, *reason; /* NULL: unknown */
    const char *map; /* "recommended", "shrunk" or "kriged" (a calibration's map, or the fit
                        document's map read); NULL: unknown or another r of a fit document */
    int64_t id, sensor_id, scan_id, fit_id, created_ms;                /* 0: unknown */
    int current;                                                       /* 1 / 0, -1 unknown */
} mapfile_map_t;

typedef struct mapfile {
    mapfile_map_t *maps;
    size_t n;
    void *doc; /* the parsed document the strings point into */
} mapfile_t;

/* r of mapfile_read: an `ips fit` document's shrunk map (its shrunk_map, fit/shrink.h) */
#define MAPFILE_SHRUNK (-1)
/* r of mapfile_read: an `ips fit --krige` document's kriged map (its kriged_map, fit/krige.h) on
 * its fine grid (the map's r is the grid; I0, chi2_red and status are the recommended r's fit's,
 * as in a calibration that holds it) */
#define MAPFILE_KRIGED (-2)

/* Reads path; r > 0 picks that r of an `ips fit` document (0: its recommended r; MAPFILE_SHRUNK:
 * its shrunk map; MAPFILE_KRIGED: its kriged map). Returns 0, -ENOENT (no file), -EINVAL naming
 * what the file lacks, -ENOMEM. */
int mapfile_read(const char *path, int r, mapfile_t *out, err_t *err);
void mapfile_free(mapfile_t *mf);

#endif
