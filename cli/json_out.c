/* json_out.c: JSON output helpers of the `ips` commands (see json_out.h). */
#include "json_out.h"

#include <errno.h>
#include <math.h>

json_t *json_out_num(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

json_t *json_out_array(const double *v, size_t n)
{
    if (!v) return json_null();
    json_t *a = json_array();
    for (size_t k = 0; a && k < n; k++) json_array_append_new(a, json_out_num(v[k]));
    return a;
}

json_t *json_out_int_or_null(int v)
{
    return v ? json_integer(v) : json_null();
}

int json_out_print(const json_t *root, FILE *f)
{
    if (json_dumpf(root, f, JSON_INDENT(2) | JSON_REAL_PRECISION(17)) || fputc('\n', f) == EOF ||
        fflush(f) == EOF)
        return -EIO;
    return 0;
}
