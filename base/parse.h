/* base/parse.h: strict parsing of numbers written by people (command-line options, query
 * strings, path segments): the whole text must be the number, with no trailing text, no overflow
 * and, for doubles, a finite value. */
#ifndef IPSD_BASE_PARSE_H
#define IPSD_BASE_PARSE_H

/* Parses all of text as a finite double. Returns 0, or -EINVAL (not a number, trailing text,
 * empty, overflow, NaN or infinity); *v is untouched on error. */
int parse_double(const char *text, double *v);

/* Parses all of text as a decimal integer (optional sign). Returns 0 or -EINVAL (also outside
 * the type's range). */
int parse_ll(const char *text, long long *v);
int parse_int(const char *text, int *v);

#endif
