/* base/err.c: formatting of the error out-parameter (see base/err.h). */
#include "base/err.h"

#include <stdio.h>

int err_set(err_t *err, int code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}
