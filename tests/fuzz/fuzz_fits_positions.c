/* fuzz_fits_positions.c: the POSITIONS table of a FITS scan cube (export/fitsscan.h) on any
 * bytes: a fixed, valid primary HDU (a 1 x 1 x 3 cube of BITPIX 8 with every keyword) followed
 * by the input as the file's extensions, so the fuzzing spends its time in the table's header
 * and rows. fitsscan_read answers 0, -EINVAL or -ENOMEM, an error says what is wrong in one
 * line, and an accepted file has 3 finite positions and a frame count >= 1. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "export/fitsscan.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void must(int ok, const char *what)
{
    if (ok) return;
    fprintf(stderr, "fuzz_fits_positions: %s\n", what);
    abort();
}

/* The primary HDU: header and data, 2 x 2880 bytes. */
static void primary(unsigned char *p)
{
    static const char *const cards[] = {
        "SIMPLE  =                    T", "BITPIX  =                    8",
        "NAXIS   =                    3", "NAXIS1  =                    1",
        "NAXIS2  =                    1", "NAXIS3  =                    3",
        "EXTEND  =                    T", "PITCH   =                  6.0",
        "SPOTRAD =                  1.0", "BIAS    =                  0.0",
        "GAIN    =                  1.0", "RDNOISE =                  1.0",
        "NCOMBINE=                    1", "POICOL  =                    1",
        "POIROW  =                    1", "END"};
    memset(p, ' ', 2880);
    for (size_t i = 0; i < sizeof cards / sizeof cards[0]; i++)
        memcpy(p + 80 * i, cards[i], strlen(cards[i]));
    memset(p + 2880, 0, 2880);
    p[2880] = 100, p[2881] = 110, p[2882] = 120;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > (1u << 20)) return 0;
    unsigned char *buf = malloc(5760 + size);
    if (!buf) return 0;
    primary(buf);
    if (size) memcpy(buf + 5760, data, size);
    fitsscan_t s;
    err_t err = {{0}};
    int ret = fitsscan_read(buf, 5760 + size, &s, &err);
    must(ret == 0 || ret == -EINVAL || ret == -ENOMEM, "fitsscan_read answers 0, -EINVAL, -ENOMEM");
    if (ret) {
        must(err.msg[0] && !strchr(err.msg, '\n'), "an error is one line that says something");
    } else {
        must(s.n == 3 && s.frames >= 1, "an accepted cube has its 3 points and frames >= 1");
        for (size_t k = 0; k < s.n; k++)
            must(isfinite(s.x_um[k]) && isfinite(s.y_um[k]), "accepted positions are finite");
    }
    fitsscan_free(&s);
    free(buf);
    return 0;
}
