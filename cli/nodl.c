/* nodl.c: dlopen for the static `ips` (cli/CMakeLists.txt, IPSD_STATIC_CLI). A statically linked
 * glibc program can dlopen only with the very glibc it was linked against installed, and the
 * linker warns about every call. ips drives only the simulated camera, so it never loads a camera
 * module (instrument/cam.c); the link renames cam.c's calls (-Wl,--wrap=dlopen,--wrap=dlerror) to
 * these stand-ins, which fail every load with a message that says why. */
#include <stddef.h>

void *__wrap_dlopen(const char *path, int flags);
char *__wrap_dlerror(void);

void *__wrap_dlopen(const char *path, int flags)
{
    (void)path;
    (void)flags;
    return NULL;
}

char *__wrap_dlerror(void)
{
    static char why[] = "the static ips loads no modules (ipsd drives real cameras)";
    return why;
}
