/* fuzz_stage_url.c: the stage string of ipsd --stage (instrument/stage.h, stage_url_check) on any
 * bytes (up to the first NUL): it answers 0 or -EINVAL, an error says what is wrong, and a string
 * it accepts is "sim" or starts with "gcs:tcp://", "gcs:serial:/", "zaber:tcp://" or
 * "zaber:serial:/" (a zaber one naming its step_um=). The findings of attacking it: an error is one
 * line of printable ASCII (the string's control characters escaped), an accepted TCP host has no
 * bracket left in it, space or control character (parsed again by stage_url_parse), and no
 * option key is accepted twice. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_api.h"
#include "instrument/stage.h"
#include "stage_url.h" /* white-box: instrument/ internal (tests/fuzz.cmake) */

static void must(int ok, const char *what)
{
    if (ok) return;
    fprintf(stderr, "fuzz_stage_url: %s\n", what);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char *s = malloc(size + 1);
    if (!s) return 0;
    memcpy(s, data, size);
    s[size] = 0;
    err_t err = {{0}};
    int is_sim = -1;
    int ret = stage_url_check(s, &is_sim, &err);
    must(ret == 0 || ret == -EINVAL, "stage_url_check answers 0 or -EINVAL");
    if (ret) {
        must(err.msg[0] != 0, "an error says what is wrong");
        for (const char *p = err.msg; *p; p++)
            must((unsigned char)*p >= 0x20 && (unsigned char)*p < 0x7f,
                 "an error is printable ASCII, control characters escaped");
    }
    else if (is_sim)
        must(strcmp(s, "sim") == 0, "only 'sim' is the simulated stage");
    else
        must(strncmp(s, "gcs:tcp://", 10) == 0 || strncmp(s, "gcs:serial:/", 12) == 0 ||
                 ((strncmp(s, "zaber:tcp://", 12) == 0 || strncmp(s, "zaber:serial:/", 14) == 0) &&
                  strstr(s, "step_um=")),
             "an accepted stage string names a gcs or zaber link");
    if (ret == 0 && !is_sim) {
        stage_url_t u;
        must(stage_url_parse(s, &u, &err) == 0, "stage_url_parse accepts what the check did");
        for (const char *p = u.host; *p; p++)
            must(*p > 0x20 && *p < 0x7f && *p != '[' && *p != ']' && *p != ' ',
                 "an accepted host has no bracket, space or control character");
        const char *q = strchr(s, '?');
        /* no key twice: every "key=" at the start of an option occurs once */
        for (const char *k = q; k; k = strchr(k + 1, '&')) {
            size_t len = strcspn(k + 1, "=&");
            for (const char *o = strchr(k + 1, '&'); o; o = strchr(o + 1, '&'))
                must(!(strncmp(o + 1, k + 1, len) == 0 && o[1 + len] == '='),
                     "no option key is accepted twice");
        }
    }
    free(s);
    return 0;
}
