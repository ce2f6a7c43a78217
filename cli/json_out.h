/* json_out.h: jansson helpers for the commands' JSON output: numbers at full precision with
 * non-finite values as null (JSON has no NaN), arrays of doubles, and printing. */
#ifndef IPSD_CLI_JSON_OUT_H
#define IPSD_CLI_JSON_OUT_H

#include <stddef.h>
#include <stdio.h>

#include <jansson.h>

/* A new JSON real, or null when v is not finite. Owned by the caller (give it to jansson with
 * a _set_new / _append_new). */
json_t *json_out_num(double v);

/* A new JSON array of n numbers (non-finite as null), or null when v is NULL. Owned by caller. */
json_t *json_out_array(const double *v, size_t n);

/* A new JSON int, or null when v is 0 (for "no such r" answers). Owned by the caller. */
json_t *json_out_int_or_null(int v);

/* Prints root to f, indented, every real with 17 significant digits, and a newline.
 * Returns 0 or -EIO. root stays the caller's. */
int json_out_print(const json_t *root, FILE *f);

#endif
