/* nodl.c: dlopen and getaddrinfo for the static `ips` (cli/CMakeLists.txt, IPSD_STATIC_CLI). A statically linked
 * glibc program can dlopen only with the very glibc it was linked against installed, and the
 * linker warns about every call. ips drives only the simulated camera, so it never loads a camera
 * module (instrument/cam.c); the link renames cam.c's calls (-Wl,--wrap=dlopen,--wrap=dlerror) to
 * these stand-ins, which fail every load with a message that says why. Likewise getaddrinfo
 * (NSS, the same trap): ips never connects to a motion controller (instrument/stage_link.c is
 * linked in only through the stage backends' table), so -Wl,--wrap=getaddrinfo makes a TCP stage
 * fail there with getaddrinfo's "non-recoverable failure" (EAI_FAIL) instead. */
#include <netdb.h>
#include <stddef.h>

void *__wrap_dlopen(const char *path, int flags);
int __wrap_getaddrinfo(const char *node, const char *service, const struct addrinfo *hints,
                       struct addrinfo **res);
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

int __wrap_getaddrinfo(const char *node, const char *service, const struct addrinfo *hints,
                       struct addrinfo **res)
{
    (void)node;
    (void)service;
    (void)hints;
    *res = NULL;
    return EAI_FAIL;
}
