/* stage_link.c: TCP and serial byte streams for stage controllers (stage_link.h): non-blocking
 * descriptors, poll() for every wait, a small read buffer that splits lines. */
#include "stage_link.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "base/clock.h"

struct stage_link {
    int fd;
    char buf[4096]; /* bytes read but not yet returned */
    size_t len;
    char name[300]; /* for messages: "host:port" or the device */
};

/* Waits until fd is ready for events or the deadline (CLOCK_MONOTONIC seconds) passes.
 * Returns 0, or -ETIMEDOUT, -EIO. */
static int wait_fd(int fd, short events, double deadline)
{
    for (;;) {
        double left = deadline - clock_mono_s();
        if (left <= 0) return -ETIMEDOUT;
        struct pollfd p = {.fd = fd, .events = events};
        int r = poll(&p, 1, (int)(left * 1000) + 1);
        if (r > 0) return 0;  /* readable, writable, or hung up: the read or write says which */
        if (r == 0) continue; /* rounding: the loop checks the deadline again */
        if (errno != EINTR) return -EIO;
    }
}

static int open_tcp(const stage_url_t *u, stage_link_t *l, err_t *err)
{
    char port[8];
    snprintf(port, sizeof port, "%d", u->port);
    struct addrinfo hints = {.ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM}, *res;
    int g = getaddrinfo(u->host, port, &hints, &res);
    if (g) return err_set(err, -ENOENT, "stage controller %s: %s", l->name, gai_strerror(g));
    int ret = -ECONNREFUSED;
    double deadline = clock_mono_s() + u->timeout_s;
    for (struct addrinfo *a = res; a; a = a->ai_next) {
        int fd = socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
        if (fd < 0) continue;
        int rc = connect(fd, a->ai_addr, a->ai_addrlen);
        if (rc < 0 && errno == EINPROGRESS) {
            rc = wait_fd(fd, POLLOUT, deadline);
            int soerr = 0;
            socklen_t sl = sizeof soerr;
            if (rc == 0 && getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) == 0 && soerr) {
                errno = soerr;
                rc = -1;
            }
            if (rc == -ETIMEDOUT) ret = -ETIMEDOUT;
        }
        if (rc == 0) {
            int one = 1; /* short command lines: send each at once */
            setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
            l->fd = fd;
            freeaddrinfo(res);
            return 0;
        }
        close(fd);
    }
    freeaddrinfo(res);
    return err_set(err, ret, "stage controller %s: %s", l->name,
                   ret == -ETIMEDOUT ? "no connection within the timeout" : "connection refused");
}

static speed_t speed_of(int baud)
{
    switch (baud) {
    case 9600:
        return B9600;
    case 19200:
        return B19200;
    case 38400:
        return B38400;
    case 57600:
        return B57600;
    case 230400:
        return B230400;
    case 460800:
        return B460800;
    default:
        return B115200;
    }
}

