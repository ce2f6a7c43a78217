/* scanfile.h: reading and writing scan files, the JSON exchange format of a spot scan (the
 * scan-file contract of docs/contracts.md: `ips fit` input, the API's upload format, `ips simulate`
 * output). Required: pitch_um, spot_radius_um, bias_dn, gain_e_per_dn, read_noise_e, frames and
 * the equal-length arrays x_um, y_um, signal_dn; optional full_scale_dn; other keys are ignored.
 * Non-finite array values may be written as null, as Python's bare NaN / Infinity / -Infinity,
 * or as those words in quotes; they are read as NaN / +-inf (the fit leaves such points out). */
#ifndef IPSD_INSTRUMENT_SCANFILE_H
#define IPSD_INSTRUMENT_SCANFILE_H

#include <stddef.h>
#include <stdio.h>

#include <jansson.h>

#include "base/err.h"
#include "fit/scandata.h"

/* A parsed scan file: scan's arrays point into the buffers owned by this struct. */
typedef struct scanfile {
    fit_scan_t scan;
    double *x_um, *y_um, *signal_dn; /* owned (NULL when n = 0) */
} scanfile_t;

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

/* As scanfile_dump into the file at path, replaced atomically (written to path.tmp first, then
 * renamed), so a failed write leaves any earlier file intact. Returns 0 or a negative errno. */
int scanfile_write(const char *path, const fit_scan_t *scan, json_t *extra, err_t *err);

#endif
