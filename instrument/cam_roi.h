/* cam_roi.h (internal to instrument/): the region-of-interest check every camera backend does,
 * in a leaf file of its own (cam_roi.c, libc only) so that the simulated bench and run-time
 * loaded backend modules (which carry their own copy) use it without depending on cam.c. */
#ifndef IPSD_INSTRUMENT_CAM_ROI_H
#define IPSD_INSTRUMENT_CAM_ROI_H

#ifdef __cplusplus
extern "C" {
#endif

#include "instrument/cam.h"

/* Checks roi against a width x height array; fills *out (the whole array when roi is NULL).
 * Returns 0 or -EINVAL (with the ROI and the array in err). */
int cam_roi_check(const cam_roi_t *roi, int width, int height, cam_roi_t *out, err_t *err);

#ifdef __cplusplus
}
#endif

#endif
