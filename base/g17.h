/* g17.h: a double as printf's "%.17g" writes it (the 17 significant digits that docs/contracts.md
 * asks of every number written), the same text byte for byte, correctly rounded (ties to even, as
 * glibc in the default rounding mode), several times faster than snprintf. */
#ifndef IPSD_BASE_G17_H
#define IPSD_BASE_G17_H

#include <stddef.h>

#define G17_MAX 32 /* room for any result and its terminating NUL ("-2.2250738585072014e-308") */

/* Writes v as snprintf(buf, G17_MAX, "%.17g", v) would and returns the length (the NUL is
 * written too). Exact integer arithmetic for normal numbers of magnitude 1e-16 .. 3.4e38; other
 * values (zero aside) are passed to snprintf itself. */
int g17_format(double v, char buf[G17_MAX]);

#endif
