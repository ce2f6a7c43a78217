/* api_static.c: the dashboard's static files. Only regular files under the web directory are
 * served: "/" is index.html, "/web/PATH" and "/PATH" are PATH in that directory; the resolved
 * path (realpath, so "..", symlinks and encoded dots are all seen through) must stay inside the
 * directory (else 403).
 * Caching (RFC 9110 8.8.3, 13.1.2; RFC 9111 5.2.2): every file carries an ETag made of its size
 * and modification time (nanoseconds), and a request whose If-None-Match names it gets 304 with
 * no body. Files under node_modules/ (the pinned plotting library, 4.8 MB, loaded by index.html
 * with its version in the query, ?v=X.Y.Z) are cached for a year without asking again; every
 * other file (index.html, the modules, the style) is "no-cache": the browser asks each time and
 * gets 304 while the file is unchanged, so an edit shows at the next reload. */
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

/* One year, the longest max-age RFC 9111 5.2.2.1 advises caches to honour. */
#define STATIC_IMMUTABLE_MAX_AGE "31536000"

/* The ETag of a file: its size and modification time (hex), quoted (RFC 9110 8.8.3). */
static void file_etag(const struct stat *sb, char *out, size_t n)
{
    snprintf(out, n, "\"%llx-%llx.%lx\"", (unsigned long long)sb->st_size,
             (unsigned long long)sb->st_mtim.tv_sec, (unsigned long)sb->st_mtim.tv_nsec);
}

/* 1 when the If-None-Match list (RFC 9110 13.1.2: "*" or comma-separated entity tags, weak
 * ones compared weakly) names etag. */
static int etag_matches(const char *list, const char *etag)
{
    if (!list) return 0;
    size_t n = strlen(etag);
    for (const char *p = list; *p;) {
        while (*p == ' ' || *p == '\t' || *p == ',') p++;
        if (!*p) break;
        const char *e = p;
        while (*e && *e != ',') e++;
        const char *end = e;
        while (end > p && (end[-1] == ' ' || end[-1] == '\t')) end--;
        if (end - p == 1 && *p == '*') return 1;
        if (end - p >= 2 && strncmp(p, "W/", 2) == 0) p += 2;
        if ((size_t)(end - p) == n && strncmp(p, etag, n) == 0) return 1;
        p = e;
    }
    return 0;
}

/* The caching headers of a file served as rel (its path under the web directory). */
static void cache_headers(struct MHD_Response *resp, const char *rel, const char *etag)
{
    int versioned = strncmp(rel, "/node_modules/", 14) == 0;
    MHD_add_response_header(resp, MHD_HTTP_HEADER_ETAG, etag);
    MHD_add_response_header(resp, MHD_HTTP_HEADER_CACHE_CONTROL,
                            versioned ? "public, max-age=" STATIC_IMMUTABLE_MAX_AGE ", immutable"
                                      : "no-cache");
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
    char etag[96];
    file_etag(&sb, etag, sizeof etag);
    if (etag_matches(MHD_lookup_connection_value(q->conn, MHD_HEADER_KIND,
                                                 MHD_HTTP_HEADER_IF_NONE_MATCH),
                     etag)) {
        close(fd);
        q->resp = MHD_create_response_from_buffer(0, NULL, MHD_RESPMEM_PERSISTENT);
        if (!q->resp) {
            api_error(q, 500, "internal", NULL, "out of memory");
            return;
        }
        q->status = 304;
        q->resp_bytes = 0;
        cache_headers(q->resp, real + n, etag);
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
    cache_headers(q->resp, real + n, etag);
}
