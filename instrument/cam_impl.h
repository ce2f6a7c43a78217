/* cam_impl.h (internal to instrument/): how a camera backend plugs into cam.h. A backend is a
 * table (struct cam_backend): its name, how to list its cameras, how to open one, and the
 * operations on what it opened. cam.c keeps one entry per backend, built in (the simulator's,
 * cam_sim.c) or provided by a module loaded at run time when first asked for (libcamera's,
 * cam_libcamera.cpp; Aravis's, cam_aravis.c): a shared object whose one exported symbol,
 * ipsd_cam_backend_v3(), returns its table. A module needs nothing from the program that loads
 * it (it is linked with --no-undefined and carries its own copies of err_set and cam_roi_check),
 * so this header is its whole interface, hence the extern "C" for the C++ module.
 *
 * The ABI is this table, the operations, and the layouts of cam_info_t, cam_frame_t, cam_roi_t
 * and err_t (cam.h, base/err.h), whose sizes the table states so that a stale module is refused
 * rather than misread. Memory a backend hands over (the list of cam_list, a frame's dn and
 * expected_dn) is malloc'ed: the caller frees it with free(). Any change of these is a new
 * version: a new entry point (ipsd_cam_backend_v4 next). */
#ifndef IPSD_INSTRUMENT_CAM_IMPL_H
#define IPSD_INSTRUMENT_CAM_IMPL_H

#ifdef __cplusplus
extern "C" {
#endif

#include "instrument/cam.h" /* C declarations, err.h's included: C linkage for the C++ module */

#define CAM_BACKEND_ABI 3 /* 2: cam_ops.set_timeout; 3: the camera's description in cam_info_t
                             (vendor, serial, firmware, pixel format, bits), its frame id in
                             cam_frame_t */
#define CAM_BACKEND_ENTRY "ipsd_cam_backend_v3" /* the symbol cam.c looks up in a module */

/* What can be done with an opened camera (impl: what the backend's open gave). */
struct cam_ops {
    void (*close)(void *impl); /* releases impl (NULL: the handle does not own it) */
    int (*info)(void *impl, cam_info_t *info, err_t *err);
    int (*set_exposure)(void *impl, double exposure_us, err_t *err);
    int (*set_gain)(void *impl, double gain, err_t *err);
    /* frame arrives zeroed; on error the caller frees what was put in it */
    int (*capture)(void *impl, const cam_roi_t *roi, cam_frame_t *frame, err_t *err);
    /* bounds the wait for each later frame (cam_set_timeout; 0: the backend's default) */
    int (*set_timeout)(void *impl, double seconds, err_t *err);
};

/* A backend (cam.h's semantics for list and open; open gives the state ops works on). */
struct cam_backend {
    unsigned abi;                             /* CAM_BACKEND_ABI */
    unsigned info_size, frame_size, err_size; /* sizeof cam_info_t, cam_frame_t, err_t */
    const char *name;                         /* "sim", "libcamera" */
    int (*list)(cam_info_t **infos, size_t *n, err_t *err);
    int (*open)(const char *id, void **impl, err_t *err);
    const struct cam_ops *ops; /* of what open gives */
};

/* The initialiser of the version and layout fields. */
#define CAM_BACKEND_HEADER                                                                         \
    CAM_BACKEND_ABI, (unsigned)sizeof(cam_info_t), (unsigned)sizeof(cam_frame_t),                  \
        (unsigned)sizeof(err_t)

/* The entry point of a backend module (cam_libcamera.cpp, cam_aravis.c): its table, static. */
typedef const struct cam_backend *(*cam_backend_entry_fn)(void);
const struct cam_backend *ipsd_cam_backend_v3(void);

/* ---- inside the library only (not for modules) ---- */

/* The simulator's backend (cam_sim.c). */
extern const struct cam_backend cam_sim_backend;

/* A new handle over impl with ops, owning impl when ops->close is not NULL; NULL when out of
 * memory (impl is then not released). */
cam_t *cam_wrap(const struct cam_ops *ops, void *impl);

/* impl of cam when its operations are ops, else NULL (cam may be NULL). */
void *cam_impl_of(cam_t *cam, const struct cam_ops *ops);

#ifdef __cplusplus
}
#endif

#endif
