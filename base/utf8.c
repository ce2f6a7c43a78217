/* utf8.c: UTF-8 validation and repair (utf8.h). Hand-written: neither libc nor jansson exposes a
 * validator (jansson's is internal), and the rules fit in one table-free function. */
#include "base/utf8.h"

#include <string.h>

/* Length of the valid sequence starting at p (n bytes available), or 0 if it is not one. The
 * ranges of the second byte are RFC 3629's table: E0 A0..BF, ED 80..9F, F0 90..BF, F4 80..8F. */
static size_t valid_len(const unsigned char *p, size_t n)
{
    unsigned char c = p[0];
    size_t len;
    unsigned char lo = 0x80, hi = 0xBF;
    if (c < 0x80) return 1;
    if (c >= 0xC2 && c <= 0xDF) len = 2;
    else if (c >= 0xE0 && c <= 0xEF) {
        len = 3;
        if (c == 0xE0) lo = 0xA0;
        if (c == 0xED) hi = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
        len = 4;
        if (c == 0xF0) lo = 0x90;
        if (c == 0xF4) hi = 0x8F;
    } else
        return 0;
    if (n < len) return 0;
    if (p[1] < lo || p[1] > hi) return 0;
    for (size_t i = 2; i < len; i++)
        if (p[i] < 0x80 || p[i] > 0xBF) return 0;
    return len;
}

/* A valid start of a sequence that the end of the string cuts off (truncation by a buffer). */
static int cut_short(const unsigned char *p, size_t n)
{
    unsigned char c = p[0];
    size_t need = c >= 0xF0 && c <= 0xF4 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 ? 2 : 0;
    if (need == 0 || n >= need) return 0;
    for (size_t i = 1; i < n; i++)
        if (p[i] < 0x80 || p[i] > 0xBF) return 0;
    return 1;
}

size_t utf8_sanitize(char *s)
{
    unsigned char *p = (unsigned char *)s;
    size_t n = strlen(s), fixed = 0, i = 0;
    while (i < n) {
        size_t len = valid_len(p + i, n - i);
        if (len) {
            i += len;
            continue;
        }
        if (cut_short(p + i, n - i)) {
            fixed += n - i;
            p[i] = 0;
            break;
        }
        p[i++] = '?';
        fixed++;
    }
    return fixed;
}
