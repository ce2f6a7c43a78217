/* srv_setup.h: the scan setup (instrument/scan.h scan_setup_t: the centre the procedure found, the
 * exposure, the settled sensor constants) as the JSON text stored with the scan
 * (storage_scan_set_setup), and the extraction of one sub-frame pixel's response from the stored
 * points as a scan file: the input of every fit ipsd runs and of GET .../pixels/{dcol}/{drow}. */
#ifndef IPSD_SERVER_SRV_SETUP_H
#define IPSD_SERVER_SRV_SETUP_H

#include <jansson.h>
#include <stddef.h>

#include "base/err.h"
#include "instrument/scan.h"
#include "instrument/scanfile.h"
#include "storage/storage.h"

/* The setup as JSON text (every double with 17 digits, so it reads back bit-identical).
 * Returns a malloc'ed string (caller frees) or NULL when out of memory. */
char *srv_setup_dump(const scan_setup_t *su);

/* The same with the scan's provenance: what took its frames, "camera": {backend, id, vendor,
 * model, serial, firmware, pixel_format, bits} (null members unknown), and "setup": "paper" (the
 * paper's exposure, centring and focus) or "none" (the POI's centre and exposure as given). */
char *srv_setup_dump_provenance(const scan_setup_t *su, const cam_info_t *cam, int setup_none);

/* The camera of a stored setup (what srv_setup_dump_provenance wrote) into *cam; -ENOENT when
 * the setup has none (stored by an older ipsd). */
int srv_setup_camera(const char *text, cam_info_t *cam);

/* Parses text made by srv_setup_dump. Returns 0 or -EINVAL naming the missing field. */
int srv_setup_parse(const char *text, scan_setup_t *su, err_t *err);

/* The response of sub-frame pixel (dcol, drow) of scan sc over its stored points, as a scan file
 * (*out owned by the caller: scanfile_free): positions relative to that pixel's top-left corner
 * computed from the stored stage positions and the stored setup's centre, the pixel's mean signal,
 * and the setup's sensor constants (gain divided by the analogue gain), exactly as
 * scan_extract_pixel does for a raster in memory. all = 0 keeps the positions strictly inside the
 * pixel (what the fit uses), all = 1 keeps every point. Returns 0, -EINVAL (pixel outside the
 * sub-frame), -ENODATA (the scan has no setup yet: nothing captured), or a storage error. */
int srv_pixel_scan(storage_t *st, const storage_scan_t *sc, int dcol, int drow, int all,
                   scanfile_t *out, err_t *err);

/* srv_pixel_scan written as scan-file text (scanfile_dump: full precision), with the metadata
 * object extra (borrowed, may be NULL) first, and sigma_dn (each point's uncertainty in DN under
 * the automatic fit's noise model, fit_noise_sigma) and sigma_model (that model's name) added. Returns 0 with a malloc'ed *text of *len bytes
 * (caller frees), or the errors of srv_pixel_scan. */
int srv_pixel_scan_text(storage_t *st, const storage_scan_t *sc, int dcol, int drow, int all,
                        json_t *extra, char **text, size_t *len, err_t *err);

#endif
