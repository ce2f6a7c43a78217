/* scanfile_sub.h: the pixels of a scan file's sub-frame (the optional `subframe` of scanfile.h):
 * which ones its raster covers and each one's response as a scan file of its own, what
 * `ips fit --pixels all` fits. Both go through the functions the server uses on a stored scan
 * (scan_pixel_cover of scan_cover.h, scan_pixel_coords of scan.h), with the file's positions as
 * the stage positions and the POI's centre at (p/2, p/2): the rule is the server's, not a copy,
 * and the positions are the server's bit for bit (scan_pixel_coords subtracts the POI's corner,
 * then whole pitches). */
#ifndef IPSD_INSTRUMENT_SCANFILE_SUB_H
#define IPSD_INSTRUMENT_SCANFILE_SUB_H

#include "base/err.h"
#include "instrument/scan_cover.h"
#include "instrument/scanfile.h"

/* The coverage of sub-frame pixel (dcol, drow) (|dcol|, |drow| <= sub_px / 2) by sf's raster. */
void scanfile_pixel_cover(const scanfile_t *sf, int dcol, int drow, scan_cover_t *out);

/* Pixel (dcol, drow)'s response at every point of sf as a scan file (positions relative to that
 * pixel's corner, its means, sf's constants; no sub-frame): what the server's fit of that pixel
 * reads (GET /api/scans/{id}/pixels/{dcol}/{drow}?all=1). *out is the caller's (scanfile_free).
 * Returns 0, -EINVAL (sf has no sub-frame, or the pixel is outside it) or -ENOMEM. */
int scanfile_pixel(const scanfile_t *sf, int dcol, int drow, scanfile_t *out, err_t *err);

#endif
