/* fitshdr.c: the FITS standard's card syntax (4.0, section 4.1-4.2), checked on every header of
 * a file before cfitsio parses it. Hand-written because cfitsio trusts it: Debian's cfitsio 4.2
 * copies an unquoted 70-character value of a table keyword (TTYPE1 = AAAA...) into a smaller
 * buffer, and its _FORTIFY_SOURCE build then aborts the whole process, so a FITS upload could
 * stop ipsd. A header here is 2880-byte blocks of 80-byte cards up to the END card; an HDU's data
 * is |BITPIX| / 8 * GCOUNT * (PCOUNT + NAXIS1 * ... * NAXISn) bytes padded to whole blocks. */
#include "fitshdr.h"

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define BLOCK 2880
#define CARD 80

/* The digits at *p (at least one), moved past. */
static int digits(const char **p, const char *end)
{
    const char *s = *p;
    while (*p < end && **p >= '0' && **p <= '9') (*p)++;
    return *p > s;
}

/* A FITS integer or real ([+-] digits [. digits] [E|D [+-] digits], or [+-] . digits ...). */
static int number(const char **p, const char *end)
{
    if (*p < end && (**p == '+' || **p == '-')) (*p)++;
    int whole = digits(p, end), frac = 0;
    if (*p < end && **p == '.') {
        (*p)++;
        frac = digits(p, end);
    }
    if (!whole && !frac) return 0;
    if (*p < end && (**p == 'E' || **p == 'e' || **p == 'D' || **p == 'd')) {
        (*p)++;
        if (*p < end && (**p == '+' || **p == '-')) (*p)++;
        if (!digits(p, end)) return 0;
    }
    return 1;
}

static void spaces(const char **p, const char *end)
{
    while (*p < end && **p == ' ') (*p)++;
}

/* The value field [p, end) of a card with a value indicator: nothing, a quoted string ('' is a
 * quote inside it), T or F, a number, or (number, number); then spaces and an optional
 * comment. NULL when it is valid, else what is wrong. */
static const char *value_error(const char *p, const char *end)
{
    spaces(&p, end);
    if (p == end || *p == '/') return NULL; /* an undefined value */
    if (*p == '\'') {
        for (p++;; p++) {
            if (p == end) return "a string value without its closing quote";
            if (*p == '\'') {
                if (p + 1 < end && p[1] == '\'') {
                    p++;
                    continue;
                }
                p++;
                break;
            }
        }
    } else if (*p == 'T' || *p == 'F') {
        p++;
    } else if (*p == '(') {
        p++;
        spaces(&p, end);
        if (!number(&p, end)) return "a complex value whose real part is not a number";
        spaces(&p, end);
        if (p == end || *p++ != ',') return "a complex value without its comma";
        spaces(&p, end);
        if (!number(&p, end)) return "a complex value whose imaginary part is not a number";
        spaces(&p, end);
        if (p == end || *p++ != ')') return "a complex value without its closing parenthesis";
    } else if (!number(&p, end)) {
        return "a value that is not a quoted string, T, F, a number or a complex number";
    }
    spaces(&p, end);
    return p == end || *p == '/' ? NULL : "text after the value that is not a / comment";
}

/* The integer value of card c ([+-] digits, then spaces and an optional comment), or
 * INT64_MIN when it is not one or its size is past 2^62. */
static long long int_value(const char *c)
{
    const char *p = c + 10, *end = c + CARD;
    spaces(&p, end);
    int neg = p < end && *p == '-';
    if (p < end && (*p == '+' || *p == '-')) p++;
    long long v = 0;
    const char *s = p;
    while (p < end && *p >= '0' && *p <= '9') {
        if (v > (INT64_C(1) << 62) / 10) return INT64_MIN;
        v = v * 10 + (*p++ - '0');
    }
    spaces(&p, end);
    if (p == s || (p < end && *p != '/')) return INT64_MIN;
    return neg ? -v : v;
}

/* The size of one HDU's data from its header's keywords. */
struct sizing {
    long long bitpix, naxis, pcount, gcount;
    long long axis[1000]; /* NAXISn, n = 1..999 */
    int extension;
};

static int keyword_is(const char *c, const char *name)
{
    size_t n = strlen(name);
    if (memcmp(c, name, n) != 0) return 0;
    for (size_t i = n; i < 8; i++)
        if (c[i] != ' ') return 0;
    return 1;
}

