/* base/le.h: little-endian byte codecs, the same bytes whatever the host's byte order (the BLOB
 * layouts of docs/schema.md, files other programs read). Inline; no allocation. */
#ifndef IPSD_BASE_LE_H
#define IPSD_BASE_LE_H

#include <stdint.h>
#include <string.h>

static inline void le_put_u16(unsigned char *p, uint16_t v)
{
    p[0] = (unsigned char)(v & 0xff);
    p[1] = (unsigned char)(v >> 8);
}

static inline uint16_t le_get_u16(const unsigned char *p)
{
    return (uint16_t)(p[0] | (p[1] << 8));
}

static inline void le_put_u64(unsigned char *p, uint64_t v)
{
    for (int k = 0; k < 8; k++) p[k] = (unsigned char)(v >> (8 * k));
}

static inline uint64_t le_get_u64(const unsigned char *p)
{
    uint64_t v = 0;
    for (int k = 0; k < 8; k++) v |= (uint64_t)p[k] << (8 * k);
    return v;
}

/* IEEE 754 binary64, its bit pattern little-endian. */
static inline void le_put_f64(unsigned char *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    le_put_u64(p, u);
}

static inline double le_get_f64(const unsigned char *p)
{
    uint64_t u = le_get_u64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

#endif
