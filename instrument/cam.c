/* cam.c: the camera interface's dispatch over the backends built in (see cam.h, cam_impl.h). */
#include "instrument/cam.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "cam_impl.h"

static const char *const backends[] = {
    "sim",
#ifdef IPSD_HAVE_LIBCAMERA
    "libcamera",
#endif
    NULL,
};

const char *const *cam_backends(void)
{
    return backends;
}

cam_t *cam_wrap(const struct cam_ops *ops, void *impl)
{
    cam_t *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->ops = ops;
    c->impl = impl;
    return c;
}

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

/* -EINVAL for an unknown name, -ENOTSUP for a known backend not built in, else 0 with *which. */
static int pick(const char *backend, int *which, err_t *err)
{
    if (!backend || strcmp(backend, "sim") == 0) {
        *which = 0;
        return 0;
    }
    if (strcmp(backend, "libcamera") == 0) {
#ifdef IPSD_HAVE_LIBCAMERA
        *which = 1;
        return 0;
#else
        return err_set(err, -ENOTSUP,
                       "camera backend 'libcamera' is not built in (libcamera "
                       "was not found when ipsd was built)");
#endif
    }
    return err_set(err, -EINVAL, "unknown camera backend '%s' (sim or libcamera)", backend);
}

int cam_list(const char *backend, cam_info_t **infos, size_t *n, err_t *err)
{
    int which, rc = pick(backend, &which, err);
    *infos = NULL;
    *n = 0;
    if (rc) return rc;
#ifdef IPSD_HAVE_LIBCAMERA
    if (which == 1) return cam_libcamera_list(infos, n, err);
#endif
    return cam_sim_list(infos, n, err);
}

int cam_open(const char *backend, const char *id, cam_t **out, err_t *err)
{
    int which, rc = pick(backend, &which, err);
    *out = NULL;
    if (rc) return rc;
#ifdef IPSD_HAVE_LIBCAMERA
    if (which == 1) return cam_libcamera_open(id, out, err);
#endif
    return cam_sim_open(id, out, err);
}

void cam_close(cam_t *cam)
{
    if (!cam) return;
    if (cam->ops->close) cam->ops->close(cam->impl);
    free(cam);
}

int cam_get_info(cam_t *cam, cam_info_t *info, err_t *err)
{
    memset(info, 0, sizeof *info);
    return cam->ops->info(cam->impl, info, err);
}

int cam_set_exposure(cam_t *cam, double exposure_us, err_t *err)
{
    return cam->ops->set_exposure(cam->impl, exposure_us, err);
}

int cam_set_gain(cam_t *cam, double gain, err_t *err)
{
    return cam->ops->set_gain(cam->impl, gain, err);
}

int cam_capture(cam_t *cam, const cam_roi_t *roi, cam_frame_t *frame, err_t *err)
{
    memset(frame, 0, sizeof *frame);
    int rc = cam->ops->capture(cam->impl, roi, frame, err);
    if (rc) {
        cam_frame_free(frame);
        return rc;
    }
    frame->sequence = cam->sequence++;
    return 0;
}

void cam_frame_free(cam_frame_t *frame)
{
    if (!frame) return;
    free(frame->dn);
    free(frame->expected_dn);
    memset(frame, 0, sizeof *frame);
}
