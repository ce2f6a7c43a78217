/* jdump.c: jansson's dump with reals by base/g17.h (see jdump.h). The walk follows jansson's
 * do_dump (dump.c of jansson 2.14) rule for rule: an indent is a newline and depth * n spaces; an
 * empty array or object is "[]" / "{}"; between members "," and then the indent (or " " when not
 * indenting and not compact); a key and its value are separated by ": " (":" compact). The text is
 * built in one buffer and written once. tests/test_jdump.c compares it with json_dumps. */
#include "json/jdump.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/g17.h"

struct buf {
    char *p;
    size_t n, cap;
    int fail;
};

static int grow(struct buf *b, size_t more)
{
    if (b->fail) return -1;
    if (b->n + more <= b->cap) return 0;
    size_t cap = b->cap ? b->cap : 4096;
    while (cap < b->n + more) cap *= 2;
    char *p = realloc(b->p, cap);
    if (!p) {
        b->fail = 1;
        return -1;
    }
    b->p = p;
    b->cap = cap;
    return 0;
}

static void put(struct buf *b, const char *s, size_t n)
{
    if (grow(b, n)) return;
    memcpy(b->p + b->n, s, n);
    b->n += n;
}

/* jansson's dump_indent */
static void indent(struct buf *b, unsigned flags, int depth, int space)
{
    unsigned ws = flags & 31;
    if (ws) {
        size_t n = (size_t)depth * ws;
        if (grow(b, n + 1)) return;
        b->p[b->n++] = '\n';
        memset(b->p + b->n, ' ', n);
        b->n += n;
    } else if (space && !(flags & JDUMP_COMPACT)) {
        put(b, " ", 1);
    }
}

/* Length of the valid UTF-8 sequence at s (RFC 3629, as jansson's utf8_iterate accepts), 0 if
 * invalid. */
static size_t utf8_len(const unsigned char *s, size_t left)
{
    unsigned c = s[0];
    size_t n;
    uint32_t cp;
    if (c < 0x80) return 1;
    if (c >= 0xC2 && c <= 0xDF) n = 2, cp = c & 0x1F;
    else if (c >= 0xE0 && c <= 0xEF) n = 3, cp = c & 0x0F;
    else if (c >= 0xF0 && c <= 0xF4) n = 4, cp = c & 0x07;
    else return 0;
    if (n > left) return 0;
    for (size_t i = 1; i < n; i++) {
        if ((s[i] & 0xC0) != 0x80) return 0;
        cp = (cp << 6) | (s[i] & 0x3F);
    }
    if (cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
    if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000)) return 0; /* overlong */
    return n;
}

/* jansson's dump_string without JSON_ENSURE_ASCII / JSON_ESCAPE_SLASH */
static void string(struct buf *b, const char *str, size_t len)
{
    static const char hex[] = "0123456789ABCDEF";
    const unsigned char *s = (const unsigned char *)str;
    put(b, "\"", 1);
    size_t run = 0;
    for (size_t i = 0; i < len;) {
        unsigned c = s[i];
        if (c >= 0x20 && c != '"' && c != '\\') {
            size_t n = c < 0x80 ? 1 : utf8_len(s + i, len - i);
            if (!n) {
                b->fail = 1;
                return;
            }
            i += n;
            run += n;
            continue;
        }
        put(b, str + i - run, run);
        run = 0;
        char esc[6] = {'\\', 0};
        size_t en = 2;
        switch (c) {
        case '"': esc[1] = '"'; break;
        case '\\': esc[1] = '\\'; break;
        case '\b': esc[1] = 'b'; break;
        case '\f': esc[1] = 'f'; break;
        case '\n': esc[1] = 'n'; break;
        case '\r': esc[1] = 'r'; break;
        case '\t': esc[1] = 't'; break;
        default: /* \u00XX */
            memcpy(esc + 1, "u00", 3);
            esc[4] = hex[c >> 4];
            esc[5] = hex[c & 15];
            en = 6;
        }
        put(b, esc, en);
        i++;
    }
    put(b, str + len - run, run);
    put(b, "\"", 1);
}

