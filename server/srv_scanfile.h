/* srv_scanfile.h: a stored scan as one scan file with its whole sub-frame (the `subframe` of
 * instrument/scanfile.h): the POI's response over every stored point (positions relative to the
 * POI's corner) and, at each point, the mean of every pixel of the sub-frame. What
 * GET /api/scans/{id}/scanfile serves, so that `ips fit FILE --pixels all` fits off line every
 * pixel the server's fit of every pixel fits, to the same maps. */
#ifndef IPSD_SERVER_SRV_SCANFILE_H
#define IPSD_SERVER_SRV_SCANFILE_H

#include <jansson.h>
#include <stddef.h>

#include "base/err.h"
#include "storage/storage.h"

/* Scan sc as scan-file text (scanfile_dump: 17 digits), the metadata object extra (borrowed, may
 * be NULL) first, with `subframe`. Returns 0 with a malloc'ed *text of *len bytes (caller frees),
 * -ENODATA (no setup yet: nothing captured), -ENOMEM or a storage error. */
int srv_scan_file_text(storage_t *st, const storage_scan_t *sc, json_t *extra, char **text,
                       size_t *len, err_t *err);

#endif