static void note_size(const char *c, struct sizing *z)
{
    if (c[8] != '=' || c[9] != ' ') return;
    if (keyword_is(c, "BITPIX")) {
        z->bitpix = int_value(c);
    } else if (keyword_is(c, "NAXIS")) {
        z->naxis = int_value(c);
    } else if (keyword_is(c, "PCOUNT")) {
        z->pcount = int_value(c);
    } else if (keyword_is(c, "GCOUNT")) {
        z->gcount = int_value(c);
    } else if (!memcmp(c, "NAXIS", 5)) {
        char *e;
        long n = strtol(c + 5, &e, 10);
        if (e > c + 5 && e <= c + 8 && n >= 1 && n <= 999 && (e == c + 8 || *e == ' '))
            z->axis[n] = int_value(c);
    }
}

/* The data bytes the header sized (padded to whole blocks), or -1 when it did not say. */
static double data_bytes(const struct sizing *z)
{
    long long b = z->bitpix;
    if (b == -32 || b == -64) b = -b;
    if ((b != 8 && b != 16 && b != 32 && b != 64) || z->naxis < 0 || z->naxis > 999 ||
        z->pcount < 0 || z->gcount < 0)
        return -1;
    double n = 0;
    if (z->naxis > 0) {
        /* random groups (NAXIS1 = 0 in a primary) count from NAXIS2 */
        n = 1;
        for (long long a = 1; a <= z->naxis; a++) {
            if (z->axis[a] < 0) return -1;
            if (!(a == 1 && z->axis[a] == 0 && !z->extension && z->gcount > 0)) n *= (double)z->axis[a];
        }
    }
    double bytes = (double)(b / 8) * (double)z->gcount * ((double)z->pcount + n);
    return bytes == 0 ? 0 : (double)BLOCK * (double)(((long long)(bytes + BLOCK - 1)) / BLOCK);
}

int fitshdr_check(const unsigned char *buf, size_t len, err_t *err)
{
    size_t at = 0;
    static struct sizing zero;
    for (int hdu = 1; at < len; hdu++) {
        if (hdu > 1 && (len - at < 9 || memcmp(buf + at, "XTENSION=", 9) != 0))
            return 0; /* not another extension: cfitsio reads no header there */
        struct sizing *z = malloc(sizeof *z);
        if (!z) return err_set(err, -ENOMEM, "out of memory checking the FITS headers");
        *z = zero;
        z->gcount = 1;
        z->bitpix = z->naxis = -1;
        z->extension = hdu > 1;
        for (long long a = 0; a < 1000; a++) z->axis[a] = -1;
        int ended = 0;
        size_t card = 0;
        for (; !ended && at + CARD <= len; at += CARD, card++) {
            const char *c = (const char *)buf + at;
            for (int i = 0; i < CARD; i++)
                if ((unsigned char)c[i] < 0x20 || (unsigned char)c[i] > 0x7e) {
                    free(z);
                    return err_set(err, -EINVAL,
                                   "HDU %d, header card %zu: byte %d is not printable ASCII "
                                   "(0x%02x): not a FITS header", hdu, card + 1, i + 1,
                                   (unsigned char)c[i]);
                }
            const char *value = NULL;
            if (c[8] == '=' && c[9] == ' ')
                value = c + 10;
            else if (!memcmp(c, "HIERARCH ", 9)) /* cfitsio reads the value after the first = */
                value = memchr(c + 9, '=', CARD - 9), value = value ? value + 1 : NULL;
            const char *why = value ? value_error(value, c + CARD) : NULL;
            if (why) {
                free(z);
                return err_set(err, -EINVAL, "HDU %d, header card %zu (%.8s): %s", hdu,
                               card + 1, c, why);
            }
            if (keyword_is(c, "END")) ended = 1;
            note_size(c, z);
        }
        if (!ended) {
            free(z);
            return err_set(err, -EINVAL, "HDU %d's header has no END card before the file ends "
                                         "(cut short?)", hdu);
        }
        at = (at + BLOCK - 1) / BLOCK * BLOCK; /* the header's last block is padding */
        double bytes = data_bytes(z);
        free(z);
        if (bytes < 0 || (double)at + bytes > (double)len) return 0; /* cfitsio's to judge */
        at += (size_t)bytes;
    }
    return 0;
}
