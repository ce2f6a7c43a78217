/* jdump.h: jansson's json_dumps / json_dumpf with JSON_REAL_PRECISION(17), the same bytes, with
 * reals printed by base/g17.h instead of snprintf (the number printing was a fifth of the
 * reference `ips fit` job's instructions). Same output rules: indentation and separators of
 * JSON_INDENT(n) and JSON_COMPACT, keys in the object's order, jansson's string escapes (", \,
 * control characters; UTF-8 passed through) and its real form (".0" added to an integral value,
 * no '+' nor leading zeros in the exponent). Only arrays or objects at the top, as json_dumps
 * without JSON_ENCODE_ANY. */
#ifndef IPSD_JSON_JDUMP_H
#define IPSD_JSON_JDUMP_H

#include <stdio.h>

#include <jansson.h>

#define JDUMP_COMPACT 0x100 /* with indent 0: "," and ":" without spaces (JSON_COMPACT) */

/* The text of root, as json_dumps(root, JSON_INDENT(flags & 31) | [JSON_COMPACT] |
 * JSON_REAL_PRECISION(17)) makes it; free() it. NULL when out of memory or root cannot be
 * dumped (not an array or object, a string that is not UTF-8, a value of no known type). */
char *jdump_string(const json_t *root, unsigned flags);

/* The same text written to f (json_dumpf). Returns 0, or -1 (nothing or part written). */
int jdump_file(const json_t *root, FILE *f, unsigned flags);

#endif
