/* cam.h: the camera interface of the bench, one small C header for every backend.
 *
 * Backends are chosen by name when a camera is listed or opened (cam.c keeps a table of them):
 *   "sim"        the simulated bench's camera (always built in; see sim.h). cam_open("sim", SPEC)
 *                opens a bench of its own with the paper's defaults on scene SPEC ("uniform",
 *                "paperlike", "map:FILE"; NULL or "" for paperlike); sim.h opens configured ones.
 *   "libcamera"  a camera driven by libcamera: a module (libipscam_libcamera.so, built when
 *                pkg-config finds libcamera) loaded the first time the backend is listed or
 *                opened, looked for in $IPSD_CAM_MODULE_PATH (directories, colon-separated) or
 *                else the build tree and the install location; when it is missing or does not
 *                load, listing and opening fail with -ENOTSUP and the loader's reason. ID is
 *                libcamera's camera id, or NULL / "" for the first camera.
 *   "aravis"     a GenICam camera (GigE Vision, USB3 Vision) driven by Aravis: a module
 *                (libipscam_aravis.so, built when pkg-config finds aravis-0.8) loaded like
 *                libcamera's. ID is Aravis's device id ("Vendor-Model-Serial", as
 *                `ipsd --list-cameras` prints it), or NULL / "" for the first camera found.
 * A frame is a region of interest (ROI) of 16-bit DN values, row-major, with its metadata. A
 * handle is used by one thread at a time. */
#ifndef IPSD_INSTRUMENT_CAM_H
#define IPSD_INSTRUMENT_CAM_H

#include <stddef.h>
#include <stdint.h>

#include "base/err.h"

typedef struct cam cam_t;

/* A rectangle of pixels: columns [col, col + width), rows [row, row + height). */
typedef struct cam_roi {
    int col, row, width, height;
} cam_roi_t;

/* What a camera says about itself. Unknown numbers are NaN. */
typedef struct cam_info {
    char backend[16]; /* "sim", "libcamera" or "aravis" */
    char id[128];     /* the id cam_open takes */
    char model[64];
    int width, height;    /* full array, pixels */
    double pitch_um;      /* pixel pitch */
    double gain_e_per_dn; /* conversion gain at analogue gain 1 */
    double read_noise_e;
    double bias_dn;
    double full_scale_dn; /* largest DN value the ADC gives */
    double exposure_min_us, exposure_max_us;
    double gain_min, gain_max; /* analogue gain range */
    /* the camera's own description (GenICam cameras: DeviceVendorName, DeviceSerialNumber,
     * DeviceFirmwareVersion or DeviceVersion); "" when the backend does not know it */
    char vendor[64], serial[64], firmware[64];
    char pixel_format[32]; /* the format frames are read in ("Mono16"; "" unknown) */
    int bits;              /* bits per pixel value of that format, 0 unknown */
} cam_info_t;

/* One captured frame. dn and expected_dn are owned by the frame: release with cam_frame_free. */
typedef struct cam_frame {
    cam_roi_t roi;
    uint16_t *dn;         /* roi.width * roi.height values, row-major (y then x) */
    double *expected_dn;  /* the simulator's noiseless expectation of each pixel (bias
                             included, unrounded, unclipped); NULL for real cameras */
    double left_out_dn;   /* the simulator's bound on signal it left out of any one pixel of
                             the frame (its leave-out rule); 0 for real cameras */
    double exposure_us;   /* exposure actually used */
    double gain;          /* analogue gain actually used */
    int64_t timestamp_ns; /* start of the exposure, backend clock: libcamera's sensor
                             timestamp, or the simulated bench's time */
    double temperature_c; /* sensor temperature, NaN if unknown */
    uint64_t sequence;    /* frame counter of this handle */
    uint64_t camera_frame_id; /* the camera's own frame id (GigE Vision block id), 0 if none */
} cam_frame_t;

/* Lists the cameras of backend ("sim", "libcamera" or "aravis"). *infos (n entries) is owned by
 * the caller (free()). Returns 0 (possibly with n = 0), -ENOTSUP for a backend whose module is not built or
 * does not load, -EINVAL for an unknown backend, or another negative errno from the backend. */
int cam_list(const char *backend, cam_info_t **infos, size_t *n, err_t *err);

/* Opens camera id of backend (see above). *out is owned by the caller (cam_close). Returns 0,
 * -ENODEV (no such camera; for libcamera with none present: "no camera found by libcamera"),
 * -ENOTSUP (backend's module not built or not loadable), -EINVAL, -EBUSY or -ENOMEM. */
int cam_open(const char *backend, const char *id, cam_t **out, err_t *err);

/* Closes the camera (stops it, releases it); accepts NULL. */
void cam_close(cam_t *cam);

/* Fills *info. Returns 0 or a negative errno. */
int cam_get_info(cam_t *cam, cam_info_t *info, err_t *err);

/* Sets the exposure time for the following captures (microseconds, within the info's range).
 * Returns 0, -ERANGE (outside the range) or a backend error. */
int cam_set_exposure(cam_t *cam, double exposure_us, err_t *err);

/* Sets the analogue gain (1 = the sensor's base conversion gain). Returns 0, -ERANGE or an
 * error. */
int cam_set_gain(cam_t *cam, double gain, err_t *err);

/* Bounds how long a capture waits for its frame: a camera that has not delivered a frame within
 * seconds of being asked (a camera that stopped answering) fails that capture with -ETIMEDOUT and
 * the camera's message. 0: the backend's default, the exposure time plus 5 s. Returns 0 or
 * -EINVAL (negative or not finite). */
int cam_set_timeout(cam_t *cam, double seconds, err_t *err);

/* Captures one frame of roi (NULL: the whole array) into *frame, which the caller releases with
 * cam_frame_free. Returns 0, -EINVAL (ROI outside the array), -EIO (capture failed),
 * -ETIMEDOUT (no frame within the timeout, cam_set_timeout), -ENOMEM. */
int cam_capture(cam_t *cam, const cam_roi_t *roi, cam_frame_t *frame, err_t *err);

/* Releases what the frame owns and zeroes it; accepts NULL. */
void cam_frame_free(cam_frame_t *frame);

/* Names of the backends available, NULL-terminated (static): the built-in ones, and those whose
 * module file is in the module path at the first call. Loads nothing: a module listed here may
 * still fail to load (a library it needs missing), which cam_list and cam_open report. */
const char *const *cam_backends(void);

#endif
