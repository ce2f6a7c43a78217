/* fuzz_text.c: base/'s parsers of outside text on any bytes (up to the first NUL): utf8_sanitize
 * (its result must be valid UTF-8 by jansson, an independent decoder, never longer, and a second
 * pass changes nothing), parse_ll and parse_double (a number they accept is what strtoll /
 * strtod read from the whole text, and finite). */
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/parse.h"
#include "base/utf8.h"
#include "fuzz_api.h"

static void must(int ok, const char *what)
{
    if (ok) return;
    fprintf(stderr, "fuzz_text: %s\n", what);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *s = malloc(size + 1);
    if (!s) return 0;
    memcpy(s, data, size);
    s[size] = 0;
    long long ll;
    double d;
    if (parse_ll(s, &ll) == 0) {
        char *end;
        errno = 0;
        must(strtoll(s, &end, 10) == ll && *end == 0 && errno == 0, "parse_ll");
    }
    if (parse_double(s, &d) == 0) must(isfinite(d) && strtod(s, NULL) == d, "parse_double");
    size_t n = strlen(s);
    utf8_sanitize(s);
    must(strlen(s) <= n, "utf8_sanitize made the text longer");
    json_t *j = json_string(s); /* NULL when not valid UTF-8 */
    must(j != NULL, "utf8_sanitize left invalid UTF-8");
    json_decref(j);
    must(utf8_sanitize(s) == 0, "utf8_sanitize is not idempotent");
    free(s);
    return 0;
}
