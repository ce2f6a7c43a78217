/* g17.c: "%.17g" by exact integer arithmetic (see g17.h).
 *
 * Why hand-written: glibc's printf formats a double through its multi-precision path (~2,000
 * instructions a number), which was a fifth of the reference `ips fit` job's instructions and a
 * tenth of the 41 x 41 raster's (callgrind); no C library in Debian prints a fixed number of
 * significant digits faster (Ryu and double-conversion are Rust and C++ there). This is not an
 * approximation with a check: every step below is exact, so no error analysis is needed.
 *
 * A normal double is v = m 2^e (m < 2^53). With E = floor(log10 v), %.17g needs
 * N = round(v 10^(16-E)), 10^16 <= N < 10^17 (ties to even), and then the text. With p = 16 - E:
 *  - p >= 0: v 10^p = (m 5^p) 2^(e+p). m 5^p < 2^128 for p <= 32 (5^32 < 2^75), so N is that
 *    integer shifted by e + p bits, and the bits shifted out decide the rounding exactly.
 *  - p < 0 (v >= 1e17 > 2^53, so v is an integer): v 10^p = (m 2^e) / 10^-p, one 128-bit
 *    division when m 2^e < 2^128, the remainder against half the divisor.
 * E is first estimated from the binary exponent and corrected while N falls outside
 * [10^16, 10^17). Other values (0 aside: subnormals, |v| < 1e-16, |v| >= 2^128, inf, nan) go to
 * snprintf. tests/test_g17.c compares it with snprintf on millions of values. */
#include "base/g17.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#if defined(__SIZEOF_INT128__)
__extension__ typedef unsigned __int128 u128;

static const uint64_t pow5[28] = {
    1ull, 5ull, 25ull, 125ull, 625ull, 3125ull, 15625ull, 78125ull, 390625ull, 1953125ull,
    9765625ull, 48828125ull, 244140625ull, 1220703125ull, 6103515625ull, 30517578125ull,
    152587890625ull, 762939453125ull, 3814697265625ull, 19073486328125ull, 95367431640625ull,
    476837158203125ull, 2384185791015625ull, 11920928955078125ull, 59604644775390625ull,
    298023223876953125ull, 1490116119384765625ull, 7450580596923828125ull};

#define P16 10000000000000000ull  /* 10^16 */
#define P17 100000000000000000ull /* 10^17 */

/* floor(v 10^p) into *t (saturated at 2^64 - 1) and the rounding decision (1: round up) for
 * v = m 2^e. Returns 0, or -1 when the numbers leave the exact range. */
static int scaled(uint64_t m, int e, int p, uint64_t *t, int *up)
{
    if (p >= 0) {
        if (p > 32) return -1;
        u128 x = p <= 27 ? (u128)m * pow5[p] : (u128)m * pow5[p - 27] * pow5[27]; /* m 5^p */
        int s = e + p;
        if (s >= 0) {
            if (s >= 64) return -1;
            x <<= s; /* x < 2^60 (m 5^p 2^s ~ 10^17 or 10^18) whenever it matters */
            *t = x >> 64 ? UINT64_MAX : (uint64_t)x;
            *up = 0;
            return 0;
        }
        int sh = -s;
        if (sh >= 128) { /* v 10^p < 1: below 10^16 anyway */
            *t = 0;
            *up = 0;
            return 0;
        }
        u128 q = x >> sh, rem = x - (q << sh), half = (u128)1 << (sh - 1);
        *t = q >> 64 ? UINT64_MAX : (uint64_t)q;
        *up = rem > half || (rem == half && (q & 1)); /* ties to even */
        return 0;
    }
    if (p < -27 || e > 74) return -1; /* 10^-p and m 2^e < 2^128 (checked before negating p:
                                         * gcc's -Warray-bounds under ASan saw -INT_MIN) */
    int q10 = -p;
    u128 x = (u128)m << e, d = (u128)pow5[q10] << q10; /* 10^q10 */
    u128 q = x / d, rem = x - q * d;
    *t = q >> 64 ? UINT64_MAX : (uint64_t)q;
    *up = 2 * rem > d || (2 * rem == d && (q & 1));
    return 0;
}

/* Writes the 17 digits of n (10^16 <= n < 10^17) into d. */
static void digits17(uint64_t n, char *d)
{
    for (int i = 16; i >= 0; i--) {
        d[i] = (char)('0' + n % 10);
        n /= 10;
    }
}

int g17_format(double v, char buf[G17_MAX])
{
    uint64_t bits;
    memcpy(&bits, &v, sizeof bits);
    int neg = (int)(bits >> 63), be = (int)((bits >> 52) & 0x7ff);
    uint64_t frac = bits & ((1ull << 52) - 1);
    char *o = buf;
    if (be == 0 && frac == 0) { /* +-0 */
        if (neg) *o++ = '-';
        *o++ = '0';
        *o = 0;
        return (int)(o - buf);
    }
    if (be == 0 || be == 0x7ff) return snprintf(buf, G17_MAX, "%.17g", v);
    uint64_t m = frac | (1ull << 52);
    int e = be - 1075, x2 = be - 1023; /* v in [2^x2, 2^(x2+1)) */
    /* floor(x2 log10 2) or one less: 78913 / 2^18 ~ log10 2, the shift of a negative number
     * written as a division that rounds down */
    int E = x2 >= 0 ? (x2 * 78913) >> 18 : -((-x2 * 78913 + (1 << 18) - 1) >> 18);
    uint64_t t = 0;
    int up = 0;
    for (int tries = 0;; tries++) {
        if (tries == 4 || scaled(m, e, 16 - E, &t, &up)) return snprintf(buf, G17_MAX, "%.17g", v);
        if (t < P16) E--;
        else if (t >= P17) E++;
        else break;
    }
    uint64_t n = t + (uint64_t)up;
    if (n == P17) { /* rounded up to the next power of ten */
        n = P16;
        E++;
    }
    char d[17];
    digits17(n, d);
    int nd = 17;
    while (nd > 1 && d[nd - 1] == '0') nd--; /* %g drops trailing zeros (and then the point) */
    if (neg) *o++ = '-';
    if (E < -4 || E >= 17) { /* d.ddde[+-]XX, at least two exponent digits */
        *o++ = d[0];
        if (nd > 1) {
            *o++ = '.';
            memcpy(o, d + 1, (size_t)(nd - 1));
            o += nd - 1;
        }
        *o++ = 'e';
        *o++ = E < 0 ? '-' : '+';
        int a = E < 0 ? -E : E;
        if (a >= 100) *o++ = (char)('0' + a / 100);
        *o++ = (char)('0' + a / 10 % 10);
        *o++ = (char)('0' + a % 10);
    } else if (E >= 0) { /* ddd.ddd */
        memcpy(o, d, (size_t)E + 1);
        o += E + 1;
        if (nd > E + 1) {
            *o++ = '.';
            memcpy(o, d + E + 1, (size_t)(nd - E - 1));
            o += nd - E - 1;
        }
    } else { /* 0.000ddd */
        *o++ = '0';
        *o++ = '.';
        for (int z = 0; z < -E - 1; z++) *o++ = '0';
        memcpy(o, d, (size_t)nd);
        o += nd;
    }
    *o = 0;
    return (int)(o - buf);
}

#else /* no 128-bit integers: the C library's */

int g17_format(double v, char buf[G17_MAX])
{
    return snprintf(buf, G17_MAX, "%.17g", v);
}

#endif
