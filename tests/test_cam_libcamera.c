/* test_cam_libcamera.c: the libcamera camera backend (instrument/cam_libcamera.cpp), a module
 * cam.c loads at run time. Checked against what the process itself shows (/proc/self/maps): the
 * module and libcamera are not loaded until the backend is listed or opened, and are loaded
 * then. A module path without the module gives -ENOTSUP naming the reason (dlerror's text), and
 * IPSD_CAM_MODULE_PATH finds the module elsewhere. On a machine without a camera (CI, a laptop)
 * the backend reports that cleanly: no cameras listed, and opening one fails with -ENODEV and "no
 * camera found by libcamera". Where a camera is present, it opens, describes itself and captures
 * one frame. When the module was not built (IPSD_HAVE_LIBCAMERA undefined here) the backend is
 * not listed and is refused with -ENOTSUP. */
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

/* Whether a file whose path contains needle is mapped into this process ("/libcamera": the
 * library, not this test's own name). */
static int mapped(const char *needle)
{
    FILE *f = fopen("/proc/self/maps", "r");
    char line[4096];
    int found = 0;
    if (!f) return -1;
    while (!found && fgets(line, sizeof line, f))
        found = strstr(line, needle) != NULL;
    fclose(f);
    return found;
}

int main(void)
{
    err_t err = {{0}};
    cam_t *cam = NULL;
    cam_info_t *list = NULL;
    size_t n = 99;
    CHECK(mapped("/libc.so") == 1); /* the way of looking works */
    CHECK(has_backend("sim"));
    /* the simulated camera and the list of backends load nothing */
    CHECK(cam_open("sim", "uniform", &cam, &err) == 0 && cam != NULL);
    cam_close(cam);
    CHECK(mapped("/libcamera") == 0 && mapped("/libipscam") == 0);
#ifndef IPSD_HAVE_LIBCAMERA
    CHECK(!has_backend("libcamera"));
    CHECK(cam_open("libcamera", NULL, &cam, &err) == -ENOTSUP && cam == NULL);
    CHECK(strstr(err.msg, "not built") != NULL);
    CHECK(cam_list("libcamera", &list, &n, &err) == -ENOTSUP && n == 0);
    CHECK(mapped("/libcamera") == 0);
    printf("libcamera backend not built: checked that it is refused\n");
#else
    CHECK(has_backend("libcamera"));
    /* a module path without the module: refused with the loader's reason, nothing loaded */
    setenv("IPSD_CAM_MODULE_PATH", "/nonexistent/ipsd-modules", 1);
    CHECK(cam_open("libcamera", NULL, &cam, &err) == -ENOTSUP && cam == NULL);
    CHECK(strstr(err.msg, "not built") != NULL);
    CHECK(strstr(err.msg, "/nonexistent/ipsd-modules/libipscam_libcamera.so") != NULL);
    CHECK(strstr(err.msg, "No such file") != NULL); /* dlerror's text */
    CHECK(mapped("/libcamera") == 0);
    /* found in a later directory of the path (an empty element is skipped) */
    setenv("IPSD_CAM_MODULE_PATH", "/nonexistent/ipsd-modules::" IPSD_TEST_CAM_MODULE_DIR, 1);
    CHECK(cam_list("libcamera", &list, &n, &err) == 0);
    unsetenv("IPSD_CAM_MODULE_PATH");
    CHECK(mapped("/libipscam_libcamera.so") == 1 && mapped("/libcamera") == 1);
    if (n == 0) {
        CHECK(list == NULL);
        CHECK(cam_open("libcamera", NULL, &cam, &err) == -ENODEV && cam == NULL);
        CHECK(strstr(err.msg, "no camera found by libcamera") != NULL);
        CHECK(cam_open("libcamera", "/base/no/such/camera", &cam, &err) == -ENODEV);
        /* a second pass: the shared camera manager is released and made again cleanly */
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
    CHECK(strstr(err.msg, "sim") && strstr(err.msg, "libcamera")); /* the names it knows */
    CHECK_DONE();
}
