/* cmd_export.c: `ips export MAPS.json --pitch UM -o OUT.fits`: IPS maps as a FITS file
 * (export/fitsmap.h) from a Calibration document of the API, a page of them, an `ips fit`
 * document or a bare map (cli/mapfile.h). The same file GET /api/calibrations/{id}/map.fits
 * serves, for maps that left ipsd as JSON or were fitted by `ips fit`. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/clock.h"
#include "base/opts.h"
#include "base/outfile.h"
#include "cliutil.h"
#include "commands.h"
#include "export/fitsmap.h"
#include "mapfile.h"

static const char usage[] =
    "usage: ips export MAPS.json --pitch UM -o OUT.fits [--r R | --shrunk | --kriged]\n"
    "  Writes IPS maps as FITS: per map the image extensions ('S', k) and ('S_ERR', k) with\n"
    "  their sampling (OVERSAMP, CDELT/CRVAL/CRPIX), optics and provenance, then ('S_RES', k)\n"
    "  where the map's resolution error is known (docs/api.md, FITS).\n"
    "  MAPS.json: a Calibration (GET /api/calibrations/{id}), a page of them ({\"items\": ...}),\n"
    "  an `ips fit` document (its recommended r, or --r) or a map {\"r\", \"S\"}.\n"
    "  --pitch UM     pixel pitch of the sensor (um, > 0; the documents do not carry it)\n"
    "  -o, --out FILE the FITS file to write\n"
    "  --r R          the r of an `ips fit` document's map (default: its recommended r)\n"
    "  --shrunk       an `ips fit` document's shrunk map (its shrunk_map) instead\n"
    "  --kriged       an `ips fit --krige` document's kriged map (its kriged_map, on its fine\n"
    "                 grid: OVERSAMP is that grid) instead\n";

enum { OPT_PITCH = 256, OPT_R, OPT_SHRUNK, OPT_KRIGED, OPT_HELP };

static const struct option long_opts[] = {
    {"pitch", required_argument, NULL, OPT_PITCH}, {"out", required_argument, NULL, 'o'},
    {"r", required_argument, NULL, OPT_R},         {"help", no_argument, NULL, OPT_HELP},
    {"shrunk", no_argument, NULL, OPT_SHRUNK},     {"kriged", no_argument, NULL, OPT_KRIGED},
    {NULL, 0, NULL, 0}};

struct export_args {
    double pitch;
    const char *out;
    int r, shrunk, kriged;
};

static int parse_opt(int c, const char *arg, void *user, err_t *err)
{
    struct export_args *a = user;
    switch (c) {
    case OPT_PITCH: return opts_num("pitch", arg, 1e-3, 1e4, &a->pitch, err);
    case OPT_R: return opts_int32("r", arg, 1, 256, &a->r, err);
    case OPT_SHRUNK: a->shrunk = 1; return 0;
    case OPT_KRIGED: a->kriged = 1; return 0;
    case 'o': a->out = arg; return 0;
    default: return err_set(err, -EINVAL, "unhandled option");
    }
}

int cmd_export(int argc, char **argv)
{
    struct export_args a = {.pitch = NAN};
    err_t err;
    int first, rc = opts_parse(argc, argv, "o:", long_opts, OPT_HELP, "ips export --help",
                               parse_opt, &a, &first, &err);
    if (rc == 1) {
        fputs(usage, stdout);
        return 0;
    }
    if (rc) return cli_fail(CLI_EXIT_USAGE, "export", "%s", err.msg);
    if (first != argc - 1)
        return cli_fail(CLI_EXIT_USAGE, "export", "expected one MAPS.json (see ips export --help)");
    if (!a.out) return cli_fail(CLI_EXIT_USAGE, "export", "-o OUT.fits is required");
    if (!(a.pitch > 0)) return cli_fail(CLI_EXIT_USAGE, "export", "--pitch UM is required");
    if ((a.shrunk != 0) + (a.kriged != 0) + (a.r != 0) > 1)
        return cli_fail(CLI_EXIT_USAGE, "export", "--r, --shrunk and --kriged exclude each other");
    mapfile_t mf;
    rc = mapfile_read(argv[first], a.shrunk ? MAPFILE_SHRUNK : a.kriged ? MAPFILE_KRIGED : a.r,
                      &mf, &err);
    if (rc) {
        mapfile_free(&mf);
        return cli_fail(cli_exit_code(rc), "export", "%s", err.msg);
    }
    fitsmap_t *maps = calloc(mf.n, sizeof *maps);
    if (!maps) {
        mapfile_free(&mf);
        return cli_fail(CLI_EXIT_FAILURE, "export", "out of memory");
    }
    for (size_t k = 0; k < mf.n; k++) {
        const mapfile_map_t *m = &mf.maps[k];
        maps[k] = (fitsmap_t){.r = m->r, .S = m->S, .S_err = m->S_err, .S_res = m->S_res,
                              .pitch_um = a.pitch, .pixel_col = m->col, .pixel_row = m->row,
                              .wavelength_um = m->wavelength_um, .na = m->na,
                              .spot_radius_um = m->spot_radius_um, .I0 = m->I0,
                              .chi2_red = m->chi2_red, .status = m->status,
                              .noise_model = m->noise_model,
                              .software_version = m->software_version, .calib_id = m->id,
                              .sensor_id = m->sensor_id, .scan_id = m->scan_id,
                              .fit_id = m->fit_id, .created_ms = m->created_ms,
                              .current = m->current, .by = m->by, .reason = m->reason,
                              .map = m->map};
    }
    fitsmap_file_t file = {.creator = "ips " IPSD_VERSION, .sensor_id = mf.maps[0].sensor_id,
                           .pitch_um = a.pitch, .date_ms = clock_wall_ms()};
    void *buf = NULL;
    size_t len = 0;
    rc = fitsmap_write(&file, maps, mf.n, &buf, &len, &err);
    free(maps);
    mapfile_free(&mf);
    if (rc) return cli_fail(cli_exit_code(rc), "export", "%s", err.msg);
    outfile_t o;
    if ((rc = outfile_open(a.out, &o, &err)) == 0) {
        if (fwrite(buf, 1, len, o.f) != len) {
            rc = err_set(&err, -EIO, "%s: cannot write: %s", a.out, strerror(errno));
            outfile_abort(&o);
        } else {
            rc = outfile_commit(&o, &err);
        }
    }
    free(buf);
    return rc ? cli_fail(cli_exit_code(rc), "export", "%s", err.msg) : 0;
}
