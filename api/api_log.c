/* api_log.c: the request log (api_log.h). Hand-written: libmicrohttpd has no access log, and the
 * line is a handful of fields. */
#include "api_log.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

int api_log_open(const char *access_log, int *fd, err_t *err)
{
    *fd = -1;
    if (!access_log[0]) {
        *fd = STDERR_FILENO;
        return 0;
    }
    if (strcmp(access_log, "off") == 0) return 0;
    *fd = open(access_log, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0640);
    if (*fd < 0)
        return err_set(err, -errno, "--access-log: cannot open %s: %s", access_log,
                       strerror(errno));
    return 0;
}

int api_log_reopen(const char *access_log, int fd, err_t *err)
{
    if (fd <= STDERR_FILENO) return 0;
    int nfd, ret = api_log_open(access_log, &nfd, err);
    if (ret) return ret;
    if (dup2(nfd, fd) < 0)
        ret = err_set(err, -errno, "--access-log: %s", strerror(errno));
    else
        fcntl(fd, F_SETFD, FD_CLOEXEC); /* dup2 cleared it */
    close(nfd);
    return ret;
}

void api_log_close(int fd)
{
    if (fd > STDERR_FILENO) close(fd);
}

void api_log_escape(const char *in, char *out, size_t n)
{
    static const char hex[] = "0123456789ABCDEF";
    size_t w = 0;
    for (const unsigned char *p = (const unsigned char *)in; *p; p++) {
        int plain = *p > 0x20 && *p < 0x7f && *p != '%' && *p != '"' && *p != '\\';
        size_t need = plain ? 1 : 3;
        if (w + need + 4 > n) { /* room for "..." and the NUL */
            memcpy(out + w, "...", 3);
            w += 3;
            break;
        }
        if (plain) {
            out[w++] = (char)*p;
        } else {
            out[w++] = '%';
            out[w++] = hex[*p >> 4];
            out[w++] = hex[*p & 15];
        }
    }
    out[w] = 0;
}

/* The peer's numeric address, "-" when unknown. */
static void client_addr(struct MHD_Connection *conn, char *out, size_t n)
{
    const union MHD_ConnectionInfo *ci =
        conn ? MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CLIENT_ADDRESS) : NULL;
    const struct sockaddr *sa = ci ? ci->client_addr : NULL;
    snprintf(out, n, "-");
    if (sa && sa->sa_family == AF_INET)
        inet_ntop(AF_INET, &((const struct sockaddr_in *)sa)->sin_addr, out, (socklen_t)n);
    else if (sa && sa->sa_family == AF_INET6)
        inet_ntop(AF_INET6, &((const struct sockaddr_in6 *)sa)->sin6_addr, out, (socklen_t)n);
}

void api_log_request(int fd, struct MHD_Connection *conn, const char *method, const char *path,
                     unsigned status, long long bytes, const struct timespec *t0, int aborted)
{
    if (fd < 0) return;
    struct timespec now, wall;
    clock_gettime(CLOCK_MONOTONIC, &now);
    clock_gettime(CLOCK_REALTIME, &wall);
    double ms = (double)(now.tv_sec - t0->tv_sec) * 1e3 + (double)(now.tv_nsec - t0->tv_nsec) / 1e6;
    struct tm tm;
    char when[32], addr[INET6_ADDRSTRLEN + 1], size[24], line[800];
    strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%S", gmtime_r(&wall.tv_sec, &tm));
    client_addr(conn, addr, sizeof addr);
    if (bytes >= 0)
        snprintf(size, sizeof size, "%lld", bytes);
    else
        snprintf(size, sizeof size, "-");
    int len = snprintf(line, sizeof line, "%s.%03ldZ %s %s %s %u %s %.2fms%s\n", when,
                       wall.tv_nsec / 1000000, addr, method ? method : "-", path ? path : "-",
                       status, size, ms, aborted ? " aborted" : "");
    if (len <= 0) return;
    if ((size_t)len >= sizeof line) len = (int)sizeof line - 1;
    ssize_t w = write(fd, line, (size_t)len);
    (void)w; /* a full disk loses log lines, never requests */
}
