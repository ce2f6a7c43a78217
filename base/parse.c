/* base/parse.c: strict number parsing over strtod / strtoll (see base/parse.h). */
#include "base/parse.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>

int parse_double(const char *text, double *v)
{
    char *end;
    errno = 0;
    double d = strtod(text, &end);
    if (end == text || *end != '\0' || errno == ERANGE || !isfinite(d)) return -EINVAL;
    *v = d;
    return 0;
}

int parse_ll(const char *text, long long *v)
{
    char *end;
    errno = 0;
    long long l = strtoll(text, &end, 10);
    if (end == text || *end != '\0' || errno == ERANGE) return -EINVAL;
    *v = l;
    return 0;
}

int parse_int(const char *text, int *v)
{
    long long l;
    if (parse_ll(text, &l) || l < INT_MIN || l > INT_MAX) return -EINVAL;
    *v = (int)l;
    return 0;
}
