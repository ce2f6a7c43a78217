/* cam_impl.h (internal to instrument/): how a camera backend plugs into cam.h. A backend fills a
 * table of operations and wraps its state with cam_wrap; cam.c dispatches. Shared by the C
 * backends and the C++ libcamera shim, hence the extern "C". */
#ifndef IPSD_INSTRUMENT_CAM_IMPL_H
#define IPSD_INSTRUMENT_CAM_IMPL_H

#ifdef __cplusplus
extern "C" {
#endif

#include "instrument/cam.h" /* C declarations, err.h's included: C linkage for the C++ shim too */

struct cam_ops {
    const char *backend;
    void (*close)(void *impl); /* releases impl (NULL: the handle does not own it) */
    int (*info)(void *impl, cam_info_t *info, err_t *err);
    int (*set_exposure)(void *impl, double exposure_us, err_t *err);
    int (*set_gain)(void *impl, double gain, err_t *err);
    int (*capture)(void *impl, const cam_roi_t *roi, cam_frame_t *frame, err_t *err);
};

struct cam {
    const struct cam_ops *ops;
    void *impl;
    uint64_t sequence;
};

/* A new handle over impl (owned by the handle when ops->close is not NULL); NULL when out of
 * memory (impl is then not released). */
cam_t *cam_wrap(const struct cam_ops *ops, void *impl);

/* Checks roi against a width x height array; fills *out (the whole array when roi is NULL). */
int cam_roi_check(const cam_roi_t *roi, int width, int height, cam_roi_t *out, err_t *err);

/* The libcamera backend (cam_libcamera.cpp, present when IPSD_HAVE_LIBCAMERA is defined). */
int cam_libcamera_list(cam_info_t **infos, size_t *n, err_t *err);
int cam_libcamera_open(const char *id, cam_t **out, err_t *err);

/* The simulator's backend (cam_sim.c): listing the built-in scenes, opening a bench of its own
 * (the handle owns it), and a handle over a bench that stays the bench's (sim_camera). */
struct sim;
int cam_sim_list(cam_info_t **infos, size_t *n, err_t *err);
int cam_sim_open(const char *spec, cam_t **out, err_t *err);
int cam_sim_borrowed(struct sim *sim, cam_t **out);
struct sim *cam_sim_of(cam_t *cam);

#ifdef __cplusplus
}
#endif

#endif
