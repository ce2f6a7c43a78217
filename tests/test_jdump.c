/* test_jdump.c: jdump (json/jdump.h) against jansson's own json_dumps, the reference it must equal
 * byte for byte, on random documents (nested arrays and objects, empty ones, reals from random bit
 * patterns and integral values, integers to the extremes, strings with quotes, backslashes,
 * control characters, embedded NULs and multi-byte UTF-8, keys likewise) in every layout fits are
 * written in (JSON_INDENT(1), (2), none, JSON_COMPACT); and what it refuses. */
#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "check.h"
#include "json/jdump.h"

static uint64_t rng = 0x2545F4914F6CDD1Dull;
static uint64_t next(void)
{
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return rng * 2685821657736338717ull;
}

static const char *const pieces[] = {"a", "chi2", "\"", "\\", "\n", "\t", "\b", "\f", "\r",
                                     "\x01", "\x1f", "/", "\xc3\xa9", "\xe2\x82\xac",
                                     "\xf0\x9f\x98\x80", " ", "\x7f", "S_err"};

static json_t *str(void)
{
    char s[64];
    size_t n = 0, k = next() % 6;
    for (size_t i = 0; i < k; i++) {
        const char *p = pieces[next() % (sizeof pieces / sizeof pieces[0])];
        memcpy(s + n, p, strlen(p));
        n += strlen(p);
    }
    if (next() % 8 == 0) s[n++] = 0; /* an embedded NUL */
    return json_stringn(s, n);
}

static double real(void)
{
    uint64_t b = next();
    double v;
    switch (next() % 4) {
    case 0: memcpy(&v, &b, sizeof v); return isfinite(v) ? v : 1.5;
    case 1: return (double)(int64_t)(b >> (next() % 64)) * (next() % 2 ? 1 : -1);
    case 2: return (double)(b >> 11) * 0x1p-53 * 16383;
    default: return ldexp((double)(b >> 11), (int)(next() % 200) - 150);
    }
}

static json_t *doc(int depth)
{
    int kind = depth > 4 ? (int)(next() % 6) : (int)(next() % 8);
    switch (kind) {
    case 0: return json_null();
    case 1: return json_boolean(next() % 2);
    case 2: {
        static const json_int_t ex[] = {0, -1, 1, LLONG_MAX, LLONG_MIN, 1681, -42};
        return json_integer(next() % 2 ? ex[next() % 7] : (json_int_t)next());
    }
    case 3:
    case 4: return json_real(real());
    case 5: return str();
    case 6: {
        json_t *a = json_array();
        for (int i = (int)(next() % 5); i > 0; i--) json_array_append_new(a, doc(depth + 1));
        return a;
    }
    default: {
        json_t *o = json_object();
        for (int i = (int)(next() % 5); i > 0; i--) {
            json_t *k = str();
            json_object_setn_new(o, json_string_value(k), json_string_length(k), doc(depth + 1));
            json_decref(k);
        }
        return o;
    }
    }
}

int main(void)
{
    static const unsigned layouts[][2] = {{1, JSON_INDENT(1)},
                                          {2, JSON_INDENT(2)},
                                          {0, 0},
                                          {JDUMP_COMPACT, JSON_COMPACT}};
    int docs = 0, differ = 0;
    for (int i = 0; i < 3000; i++) {
        json_t *root = next() % 2 ? json_object() : json_array();
        for (int k = (int)(next() % 8); k >= 0; k--) {
            if (json_is_array(root)) json_array_append_new(root, doc(0));
            else json_object_set_new(root, k % 2 ? "fits" : "N", doc(0));
        }
        for (size_t l = 0; l < 4; l++) {
            char *want = json_dumps(root, layouts[l][1] | JSON_REAL_PRECISION(17));
            char *got = jdump_string(root, layouts[l][0]);
            docs++;
            if (!want || !got || strcmp(want, got)) {
                if (differ++ < 5) fprintf(stderr, "differ:\n%s\n---\n%s\n", want, got);
            }
            free(want);
            free(got);
        }
        json_decref(root);
    }
    printf("%d documents compared, %d differ\n", docs, differ);
    CHECK(differ == 0);
    /* refused as jansson refuses: a bare value, a string that is not UTF-8 */
    json_t *bare = json_real(1.5);
    CHECK(jdump_string(bare, 2) == NULL);
    json_decref(bare);
    json_t *bad = json_array();
    json_array_append_new(bad, json_stringn_nocheck("a\xff", 2));
    CHECK(json_dumps(bad, JSON_INDENT(2)) == NULL);
    CHECK(jdump_string(bad, 2) == NULL);
    json_decref(bad);
    /* a file gets the same text */
    json_t *o = json_pack("{s:f, s:[i, f, s]}", "chi2", 30.512345678901234, "x", 3, 0.1, "e\"");
    FILE *f = tmpfile();
    CHECK(f && jdump_file(o, f, 2) == 0);
    char got[256] = {0}, *want = json_dumps(o, JSON_INDENT(2) | JSON_REAL_PRECISION(17));
    if (f) {
        rewind(f);
        CHECK(fread(got, 1, sizeof got - 1, f) == strlen(want));
        fclose(f);
    }
    CHECK(strcmp(got, want) == 0);
    free(want);
    json_decref(o);
    CHECK_DONE();
}
