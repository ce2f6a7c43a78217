/* cliutil.c: the one-line error reporting of the `ips` commands. */
#include "cliutil.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>

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
