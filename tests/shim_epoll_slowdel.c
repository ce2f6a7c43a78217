/* shim_epoll_slowdel.c: an LD_PRELOAD library for test_server_quiesce.py. Every
 * epoll_ctl(EPOLL_CTL_DEL) waits 3 ms before it runs, which widens libmicrohttpd's race between
 * MHD_quiesce_daemon and an epoll pool thread over removing the listening socket (the loser's
 * ENOENT is an MHD_PANIC, an abort at SIGTERM; api/api_http.c). An ipsd whose HTTP threads use
 * poll() never calls it for that socket, so the shim changes nothing there. Each failed removal
 * is reported on stderr ("shim: epoll_ctl DEL fd N: errno E") for the test's log. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <stdio.h>
#include <sys/epoll.h>
#include <time.h>

typedef int (*epoll_ctl_fn)(int, int, int, struct epoll_event *);

static epoll_ctl_fn real; /* libc's, found when the shim is loaded, before any thread exists */

__attribute__((constructor)) static void find_real(void)
{
    void *sym = dlsym(RTLD_NEXT, "epoll_ctl");
    if (sym) *(void **)&real = sym; /* POSIX: dlsym's object pointer converted to a function's */
}

int epoll_ctl(int epfd, int op, int fd, struct epoll_event *event)
{
    if (!real) {
        errno = ENOSYS;
        return -1;
    }
    if (op == EPOLL_CTL_DEL) {
        struct timespec wait = {0, 3000000};
        nanosleep(&wait, NULL);
    }
    int rc = real(epfd, op, fd, event);
    if (rc && op == EPOLL_CTL_DEL) {
        int e = errno;
        fprintf(stderr, "shim: epoll_ctl DEL fd %d: errno %d\n", fd, e);
        errno = e;
    }
    return rc;
}
