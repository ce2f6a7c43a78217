/* base/utf8.h: making text that came from outside (URLs, query strings, request bodies cut to a
 * buffer's size) safe to put into JSON: jansson refuses strings that are not valid UTF-8, so an
 * error message quoting hostile input would otherwise be lost. */
#ifndef IPSD_BASE_UTF8_H
#define IPSD_BASE_UTF8_H

#include <stddef.h>

/* Rewrites s in place into valid UTF-8 (RFC 3629: no overlong forms, no surrogates, nothing above
 * U+10FFFF): each byte that does not begin a valid sequence becomes '?', and a sequence cut off
 * by the end of the string is dropped. Never makes s longer. Returns the number of bytes
 * replaced or dropped (0: s was valid). */
size_t utf8_sanitize(char *s);

#endif
