/* api_static.c: the dashboard's static files. Only regular files under the web directory are
 * served: "/" is index.html, "/web/PATH" and "/PATH" are PATH in that directory; the resolved
 * path (realpath, so "..", symlinks and encoded dots are all seen through) must stay inside the
 * directory (else 403). */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "api_int.h"

static const char *content_type(const char *path)
{
    static const struct {
        const char *ext, *type;
    } types[] = {
        {".html", "text/html; charset=utf-8"},
        {".js", "text/javascript; charset=utf-8"},
        {".mjs", "text/javascript; charset=utf-8"},
        {".css", "text/css; charset=utf-8"},
        {".json", "application/json"},
        {".svg", "image/svg+xml"},
        {".png", "image/png"},
        {".ico", "image/x-icon"},
        {".txt", "text/plain; charset=utf-8"},
        {".map", "application/json"},
        {".woff2", "font/woff2"},
    };
    const char *dot = strrchr(path, '.');
    for (size_t i = 0; dot && i < sizeof types / sizeof types[0]; i++)
        if (strcasecmp(dot, types[i].ext) == 0) return types[i].type;
    return "application/octet-stream";
}

void api_h_static(api_req_t *q, const char *url)
{
    char root[PATH_MAX], path[2 * PATH_MAX], real[PATH_MAX];
    const char *rel = url;
    if (strncmp(rel, "/web/", 5) == 0)
        rel += 4;
    else if (strcmp(rel, "/web") == 0)
        rel = "/";
    if (strcmp(rel, "/") == 0) rel = "/index.html";
    if (!realpath(srv_config(q->srv)->web_dir, root)) {
        api_error(q, 404, "not_found", NULL, "no web directory (%s)", srv_config(q->srv)->web_dir);
        return;
    }
    snprintf(path, sizeof path, "%s%s", root, rel);
    if (!realpath(path, real)) {
        api_error(q, 404, "not_found", NULL, "no such file: %s", url);
        return;
    }
    size_t n = strlen(root);
    if (strncmp(real, root, n) != 0 || real[n] != '/') {
        api_error(q, 403, "forbidden", NULL, "%s is outside the web directory", url);
        return;
    }
    /* O_NONBLOCK: a FIFO (or device) in the directory must not block the HTTP thread in open();
     * the fstat below then refuses anything but a regular file (for which O_NONBLOCK is moot) */
    int fd = open(real, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    struct stat sb;
    if (fd < 0 || fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        if (fd >= 0) close(fd);
        api_error(q, 404, "not_found", NULL, "no such file: %s", url);
        return;
    }
    /* libmicrohttpd owns fd from here and closes it with the response */
    q->resp = MHD_create_response_from_fd((uint64_t)sb.st_size, fd);
    if (!q->resp) {
        close(fd);
        api_error(q, 500, "internal", NULL, "out of memory");
        return;
    }
    q->status = 200;
    q->resp_bytes = (long long)sb.st_size;
    MHD_add_response_header(q->resp, MHD_HTTP_HEADER_CONTENT_TYPE, content_type(real));
}
