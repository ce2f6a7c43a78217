/* cmd_import_fits.c: `ips import-fits CUBE.fits [--pixel DC,DR] [--all-points] -o SCAN.json`: a
 * spot scan a lab's acquisition software wrote as a FITS cube (export/fitsscan.h; the layout is
 * docs/contracts.md, "FITS scan cube") turned into the scan file of one of its pixels, the
 * input `ips fit` and the API take. It runs as ips-import-fits (import_fits_main.c), beside ips,
 * so that ips itself does not link cfitsio (cli/CMakeLists.txt). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "base/opts.h"
#include "base/parse.h"
#include "cliutil.h"
#include "commands.h"
#include "export/fitsscan.h"
#include "instrument/scan_cube.h"
#include "instrument/scanfile.h"

#define MAX_FILE_BYTES ((size_t)1 << 32) /* 4 GiB: far above any scan (51 x 51 x 9 x 9: 1.7 MB) */

static const char usage[] =
    "usage: ips import-fits CUBE.fits [--pixel DC,DR] [--all-points] -o SCAN.json\n"
    "  Writes the scan file (docs/contracts.md) of one pixel of a spot scan stored as a FITS\n"
    "  cube: primary image NAXIS1 x NAXIS2 x NAXIS3 = sub-frame columns x rows x points (each\n"
    "  plane the mean frame at one spot position, DN), keywords PITCH, SPOTRAD, BIAS, GAIN,\n"
    "  RDNOISE, NCOMBINE, POICOL, POIROW [, SATURATE, EXPTIME], and a binary table POSITIONS\n"
    "  with X_UM, Y_UM (spot centres relative to the POI's corner) [, NCOMBINE, EXPTIME].\n"
    "  CUBE.fits '-' reads standard input.\n"
    "  --pixel DC,DR       sub-frame pixel (DC, DR) relative to the POI (default 0,0), columns\n"
    "                      rightward, rows downward; positions become relative to its corner\n"
    "  --all-points        every position, not only those strictly inside the pixel\n"
    "  -o, --output FILE   the scan file to write ('-': standard output)\n";

enum { OPT_PIXEL = 256, OPT_ALL, OPT_HELP };

static const struct option long_opts[] = {{"pixel", required_argument, NULL, OPT_PIXEL},
                                          {"all-points", no_argument, NULL, OPT_ALL},
                                          {"output", required_argument, NULL, 'o'},
                                          {"help", no_argument, NULL, OPT_HELP},
                                          {NULL, 0, NULL, 0}};

struct import_args {
    int dcol, drow, all;
    const char *out;
};

/* --pixel DC,DR: two integers. */
static int parse_pixel(const char *text, int *dc, int *dr, err_t *err)
{
    const char *comma = strchr(text, ',');
    char first[32];
    if (comma && (size_t)(comma - text) < sizeof first) {
        memcpy(first, text, (size_t)(comma - text));
        first[comma - text] = '\0';
        if (parse_int(first, dc) == 0 && parse_int(comma + 1, dr) == 0) return 0;
    }
    return err_set(err, -EINVAL, "--pixel must be two integers DC,DR (got '%s')", text);
}

static int parse_opt(int c, const char *arg, void *user, err_t *err)
{
    struct import_args *a = user;
    switch (c) {
    case OPT_PIXEL: return parse_pixel(arg, &a->dcol, &a->drow, err);
    case OPT_ALL: a->all = 1; return 0;
    case 'o': a->out = arg; return 0;
    default: return err_set(err, -EINVAL, "unhandled option");
    }
}

/* The whole of path ('-': standard input) into *buf (malloc'd) of *len bytes. */
static int slurp(const char *path, char **buf, size_t *len, err_t *err)
{
    int is_stdin = strcmp(path, "-") == 0;
    FILE *f = is_stdin ? stdin : fopen(path, "rb");
    *buf = NULL;
    *len = 0;
    if (!f) return err_set(err, errno == ENOENT ? -ENOENT : -EINVAL, "%s: %s", path, strerror(errno));
    size_t cap = 0;
    int rc = 0;
    for (;;) {
        if (*len == cap) {
            size_t ncap = cap ? 2 * cap : 1 << 16;
            char *nb = ncap <= MAX_FILE_BYTES ? realloc(*buf, ncap) : NULL;
            if (!nb) {
                rc = ncap > MAX_FILE_BYTES ? err_set(err, -EINVAL, "%s: larger than 4 GiB", path)
                                           : err_set(err, -ENOMEM, "%s: out of memory", path);
                break;
            }
            *buf = nb;
            cap = ncap;
        }
        size_t got = fread(*buf + *len, 1, cap - *len, f);
        *len += got;
        /* a FITS file begins with the card SIMPLE: anything else (/dev/zero, a log) is refused at
         * its first block instead of read to the end */
        if (*len >= 9 && *len - got < 9 && memcmp(*buf, "SIMPLE  =", 9) != 0) {
            rc = err_set(err, -EINVAL, "%s: not a FITS file (it does not begin with the card "
                         "SIMPLE)", path);
            break;
        }
        if (got == 0) {
            if (ferror(f)) rc = err_set(err, -EIO, "%s: read error", path);
            break;
        }
    }
    if (!is_stdin) fclose(f);
    if (rc) {
        free(*buf);
        *buf = NULL;
        *len = 0;
    }
    return rc;
}