/* jansson's jsonp_dtostr at precision 17: "%.17g", ".0" appended when there is neither a point
 * nor an exponent, the exponent without '+' and leading zeros. */
static void real(struct buf *b, double v)
{
    char t[G17_MAX + 4];
    int n = g17_format(v, t);
    char *e = memchr(t, 'e', (size_t)n);
    if (!e && !memchr(t, '.', (size_t)n)) {
        t[n++] = '.';
        t[n++] = '0';
    } else if (e) {
        char *start = e + 1, *end = start + 1;
        if (*start == '-') start++;
        while (*end == '0') end++;
        if (end != start) {
            memmove(start, end, (size_t)(t + n - end));
            n -= (int)(end - start);
        }
    }
    put(b, t, (size_t)n);
}

static void integer(struct buf *b, json_int_t v)
{
    char t[24], *o = t + sizeof t;
    unsigned long long u = v < 0 ? 0ull - (unsigned long long)v : (unsigned long long)v;
    do {
        *--o = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    if (v < 0) *--o = '-';
    put(b, o, (size_t)(t + sizeof t - o));
}

static void value(struct buf *b, const json_t *j, unsigned flags, int depth)
{
    if (b->fail) return;
    switch (json_typeof(j)) {
    case JSON_NULL: put(b, "null", 4); return;
    case JSON_TRUE: put(b, "true", 4); return;
    case JSON_FALSE: put(b, "false", 5); return;
    case JSON_INTEGER: integer(b, json_integer_value(j)); return;
    case JSON_REAL: real(b, json_real_value(j)); return;
    case JSON_STRING: string(b, json_string_value(j), json_string_length(j)); return;
    case JSON_ARRAY: {
        size_t n = json_array_size(j);
        put(b, "[", 1);
        if (n == 0) {
            put(b, "]", 1);
            return;
        }
        indent(b, flags, depth + 1, 0);
        for (size_t i = 0; i < n; i++) {
            value(b, json_array_get(j, i), flags, depth + 1);
            if (i < n - 1) {
                put(b, ",", 1);
                indent(b, flags, depth + 1, 1);
            } else {
                indent(b, flags, depth, 0);
            }
        }
        put(b, "]", 1);
        return;
    }
    case JSON_OBJECT: {
        const char *sep = flags & JDUMP_COMPACT ? ":" : ": ";
        size_t seplen = flags & JDUMP_COMPACT ? 1 : 2;
        void *it = json_object_iter((json_t *)j);
        put(b, "{", 1);
        if (!it) {
            put(b, "}", 1);
            return;
        }
        indent(b, flags, depth + 1, 0);
        while (it) {
            void *nx = json_object_iter_next((json_t *)j, it);
            string(b, json_object_iter_key(it), json_object_iter_key_len(it));
            put(b, sep, seplen);
            value(b, json_object_iter_value(it), flags, depth + 1);
            if (nx) {
                put(b, ",", 1);
                indent(b, flags, depth + 1, 1);
            } else {
                indent(b, flags, depth, 0);
            }
            it = nx;
        }
        put(b, "}", 1);
        return;
    }
    default: b->fail = 1;
    }
}

/* The text in b (NUL-terminated), or b->fail. */
static void dump(struct buf *b, const json_t *root, unsigned flags)
{
    if (!root || !(json_is_array(root) || json_is_object(root))) {
        b->fail = 1;
        return;
    }
    value(b, root, flags, 0);
    put(b, "", 1);
}

char *jdump_string(const json_t *root, unsigned flags)
{
    struct buf b = {0};
    dump(&b, root, flags);
    if (b.fail) {
        free(b.p);
        return NULL;
    }
    return b.p;
}

int jdump_file(const json_t *root, FILE *f, unsigned flags)
{
    struct buf b = {0};
    dump(&b, root, flags);
    int rc = b.fail || (b.n > 1 && fwrite(b.p, b.n - 1, 1, f) != 1) ? -1 : 0;
    free(b.p);
    return rc;
}