static int open_serial(const stage_url_t *u, stage_link_t *l, err_t *err)
{
    int fd = open(u->device, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return err_set(err, errno == ENOENT ? -ENOENT : -EIO, "stage controller %s: %s", l->name,
                       strerror(errno));
    struct termios t;
    if (tcgetattr(fd, &t)) {
        int e = errno;
        close(fd);
        return err_set(err, -EIO, "stage controller %s: not a serial line (%s)", l->name,
                       strerror(e));
    }
    cfmakeraw(&t); /* 8 data bits, no parity, no echo, no line editing */
    t.c_cflag |= CLOCAL | CREAD;
    t.c_cflag &= ~(tcflag_t)(CSTOPB | CRTSCTS);
    cfsetispeed(&t, speed_of(u->baud));
    cfsetospeed(&t, speed_of(u->baud));
    if (tcsetattr(fd, TCSANOW, &t)) {
        int e = errno;
        close(fd);
        return err_set(err, -EIO, "stage controller %s: cannot set the line (%s)", l->name,
                       strerror(e));
    }
    tcflush(fd, TCIOFLUSH); /* nothing stale from before we opened */
    l->fd = fd;
    return 0;
}

int stage_link_open(const stage_url_t *u, stage_link_t **out, err_t *err)
{
    *out = NULL;
    stage_link_t *l = calloc(1, sizeof *l);
    if (!l) return err_set(err, -ENOMEM, "out of memory for the stage link");
    l->fd = -1;
    if (u->link == STAGE_LINK_TCP)
        snprintf(l->name, sizeof l->name, "tcp://%s:%d", u->host, u->port);
    else
        snprintf(l->name, sizeof l->name, "%s", u->device);
    int ret = u->link == STAGE_LINK_TCP ? open_tcp(u, l, err) : open_serial(u, l, err);
    if (ret) {
        free(l);
        return ret;
    }
    *out = l;
    return 0;
}

void stage_link_close(stage_link_t *l)
{
    if (!l) return;
    if (l->fd >= 0) close(l->fd);
    free(l);
}

int stage_link_send(stage_link_t *l, const char *line, err_t *err)
{
    size_t n = strlen(line);
    char out[1100];
    if (n + 1 > sizeof out) return err_set(err, -EINVAL, "stage command too long");
    memcpy(out, line, n);
    out[n++] = '\n';
    double deadline = clock_mono_s() + 5;
    for (size_t done = 0; done < n;) {
        ssize_t w = send(l->fd, out + done, n - done, MSG_NOSIGNAL);
        if (w < 0 && errno == ENOTSOCK) w = write(l->fd, out + done, n - done);
        if (w > 0) {
            done += (size_t)w;
            continue;
        }
        if (w < 0 && errno == EINTR) continue;
        if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            int rc = wait_fd(l->fd, POLLOUT, deadline);
            if (rc)
                return err_set(err, rc, "stage controller %s: %s", l->name,
                               rc == -ETIMEDOUT ? "does not take commands" : "write failed");
            continue;
        }
        return err_set(err, -EIO, "stage controller %s: connection lost while sending (%s)",
                       l->name, w < 0 ? strerror(errno) : "nothing written");
    }
    return 0;
}

int stage_link_read_line(stage_link_t *l, char *buf, size_t n, double timeout_s, err_t *err)
{
    double deadline = clock_mono_s() + timeout_s;
    for (;;) {
        char *lf = memchr(l->buf, '\n', l->len);
        if (lf) {
            size_t len = (size_t)(lf - l->buf), used = len + 1;
            if (len > 0 && l->buf[len - 1] == '\r') len--;
            int ret = (int)len;
            if (len >= n) {
                ret = err_set(err, -EOVERFLOW, "stage controller %s: reply line too long", l->name);
            } else {
                memcpy(buf, l->buf, len);
                buf[len] = 0;
            }
            memmove(l->buf, l->buf + used, l->len - used);
            l->len -= used;
            return ret;
        }
        if (l->len == sizeof l->buf)
            return err_set(err, -EOVERFLOW, "stage controller %s: reply line too long", l->name);
        ssize_t r = read(l->fd, l->buf + l->len, sizeof l->buf - l->len);
        if (r > 0) {
            l->len += (size_t)r;
            continue;
        }
        if (r == 0)
            return err_set(err, -EIO, "stage controller %s: connection closed by the controller",
                           l->name);
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK)
            return err_set(err, -EIO, "stage controller %s: connection lost (%s)", l->name,
                           strerror(errno));
        int rc = wait_fd(l->fd, POLLIN, deadline);
        if (rc)
            return err_set(err, rc, "stage controller %s: %s", l->name,
                           rc == -ETIMEDOUT ? "no reply within the timeout" : "read failed");
    }
}

int stage_link_broken(int ret)
{
    return ret == -EIO || ret == -ETIMEDOUT || ret == -EOVERFLOW;
}

void stage_link_pause_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    while (ms > 0 && nanosleep(&ts, &ts) && errno == EINTR) {
    }
}
