/* scan_config.c: the scan procedure's configuration (scan.h): its defaults and its checks, both
 * from the one definition of a scan's defaults and limits (scan_limits.h). */
#include "instrument/scan.h"

#include <errno.h>
#include <math.h>

#include "instrument/scan_limits.h"

scan_config_t scan_config_default(void)
{
    return (scan_config_t){
        .poi_col = 0,
        .poi_row = 0,
        .start = {0, 0, 0},
        .area_px = SCAN_DEFAULT_AREA_PX,
        .step_um = SCAN_DEFAULT_STEP_UM,
        .subframe_px = SCAN_DEFAULT_SUB_PX,
        .frames = SCAN_DEFAULT_FRAMES,
        .setup_frames = SCAN_DEFAULT_SETUP_FRAMES,
        .saturation_dn = 16000,
        .exposure_fill = 0.4,
        .exposure_us = SCAN_DEFAULT_EXPOSURE_US,
        .gain = 1,
        .do_centre = 1,
        .do_focus = 1,
        .do_exposure = 1,
        .centre_step_um = 0.5,
        .centre_tol_um = 0.05,
        .centre_max_iter = 40,
        .focus_range_um = 15,
        .focus_step_um = 2.5,
        .focus_window_um = 3,
        .focus_points = 9,
        .focus_tol_um = 0.05,
        .keep_frames = 0,
        .use_expected = 0,
        .pitch_um = NAN,
        .bias_dn = NAN,
        .gain_e_per_dn = NAN,
        .read_noise_e = NAN,
        .full_scale_dn = NAN,
        .spot_radius_um = NAN,
    };
}

int scan_points_per_axis(const scan_config_t *cfg, double pitch_um)
{
    return scan_axis_points(pitch_um, cfg->area_px, cfg->step_um);
}

int scan_config_check(const scan_config_t *c, const cam_info_t *info, err_t *err)
{
    int rc;
    if ((rc = scan_field_check(&scan_fields[SCAN_F_AREA_PX], c->area_px, "area_px", err)) ||
        (rc = scan_field_check(&scan_fields[SCAN_F_STEP_UM], c->step_um, "step_um", err)) ||
        (rc = scan_field_check(&scan_fields[SCAN_F_SUB_PX], c->subframe_px, "subframe_px", err)) ||
        (rc = scan_field_check(&scan_fields[SCAN_F_FRAMES], c->frames, "frames", err)) ||
        (rc = scan_field_check(&scan_fields[SCAN_F_SETUP_FRAMES], c->setup_frames, "setup_frames",
                               err)) ||
        (rc = scan_field_check(&scan_fields[SCAN_F_EXPOSURE_US], c->exposure_us, "exposure_us",
                               err)) ||
        (rc = scan_check_samples(c->frames, c->subframe_px, "frames", err)))
        return rc;
    if (!(c->exposure_fill > 0 && c->exposure_fill < 1))
        return err_set(err, -EINVAL, "exposure_fill must be in (0, 1) (got %g)", c->exposure_fill);
    if (!(c->gain > 0) || !isfinite(c->gain) || !isfinite(c->saturation_dn))
        return err_set(err, -EINVAL, "gain must be positive, saturation finite");
    if (!(c->centre_step_um > 0) || !(c->centre_tol_um > 0) || c->centre_max_iter < 1 ||
        !(c->focus_range_um >= 0) || !(c->focus_step_um > 0) || !(c->focus_window_um > 0) ||
        c->focus_points < 3 || !(c->focus_tol_um > 0))
        return err_set(err, -EINVAL,
                       "centring and focus settings must be positive (focus_points"
                       " >= 3)");
    if (!isfinite(c->start.x_um) || !isfinite(c->start.y_um) || !isfinite(c->start.z_um))
        return err_set(err, -EINVAL, "start position must be finite");
    if (!info) return 0;
    int h = c->subframe_px / 2;
    if (c->poi_col - h < 0 || c->poi_row - h < 0 || c->poi_col + h >= info->width ||
        c->poi_row + h >= info->height)
        return err_set(err, -EINVAL,
                       "the %dx%d sub-frame around pixel (%d, %d) leaves the %dx%d "
                       "array",
                       c->subframe_px, c->subframe_px, c->poi_col, c->poi_row, info->width,
                       info->height);
    return 0;
}
