/* base/err.h: the error out-parameter every room uses: a fixed-size human message next to the
 * negative int a function returns (like jansson's json_error_t). Callers may pass NULL. */
#ifndef IPSD_BASE_ERR_H
#define IPSD_BASE_ERR_H

#include <stdarg.h>

#ifdef __cplusplus
extern "C" { /* the libcamera shim is C++ */
#endif

typedef struct err {
    char msg[256]; /* one line, no trailing newline */
} err_t;

/* Formats into err->msg when err is not NULL; returns code so callers can `return err_set(...)`. */
int err_set(err_t *err, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#ifdef __cplusplus
}
#endif

#endif
