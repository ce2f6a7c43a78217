/* scanfile.h: reading and writing scan files, the JSON exchange format of a spot scan (the
 * scan-file contract of docs/contracts.md: `ips fit` input, the API's upload format, `ips simulate`
 * output). Required: pitch_um, spot_radius_um, bias_dn, gain_e_per_dn, read_noise_e, frames and
 * the equal-length arrays x_um, y_um, signal_dn; optional full_scale_dn; other keys are ignored.
 * Non-finite array values may be written as null, as Python's bare NaN / Infinity / -Infinity,
 * or as those words in quotes; they are read as NaN / +-inf (the fit leaves such points out).
 * The optional `subframe` (below) is read and checked when present. */
#ifndef IPSD_INSTRUMENT_SCANFILE_H
#define IPSD_INSTRUMENT_SCANFILE_H

#include <stddef.h>
#include <stdio.h>

#include <jansson.h>

#include "base/err.h"
#include "fit/scandata.h"

/* A parsed scan file: scan's arrays point into the buffers owned by this struct.
 *
 * The optional `subframe` (an ipsd addition, docs/contracts.md): every pixel of the m x m
 * sub-frame the camera read at each point, so that one file holds the response of every pixel a
 * raster covers (`ips fit --pixels all`, instrument/scanfile_sub.h). Its object is
 *   {"sub_px": m (odd, the scan's limits), "step_um": the raster step (> 0: the coverage rule's
 *    half-step tolerance, instrument/scan_cover.h),
 *    "signal_dn": one array per point (x_um's order) of m*m mean signals, row-major from the top
 *    left, the POI (the file's pixel) at index (m/2) m + m/2, equal to that point's signal_dn}.
 * Per point, because a point's sub-frame is what the camera reads at one stage position (as
 * GET /api/scans/{id}/points/{index} `mean`): a writer appends point by point, and the
 * positions, shared by every pixel, stay once at the top level, relative to the POI's corner. */
typedef struct scanfile {
    fit_scan_t scan;
    double *x_um, *y_um, *signal_dn; /* owned (NULL when n = 0) */
    int sub_px;                      /* m of `subframe`; 0: the file has none */
    double sub_step_um;              /* its step_um */
    double *sub_dn;                  /* owned: n * m*m means, point after point (NULL: none) */
} scanfile_t;

/* The `subframe` member for a scan file of n points (to put into scanfile_dump's extra): sub_px
 * m, step_um and the n * m*m means dn, point after point (non-finite as null). NULL when out of
 * memory. */
json_t *scanfile_subframe_json(int m, double step_um, const double *dn, size_t n);

/* Parses a scan file from len bytes of buf (need not be NUL-terminated) into *out, which the
 * caller releases with scanfile_free. On error *out is zeroed, err gets one line naming the
 * field and the problem (or the JSON syntax error with its line and column), and *field (may be
 * NULL) the offending key (a static string; NULL when the problem is not one field's).
 * Returns 0, -EINVAL (bad content) or -ENOMEM. */
int scanfile_parse(const char *buf, size_t len, scanfile_t *out, const char **field, err_t *err);

/* As scanfile_parse, reading the file at path; messages start with the path.
 * Returns 0, -ENOENT (no such file, naming the path), other negative errno, or -EINVAL. */
int scanfile_read(const char *path, scanfile_t *out, const char **field, err_t *err);

/* Releases what *sf owns and zeroes it; accepts NULL and a zeroed struct. */
void scanfile_free(scanfile_t *sf);

/* Writes scan as a scan file to f (full precision: every double is written with %.17g, so it
 * reads back bit-identical; non-finite array values as null, read back as NaN). extra (may be
 * NULL, borrowed) is a JSON object of metadata written first (e.g. "description"); it must not
 * redefine a scan-file key. full_scale_dn is always written. Returns 0, -EINVAL or -EIO. */
int scanfile_dump(FILE *f, const fit_scan_t *scan, json_t *extra, err_t *err);

/* As scanfile_dump into the file at path by base/outfile.h: a regular file replaced atomically
 * (written to path.tmp first, then renamed), so a failed write leaves any earlier file intact;
 * a link's target written the same way; a FIFO or a character device written in place, never
 * replaced. Returns 0, -EINVAL (a directory, a link to nothing, ...: nothing written), -EIO (a
 * write failed) or another negative errno. */
int scanfile_write(const char *path, const fit_scan_t *scan, json_t *extra, err_t *err);

#endif
