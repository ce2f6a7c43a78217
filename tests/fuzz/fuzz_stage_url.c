/* fuzz_stage_url.c: the stage string of ipsd --stage (instrument/stage.h, stage_url_check) on any
 * bytes (up to the first NUL): it answers 0 or -EINVAL, an error says what is wrong, and a string
 * it accepts is "sim" or starts with "gcs:tcp://", "gcs:serial:/", "zaber:tcp://" or
 * "zaber:serial:/" (a zaber one naming its step_um=). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_api.h"
#include "instrument/stage.h"

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
    if (ret)
        must(err.msg[0] != 0, "an error says what is wrong");
    else if (is_sim)
        must(strcmp(s, "sim") == 0, "only 'sim' is the simulated stage");
    else
        must(strncmp(s, "gcs:tcp://", 10) == 0 || strncmp(s, "gcs:serial:/", 12) == 0 ||
                 ((strncmp(s, "zaber:tcp://", 12) == 0 || strncmp(s, "zaber:serial:/", 14) == 0) &&
                  strstr(s, "step_um=")),
             "an accepted stage string names a gcs or zaber link");
    free(s);
    return 0;
}
