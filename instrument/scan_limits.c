/* scan_limits.c: the table of a scan's fields (scan_limits.h) and the checks every interface runs
 * with it: one field's range, the raster's whole steps and size, the samples of one point. */
#include "instrument/scan_limits.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

const scan_field_t scan_fields[SCAN_NFIELDS] = {
    [SCAN_F_WAVELENGTH_NM] = {"optics.wavelength_nm", "wavelength", 0, 0, SCAN_WAVELENGTH_NM_MAX, 1,
                              0, SCAN_DEFAULT_WAVELENGTH_NM, "nm", "Illumination wavelength"},
    [SCAN_F_NA] = {"optics.na", "na", 0, 0, SCAN_NA_MAX, 1, 0, SCAN_DEFAULT_NA, "",
                   "Numerical aperture of the objective"},
    [SCAN_F_SPOT_RADIUS_UM] = {"optics.spot_radius_um", "radius", 0, 0, SCAN_RADIUS_UM_MAX, 1, 0,
                               NAN, "um",
                               "First-zero radius R of the spot, given instead of the NA: eq. 1, "
                               "R = 1.22 lambda / (2 NA), is solved for the NA"},
    [SCAN_F_AREA_PX] = {"raster.area_px", "area", 1, SCAN_AREA_PX_MIN, SCAN_AREA_PX_MAX, 0, 1,
                        SCAN_DEFAULT_AREA_PX, "px",
                        "The raster covers area_px x area_px whole pixels centred on the pixel "
                        "of interest (odd)"},
    [SCAN_F_STEP_UM] = {"raster.step_um", "step", 0, 0, SCAN_STEP_UM_MAX, 1, 0,
                        SCAN_DEFAULT_STEP_UM, "um",
                        "Raster step; area_px x pitch must be a whole number of steps, and the "
                        "raster at most 10^6 points"},
    [SCAN_F_SUB_PX] = {"raster.sub_px", "subframe", 1, SCAN_SUB_PX_MIN, SCAN_SUB_PX_MAX, 0, 1,
                       SCAN_DEFAULT_SUB_PX, "px",
                       "Side of the sub-frame read at every point, centred on the pixel of "
                       "interest (odd); it must lie on the sensor"},
    [SCAN_F_FRAMES] = {"raster.frames", "frames", 1, SCAN_FRAMES_MIN, SCAN_FRAMES_MAX, 0, 0,
                       SCAN_DEFAULT_FRAMES, "",
                       "Frames averaged per point; frames x sub_px^2 at most 2^26"},
    [SCAN_F_EXPOSURE_US] = {"exposure_us", NULL, 0, 0, SCAN_EXPOSURE_US_MAX, 1, 0,
                            SCAN_DEFAULT_EXPOSURE_US, "us",
                            "Starting exposure (the procedure adjusts it)"},
    [SCAN_F_SEED] = {"seed", "seed", 1, SCAN_SEED_MIN, SCAN_SEED_MAX, 0, 0, SCAN_DEFAULT_SEED, "",
                     "Seed of the simulated bench's noise"},
    [SCAN_F_SETUP_FRAMES] = {NULL, NULL, 1, SCAN_FRAMES_MIN, SCAN_FRAMES_MAX, 0, 0,
                             SCAN_DEFAULT_SETUP_FRAMES, "",
                             "Frames per evaluation while centring and focusing"},
    [SCAN_F_GRID] = {NULL, "grid", 1, SCAN_GRID_MIN, SCAN_GRID_MAX, 0, 0, NAN, "",
                     "A direct grid of N x N points inside the pixel of interest, no setup"},
};

const scan_field_t *scan_field_by_api(const char *path)
{
    for (int i = 0; path && i < SCAN_NFIELDS; i++)
        if (scan_fields[i].api && strcmp(scan_fields[i].api, path) == 0) return &scan_fields[i];
    return NULL;
}

const char *scan_field_range(const scan_field_t *f, char *buf, size_t size)
{
    if (f->integer)
        snprintf(buf, size, "%s%.0f..%.0f", f->odd ? "odd, " : "", f->min, f->max);
    else if (f->open_min)
        snprintf(buf, size, "> %.15g and <= %.15g", f->min, f->max);
    else
        snprintf(buf, size, "%.15g..%.15g", f->min, f->max);
    return buf;
}

int scan_field_check(const scan_field_t *f, double v, const char *name, err_t *err)
{
    if (f->integer && !(isfinite(v) && v == floor(v)))
        return err_set(err, -EINVAL, "%s must be an integer (got %.17g)", name, v);
    if (!isfinite(v) || (f->open_min ? !(v > f->min) : !(v >= f->min)) || !(v <= f->max)) {
        char r[64];
        return err_set(err, -EINVAL, "%s must be %s%s (got %.17g)", name, f->integer ? "in " : "",
                       scan_field_range(f, r, sizeof r), v);
    }
    if (f->odd && fmod(v, 2) == 0)
        return err_set(err, -EINVAL, "%s must be odd (got %.0f)", name, v);
    return 0;
}

int scan_axis_points(double pitch_um, int area_px, double step_um)
{
    if (!(pitch_um > 0) || !(step_um > 0) || area_px < 1) return 0;
    double n = area_px * pitch_um / step_um; /* steps per axis */
    double k = nearbyint(n);
    /* a whole number to 1e-6 relative; beyond 10^6 steps nx^2 is over any limit anyway */
    if (!isfinite(n) || fabs(n - k) > 1e-6 * (k > 1 ? k : 1) || k < 1 || k > 1e6) return 0;
    return (int)k + 1;
}

int scan_check_raster(double pitch_um, int area_px, double step_um, const char *step_name, int *nx,
                      err_t *err)
{
    int n = scan_axis_points(pitch_um, area_px, step_um);
    if (nx) *nx = n;
    if (n < 1)
        return err_set(err, -EINVAL,
                       "%s: %.15g um steps do not divide %d pixels of %.15g um into a whole "
                       "number of steps",
                       step_name, step_um, area_px, pitch_um);
    if ((long long)n * n > SCAN_MAX_POINTS)
        return err_set(err, -EINVAL,
                       "%s: %.15g um steps over %d pixels of %.15g um make %d x %d points, more "
                       "than %d",
                       step_name, step_um, area_px, pitch_um, n, n, SCAN_MAX_POINTS);
    return 0;
}

int scan_check_samples(int frames, int sub_px, const char *frames_name, err_t *err)
{
    if ((long long)frames * sub_px * sub_px > SCAN_MAX_POINT_SAMPLES)
        return err_set(err, -EINVAL,
                       "%s: %d frames of %d x %d pixels are more than %ld samples a point",
                       frames_name, frames, sub_px, sub_px, SCAN_MAX_POINT_SAMPLES);
    return 0;
}

int scan_check_grid(double pitch_um, int n, double step_um, const char *name, err_t *err)
{
    double span = (n - 1) * step_um; /* first to last point */
    if (!(span < pitch_um * (1 - 1e-9)))
        return err_set(err, -EINVAL,
                       "%s: %d x %d points in %.15g um steps span %.15g um: they must fit inside "
                       "the %.15g um pixel",
                       name, n, n, step_um, span, pitch_um);
    return 0;
}
