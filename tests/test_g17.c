/* test_g17.c: g17_format (base/g17.h) against the C library's snprintf("%.17g"), the reference
 * it must equal byte for byte: edge cases (zeros, subnormals, the extremes, powers of ten and two
 * and their neighbours, infinities, NaN), exact ties at the 17th digit (which must round to even),
 * values that round up to the next power of ten, and millions of random doubles (random bit
 * patterns over every exponent, and random values in the ranges fits print). */
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "base/g17.h"
#include "check.h"

static long compared, mismatches;

static void cmp(double v)
{
    char want[64], got[G17_MAX + 8];
    memset(got, 'x', sizeof got);
    int wn = snprintf(want, sizeof want, "%.17g", v);
    int gn = g17_format(v, got);
    compared++;
    if (gn != wn || strcmp(got, want) != 0) {
        if (mismatches++ < 20)
            fprintf(stderr, "mismatch for %a: got \"%s\" (%d), want \"%s\" (%d)\n", v, got, gn,
                    want, wn);
    }
}

static void cmp_both(double v)
{
    cmp(v);
    cmp(-v);
}

/* xorshift64*: deterministic */
static uint64_t rng = 0x9E3779B97F4A7C15ull;
static uint64_t next(void)
{
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return rng * 2685821657736338717ull;
}

static double from_bits(uint64_t b)
{
    double v;
    memcpy(&v, &b, sizeof v);
    return v;
}

int main(void)
{
    /* edge cases */
    double edge[] = {0.0, 1.0, 0.5, 0.1, 0.2, 0.3, 1.0 / 3, 2.0 / 3, 10.0, 100.0, 1e16, 1e17,
                     1e-4, 1e-5, 9.9999999999999995e-5, 1e21, 1e22, 1e23, 123456789012345678.0,
                     DBL_MAX, DBL_MIN, DBL_TRUE_MIN, DBL_MIN / 3, 4.9406564584124654e-324,
                     DBL_EPSILON, 16383.0, 1e300, 1e-300, 3.4028236692093846e38,
                     3.4028236692093846e38 * 2, 1e-16, 1e-17, 9.9999999999999998e-17,
                     0.30000000000000004, 5e-324, INFINITY, NAN, 2.2250738585072009e-308};
    for (size_t i = 0; i < sizeof edge / sizeof edge[0]; i++) cmp_both(edge[i]);
    cmp(-NAN);
    /* powers of ten and their neighbours, two ulps either side */
    for (int p = -330; p <= 310; p++) {
        double v = pow(10, p), a = v, b = v;
        cmp_both(v);
        for (int k = 0; k < 3; k++) {
            a = nextafter(a, 0);
            b = nextafter(b, INFINITY);
            cmp_both(a);
            cmp_both(b);
        }
    }
    /* powers of two and their neighbours */
    for (int p = -1074; p <= 1023; p++) {
        double v = ldexp(1, p);
        cmp_both(v);
        cmp_both(nextafter(v, 0));
        cmp_both(nextafter(v, INFINITY));
    }
    /* 17-digit decimals with all nines (round up to the next power of ten) and all-but-last */
    for (int p = -20; p <= 40; p++) {
        cmp_both(9.9999999999999999 * pow(10, p));
        cmp_both(9.9999999999999995 * pow(10, p));
        cmp_both(9.9999999999999991 * pow(10, p));
        cmp_both(1.0000000000000001 * pow(10, p));
    }
    /* exact ties at the 17th significant digit: n / 2^k with n odd has exactly k fraction
     * digits (ending in 5); with 18 - k integer digits the 18th digit is that last 5 */
    long ties = 0;
    for (int k = 2; k <= 12; k++) {
        double lo = pow(10, 17 - k), hi = pow(10, 18 - k);
        for (int i = 0; i < 20000; i++) {
            uint64_t n = (uint64_t)(lo * ldexp(1, k)) + (next() % (uint64_t)((hi - lo) * ldexp(1, k)));
            n |= 1;
            if (n >= (1ull << 53)) continue;
            double v = ldexp((double)n, -k);
            if (v < lo || v >= hi) continue;
            cmp_both(v);
            ties++;
        }
    }
    CHECK(ties > 50000);
    /* integers, small and large */
    for (int i = 0; i < 100000; i++) {
        cmp_both((double)i);
        cmp_both((double)(next() >> (next() % 64)));
    }
    /* random bit patterns: every exponent, subnormals, NaNs and infinities included */
    for (int i = 0; i < 1500000; i++) cmp(from_bits(next()));
    /* the ranges fits print: signals (DN), chi2, sensitivities, positions, residuals, errors */
    for (int i = 0; i < 500000; i++) {
        double u = (double)(next() >> 11) * 0x1p-53; /* [0, 1) */
        int ex = (int)(next() % 40) - 20;
        cmp_both(u * pow(10, ex));
        cmp_both(1 + u * 1e-3);
        cmp_both(100 + u * 16283);
    }
    printf("%ld values compared, %ld mismatches\n", compared, mismatches);
    CHECK(mismatches == 0);
    CHECK(compared > 4500000);
    CHECK_DONE();
}
