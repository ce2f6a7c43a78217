/* test_utf8.c: base/utf8.h's repair of text that is not valid UTF-8, against RFC 3629's table
 * (the sequences below are its examples and boundaries, written out by hand). */
#include <stdio.h>
#include <string.h>

#include "base/utf8.h"
#include "check.h"

/* Sanitizes a copy of in and compares with want and the count of bytes fixed. */
static void expect(const char *in, const char *want, size_t fixed)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%s", in);
    size_t got = utf8_sanitize(buf);
    CHECK(strcmp(buf, want) == 0);
    CHECK(got == fixed);
    if (strcmp(buf, want) != 0 || got != fixed) fprintf(stderr, "  input %s\n", in);
}

int main(void)
{
    expect("", "", 0);
    expect("plain ascii", "plain ascii", 0);
    expect("\xc3\xa9t\xc3\xa9", "\xc3\xa9t\xc3\xa9", 0);          /* été */
    expect("\xe2\x82\xac", "\xe2\x82\xac", 0);                    /* U+20AC euro */
    expect("\xf0\x9f\x98\x80", "\xf0\x9f\x98\x80", 0);            /* U+1F600 */
    expect("\xf4\x8f\xbf\xbf", "\xf4\x8f\xbf\xbf", 0);            /* U+10FFFF, the last */
    expect("a\xff" "b", "a?b", 1);                                /* never a UTF-8 byte */
    expect("\xc0\x80", "??", 2);                                  /* overlong NUL */
    expect("\xe0\x80\xaf", "???", 3);                             /* overlong '/' */
    expect("\xed\xa0\x80", "???", 3);                             /* a surrogate, U+D800 */
    expect("\xf4\x90\x80\x80", "????", 4);                        /* above U+10FFFF */
    expect("\x80x", "?x", 1);                                     /* a lone continuation */
    expect("\xc3(", "?(", 1);                                     /* lead without continuation */
    expect("ab\xc3", "ab", 1);                                    /* cut off at the end */
    expect("ab\xe2\x82", "ab", 2);                                /* cut off at the end */
    expect("ab\xf0\x9f\x98", "ab", 3);                            /* cut off at the end */
    CHECK_DONE();
}
