/* cam_roi.c: the region-of-interest check of the camera backends (cam_roi.h). */
#include "cam_roi.h"

#include <errno.h>

int cam_roi_check(const cam_roi_t *roi, int width, int height, cam_roi_t *out, err_t *err)
{
    if (!roi) {
        *out = (cam_roi_t){0, 0, width, height};
        return 0;
    }
    if (roi->width < 1 || roi->height < 1 || roi->col < 0 || roi->row < 0 ||
        roi->col > width - roi->width || roi->row > height - roi->height)
        return err_set(err, -EINVAL,
                       "region of interest %dx%d at column %d, row %d is outside the %dx%d array",
                       roi->width, roi->height, roi->col, roi->row, width, height);
    *out = *roi;
    return 0;
}
