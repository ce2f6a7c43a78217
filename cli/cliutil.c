/* cliutil.c: error reporting, number parsing and the clock for the `ips` commands. */
#include "cliutil.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

int cli_fail(int code, const char *cmd, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (char *c = msg; *c; c++)
        if (*c == '\n' || *c == '\r') *c = ' ';
    fprintf(stderr, "ips%s%s: %s\n", cmd ? " " : "", cmd ? cmd : "", msg);
    return code;
}

int cli_exit_code(int rc)
{
    return rc == -ENOMEM || rc == -EIO ? CLI_EXIT_FAILURE : CLI_EXIT_USAGE;
}

int cli_parse_double(const char *text, double *v)
{
    char *end;
    errno = 0;
    double d = strtod(text, &end);
    if (end == text || *end != '\0' || errno == ERANGE || !isfinite(d)) return -EINVAL;
    *v = d;
    return 0;
}

int cli_parse_int(const char *text, int *v)
{
    char *end;
    errno = 0;
    long l = strtol(text, &end, 10);
    if (end == text || *end != '\0' || errno == ERANGE || l < INT_MIN || l > INT_MAX)
        return -EINVAL;
    *v = (int)l;
    return 0;
}

double cli_now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}
