/* srv_cover.h: which pixels of a stored scan's sub-frame its raster covers (the rule of
 * instrument/scan_cover.h applied to the stored stage positions and setup): what a fit of every
 * pixel fits, and what GET /api/scans/{id}/coverage reports. */
#ifndef IPSD_SERVER_SRV_COVER_H
#define IPSD_SERVER_SRV_COVER_H

#include "base/err.h"
#include "instrument/scan_cover.h"
#include "storage/storage.h"

/* The status of a pixel the raster does not cover (docs/api.md). */
#define SRV_NOT_COVERED "not_covered"

/* The coverage of every pixel of scan sc's sub_px x sub_px sub-frame, row by row from the top
 * left: (*out)[(drow + h) * sub_px + (dcol + h)], h = sub_px / 2 (malloc'ed, caller frees).
 * Returns 0, -ENODATA (the scan has no setup yet) or a storage error. */
int srv_scan_cover(storage_t *st, const storage_scan_t *sc, scan_cover_t **out, err_t *err);

#endif