int cmd_import_fits(int argc, char **argv)
{
    struct import_args a = {0};
    err_t err;
    int first, rc = opts_parse(argc, argv, "o:", long_opts, OPT_HELP, "ips import-fits --help",
                               parse_opt, &a, &first, &err);
    if (rc == 1) {
        fputs(usage, stdout);
        return 0;
    }
    if (rc) return cli_fail(CLI_EXIT_USAGE, "import-fits", "%s", err.msg);
    if (first != argc - 1)
        return cli_fail(CLI_EXIT_USAGE, "import-fits",
                        "expected one CUBE.fits (see ips import-fits --help)");
    if (!a.out) return cli_fail(CLI_EXIT_USAGE, "import-fits", "-o SCAN.json is required");
    const char *path = argv[first];
    char *buf;
    size_t len;
    if ((rc = slurp(path, &buf, &len, &err)))
        return cli_fail(rc == -ENOMEM || rc == -EIO ? CLI_EXIT_FAILURE : CLI_EXIT_USAGE,
                        "import-fits", "%s", err.msg);
    fitsscan_t fs;
    rc = fitsscan_read(buf, len, &fs, &err);
    free(buf);
    if (rc) return cli_fail(cli_exit_code(rc), "import-fits", "%s: %s", path, err.msg);
    scan_cube_t cube = {.ncol = fs.ncol,
                        .nrow = fs.nrow,
                        .n = fs.n,
                        .poi_col = fs.poi_col,
                        .poi_row = fs.poi_row,
                        .mean_dn = fs.mean_dn,
                        .x_um = fs.x_um,
                        .y_um = fs.y_um,
                        .pitch_um = fs.pitch_um,
                        .spot_radius_um = fs.spot_radius_um,
                        .bias_dn = fs.bias_dn,
                        .gain_e_per_dn = fs.gain_e_per_dn,
                        .read_noise_e = fs.read_noise_e,
                        .full_scale_dn = fs.full_scale_dn,
                        .frames = fs.frames};
    scanfile_t sf;
    rc = scan_cube_pixel(&cube, a.dcol, a.drow, a.all, &sf, &err);
    if (rc) {
        fitsscan_free(&fs);
        return cli_fail(cli_exit_code(rc), "import-fits", "%s: %s", path, err.msg);
    }
    if (sf.scan.n == 0) {
        fitsscan_free(&fs);
        scanfile_free(&sf);
        return cli_fail(CLI_EXIT_USAGE, "import-fits",
                        "%s: no spot position lies strictly inside pixel (%+d, %+d) (--all-points "
                        "keeps those outside)", path, a.dcol, a.drow);
    }
    /* where the scan came from, as metadata the scan-file readers ignore */
    json_t *extra = json_pack("{s:s, s:s, s:[ii], s:[ii], s:I, s:b}", "description",
                              "imported from a FITS scan cube by ips import-fits", "fits_file",
                              path, "pixel", a.dcol, a.drow, "cube_size", fs.ncol, fs.nrow,
                              "cube_points", (json_int_t)fs.n, "all_points", a.all);
    if (extra && isfinite(fs.exptime_s))
        json_object_set_new(extra, "exptime_s", json_real(fs.exptime_s));
    fitsscan_free(&fs);
    if (!extra) {
        scanfile_free(&sf);
        return cli_fail(CLI_EXIT_FAILURE, "import-fits", "out of memory");
    }
    if (strcmp(a.out, "-") == 0) {
        rc = scanfile_dump(stdout, &sf.scan, extra, &err);
        if (rc == 0 && fflush(stdout) != 0) rc = err_set(&err, -EIO, "cannot write stdout");
    } else {
        rc = scanfile_write(a.out, &sf.scan, extra, &err);
    }
    json_decref(extra);
    scanfile_free(&sf);
    if (rc) return cli_fail(cli_exit_code(rc), "import-fits", "%s", err.msg);
    return 0;
}
