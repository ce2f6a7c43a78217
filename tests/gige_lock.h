/* gige_lock.h: one GigE Vision emulator on 127.0.0.1 at a time across the whole machine, for the
 * tests that run one: test_cam_aravis, in its process (the HTTP tests, which run arv_emulator,
 * take the same lock in Python: test_server_aravis.py's gige_lock).
 *
 * Why a lock file and not only ctest's RESOURCE_LOCK "gige_emulator": that lock holds within one
 * ctest run, but two runs (two build trees, two work trees) may test at once, and Aravis's
 * emulator binds the GigE Vision control port 3956 with SO_REUSEADDR: a second one starts as if
 * the port were free, and the kernel then hands a command meant for one to the other. A camera
 * opened by id then answers with another's serial, or its trigger reaches the other emulator and
 * the frame never comes. flock(2) on a file in /tmp orders them instead; the kernel releases it
 * when the process ends, however it ends. A process that does not take the lock (a test of an
 * older tree, arv-fake-gv-camera-0.8 run by hand) is seen by binding the port without
 * SO_REUSEADDR, and waited for too. */
#ifndef IPSD_TESTS_GIGE_LOCK_H
#define IPSD_TESTS_GIGE_LOCK_H

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <stdio.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define GIGE_LOCK_PATH "/tmp/ipsd-gige-emulator.lock"

/* Whether a socket of another process is bound to 127.0.0.1:3956. */
static inline int gige_port_taken(void)
{
    int s = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons(3956)};
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    int taken = s >= 0 && bind(s, (struct sockaddr *)&a, sizeof a) < 0 && errno == EADDRINUSE;
    if (s >= 0) close(s);
    return taken;
}

/* Waits until no other process holds the lock, then holds it until this process ends, and waits
 * (up to 300 s) until no process that ignores the lock has the port. Returns 0, or -1 (with a
 * message on stderr) when the lock file cannot be opened. */
static inline int gige_lock(void)
{
    int fd = open(GIGE_LOCK_PATH, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) {
        perror("gige_lock: " GIGE_LOCK_PATH);
        return -1;
    }
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        fprintf(stderr, "gige_lock: another test runs a GigE Vision emulator on port 3956: waiting "
                        "for it (" GIGE_LOCK_PATH ")\n");
        while (flock(fd, LOCK_EX) < 0)
            if (errno != EINTR) {
                perror("gige_lock: flock");
                return -1;
            }
    }
    if (gige_port_taken())
        fprintf(stderr, "gige_lock: port 3956 of 127.0.0.1 is bound by a process without the "
                        "lock: waiting for it to end\n");
    for (int i = 0; i < 3000 && gige_port_taken(); i++)
        nanosleep(&(struct timespec){0, 100000000}, NULL); /* 0.1 s */
    return 0;
}

#endif
