/* test_cam_libcamera.c: the libcamera camera backend (instrument/cam_libcamera.cpp) builds and,
 * on a machine without a camera (CI, a laptop), reports that cleanly: no cameras listed, and
 * opening one fails with -ENODEV and "no camera found by libcamera". Where a camera is present,
 * it opens, describes itself and captures one frame. Without libcamera at build time the
 * backend is refused with -ENOTSUP. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "instrument/cam.h"
#include "check.h"

static int has_backend(const char *name)
{
    for (const char *const *b = cam_backends(); *b; b++)
        if (strcmp(*b, name) == 0) return 1;
    return 0;
}

int main(void)
{
    err_t err = {{0}};
    cam_t *cam = NULL;
    cam_info_t *list = NULL;
    size_t n = 99;
    CHECK(has_backend("sim"));
#ifndef IPSD_HAVE_LIBCAMERA
    CHECK(!has_backend("libcamera"));
    CHECK(cam_open("libcamera", NULL, &cam, &err) == -ENOTSUP && cam == NULL);
    CHECK(strstr(err.msg, "not built") != NULL);
    CHECK(cam_list("libcamera", &list, &n, &err) == -ENOTSUP && n == 0);
    printf("libcamera backend not built: checked that it is refused\n");
#else
    CHECK(has_backend("libcamera"));
    CHECK(cam_list("libcamera", &list, &n, &err) == 0);
    if (n == 0) {
        CHECK(list == NULL);
        CHECK(cam_open("libcamera", NULL, &cam, &err) == -ENODEV && cam == NULL);
        CHECK(strstr(err.msg, "no camera found by libcamera") != NULL);
        CHECK(cam_open("libcamera", "/base/no/such/camera", &cam, &err) == -ENODEV);
        /* a second round: the shared camera manager is released and made again cleanly */
        CHECK(cam_list("libcamera", &list, &n, &err) == 0 && n == 0);
        printf("no camera present: libcamera backend reports -ENODEV (%s)\n", err.msg);
    } else {
        CHECK(list[0].id[0] != '\0' && strcmp(list[0].backend, "libcamera") == 0);
        CHECK(cam_open("libcamera", list[0].id, &cam, &err) == 0);
        if (cam) {
            cam_info_t info;
            CHECK(cam_get_info(cam, &info, &err) == 0 && info.width > 0 && info.height > 0);
            cam_roi_t roi = {0, 0, info.width < 8 ? info.width : 8,
                             info.height < 8 ? info.height : 8};
            cam_frame_t f;
            CHECK(cam_capture(cam, &roi, &f, &err) == 0 && f.dn != NULL && f.expected_dn == NULL);
            cam_frame_free(&f);
            cam_close(cam);
        }
        printf("%zu camera(s): opened %s\n", n, list[0].id);
    }
    free(list);
#endif
    CHECK(cam_open("bogus", NULL, &cam, &err) == -EINVAL && strstr(err.msg, "bogus"));
    CHECK_DONE();
}
