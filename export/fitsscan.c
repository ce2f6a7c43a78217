/* fitsscan.c: reading a spot scan's FITS cube with cfitsio (the layout: fitsscan.h and
 * docs/contracts.md, "FITS scan cube"). cfitsio rather than our own parser: it is the reference
 * reader of the standard (every BITPIX, BSCALE / BZERO, BLANK, table column types and byte
 * order), so a file any FITS writer produced reads as that writer meant it. Every check names
 * the keyword, axis, column or row it failed on. */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <fitsio.h>

#include "export/fitsscan.h"
#include "fitshdr.h"

#define FULL_SCALE_DEFAULT 16383.0 /* the scan file's default (fit/scandata.h), 14-bit ADC */

/* cfitsio's message for status as err's text (the caller adds what it was doing). */
static int cfitsio_fail(err_t *err, int status, const char *what)
{
    char text[FLEN_STATUS];
    fits_get_errstatus(status, text);
    fits_clear_errmsg();
    return err_set(err, status == MEMORY_ALLOCATION ? -ENOMEM : -EINVAL, "%s (cfitsio: %s)", what,
                   text);
}

/* ---- primary header ---- */

/* Reads keyword key of the current HDU as a double. *present (may be NULL: the keyword is then
 * required) is set to whether it is there. */
static int key_num(fitsfile *f, const char *key, const char *meaning, double *v, int *present,
                   err_t *err)
{
    int status = 0;
    if (present) *present = 0;
    fits_read_key(f, TDOUBLE, key, v, NULL, &status);
    if (status == KEY_NO_EXIST && present) {
        fits_clear_errmsg();
        return 0;
    }
    if (status == KEY_NO_EXIST) {
        fits_clear_errmsg();
        return err_set(err, -EINVAL, "keyword %s (%s) is missing from the primary header", key,
                       meaning);
    }
    if (status) {
        fits_clear_errmsg();
        return err_set(err, -EINVAL, "keyword %s (%s) is not a number", key, meaning);
    }
    if (!isfinite(*v))
        return err_set(err, -EINVAL, "keyword %s (%s) is not finite", key, meaning);
    if (present) *present = 1;
    return 0;
}

/* sign: 1 must be > 0, -1 must be >= 0, 0 any finite value. */
static int key_checked(fitsfile *f, const char *key, const char *meaning, int sign, double *v,
                       err_t *err)
{
    int rc = key_num(f, key, meaning, v, NULL, err);
    if (rc) return rc;
    if (sign > 0 && !(*v > 0))
        return err_set(err, -EINVAL, "keyword %s (%s) must be positive (got %.17g)", key, meaning,
                       *v);
    if (sign < 0 && !(*v >= 0))
        return err_set(err, -EINVAL, "keyword %s (%s) must not be negative (got %.17g)", key,
                       meaning, *v);
    return 0;
}

/* A whole number in [lo, hi]. */
static int whole(const char *key, const char *meaning, double v, long lo, long hi, err_t *err)
{
    if (!(v >= lo && v <= hi && v == floor(v)))
        return err_set(err, -EINVAL, "keyword %s (%s) must be a whole number in %ld..%ld (got %.17g)",
                       key, meaning, lo, hi, v);
    return 0;
}

/* A keyword's value text as a finite number (FITS writes E or D exponents). */
static int finite_number(const char *text, double *v)
{
    char buf[FLEN_VALUE], *end;
    snprintf(buf, sizeof buf, "%s", text);
    for (char *p = buf; *p; p++)
        if (*p == 'D' || *p == 'd') *p = 'e';
    errno = 0;
    *v = strtod(buf, &end);
    while (*end == ' ')
        end++;
    return end != buf && !*end && errno != ERANGE && isfinite(*v);
}

/* ---- the positions table ---- */

/* The bytes of a row by the table's TFORMn (FITS 4.0, table 18: rT with r the repeat count,
 * default 1), which must be its NAXIS1: cfitsio reads a row whose columns overrun NAXIS1 from
 * the next row's bytes. */
static int table_width(fitsfile *f, long rowlen, err_t *err)
{
    int status = 0, fields = 0;
    fits_get_num_cols(f, &fields, &status);
    if (status) return cfitsio_fail(err, status, "table POSITIONS: cannot count its columns");
    double bytes = 0;
    for (int i = 1; i <= fields; i++) {
        char key[FLEN_KEYWORD], form[FLEN_VALUE] = "", *p = form;
        snprintf(key, sizeof key, "TFORM%d", i);
        fits_read_key(f, TSTRING, key, form, NULL, &status);
        if (status) return cfitsio_fail(err, status, "table POSITIONS: unreadable TFORM");
        while (*p == ' ')
            p++;
        double repeat = 1;
        if (*p >= '0' && *p <= '9') repeat = strtod(p, &p);
        static const char types[] = "LXBIJKAEDCMPQ";
        static const double size[] = {1, 0, 1, 2, 4, 8, 1, 4, 8, 8, 16, 8, 16};
        const char *t = *p ? strchr(types, *p) : NULL;
        if (!t) return err_set(err, -EINVAL, "table POSITIONS: %s = '%s' is not a binary table "
                               "column format", key, form);
        bytes += *t == 'X' ? ceil(repeat / 8) : repeat * size[t - types];
    }
    if (bytes != (double)rowlen)
        return err_set(err, -EINVAL, "table POSITIONS: its columns take %.0f bytes a row but "
                       "NAXIS1 = %ld", bytes, rowlen);
    return 0;
}

/* A column's 1-based number, or 0 when the table has none of that name; -EINVAL when it is not
 * one number per row, or its unit is not um (unit_um). */
static int column(fitsfile *f, const char *name, int unit_um, int *col, err_t *err)
{
    int status = 0, typecode = 0;
    long repeat = 0, width = 0;
    *col = 0;
    fits_get_colnum(f, CASEINSEN, (char *)name, col, &status);
    if (status == COL_NOT_FOUND) {
        fits_clear_errmsg();
        *col = 0;
        return 0;
    }
    if (status) return cfitsio_fail(err, status, "table POSITIONS: cannot find its columns");
    fits_get_coltype(f, *col, &typecode, &repeat, &width, &status);
    if (status) return cfitsio_fail(err, status, "table POSITIONS: unreadable column");
    int numeric = typecode == TBYTE || typecode == TSBYTE || typecode == TSHORT ||
                  typecode == TUSHORT || typecode == TINT || typecode == TUINT ||
                  typecode == TLONG || typecode == TULONG || typecode == TLONGLONG ||
                  typecode == TULONGLONG || typecode == TFLOAT || typecode == TDOUBLE;
    if (!numeric || repeat != 1)
        return err_set(err, -EINVAL, "table POSITIONS: column %s must hold one number per row", name);
    /* a scale cfitsio cannot use is dropped by it without a word (NaN, 1e999): refused here */
    static const char *const scales[2] = {"TSCAL", "TZERO"};
    for (int k = 0; k < 2; k++) {
        char key[FLEN_KEYWORD], value[FLEN_VALUE];
        double v;
        snprintf(key, sizeof key, "%s%d", scales[k], *col);
        fits_read_keyword(f, key, value, NULL, &status);
        if (status == KEY_NO_EXIST) {
            fits_clear_errmsg();
            status = 0;
            continue;
        }
        if (status || !finite_number(value, &v) || (k == 0 && v == 0))
            return err_set(err, -EINVAL, "table POSITIONS: %s (column %s's %s) must be a finite "
                           "number%s", key, name, k ? "offset" : "scale", k ? "" : ", not 0");
    }
    if (unit_um) {
        char key[FLEN_KEYWORD], unit[FLEN_VALUE] = "";
        snprintf(key, sizeof key, "TUNIT%d", *col);
        fits_read_key(f, TSTRING, key, unit, NULL, &status);
        if (status == KEY_NO_EXIST) {
            fits_clear_errmsg();
            status = 0;
        } else if (status == 0 && unit[0] && strcasecmp(unit, "um") != 0 &&
                   strcasecmp(unit, "micron") != 0)
            return err_set(err, -EINVAL, "table POSITIONS: column %s is in '%s', need um", name,
                           unit);
    }
    return status ? cfitsio_fail(err, status, "table POSITIONS: unreadable unit") : 0;
}

/* Reads column col (n rows) as doubles (undefined values as NaN) into a new array *out. */
static int read_column(fitsfile *f, int col, const char *name, size_t n, double **out, err_t *err)
{
    int status = 0, anynul = 0;
    double nulval = NAN;
    *out = malloc(sizeof(double) * n);
    if (!*out) return err_set(err, -ENOMEM, "out of memory for column %s", name);
    fits_read_col(f, TDOUBLE, col, 1, 1, (LONGLONG)n, &nulval, *out, &anynul, &status);
    if (status) {
        char what[64];
        snprintf(what, sizeof what, "table POSITIONS: cannot read column %s", name);
        return cfitsio_fail(err, status, what);
    }
    return 0;
}

/* An optional per-row column that must hold one value: it (or the header's, when both are
 * given) into *v; *have says whether any was given. */
static int constant_column(fitsfile *f, const char *name, size_t n, double *v, int *have,
                           err_t *err)
{
    int col, rc = column(f, name, 0, &col, err), from_header = *have;
    if (rc || !col) return rc;
    double *a = NULL;
    rc = read_column(f, col, name, n, &a, err);
    for (size_t k = 0; rc == 0 && k < n; k++) {
        if (!isfinite(a[k]))
            rc = err_set(err, -EINVAL, "table POSITIONS: %s in row %zu is not a number", name, k + 1);
        else if (*have && a[k] != *v)
            rc = err_set(err, -EINVAL,
                         "table POSITIONS: %s is %.17g in row %zu but %.17g %s: a scan has one "
                         "%s", name, a[k], k + 1, *v, from_header ? "in the header" : "in row 1",
                         strcmp(name, "NCOMBINE") ? "exposure" : "frame count");
        else {
            *v = a[k];
            *have = 1;
        }
    }
    free(a);
    return rc;
}

/* ---- the file ---- */

/* Whether the current HDU's data (bytes of them, unpadded) lie inside the file's len bytes: a
 * file cut short must not read as one whose end is missing values (cfitsio's memory driver does
 * not always say so). */
static int data_inside(fitsfile *f, double bytes, size_t len, const char *what, err_t *err)
{
    LONGLONG head = 0, start = 0, end = 0;
    int status = 0;
    fits_get_hduaddrll(f, &head, &start, &end, &status);
    if (status) return cfitsio_fail(err, status, "cannot locate the data");
    if ((double)start + bytes > (double)len)
        return err_set(err, -EINVAL, "the file ends inside %s: %zu bytes, %.0f needed (truncated?)",
                       what, len, (double)start + bytes);
    return 0;
}

static int read_primary(fitsfile *f, size_t len, size_t max_points, fitsscan_t *s, err_t *err)
{
    int status = 0, bitpix = 0, naxis = 0, rc;
    long naxes[3] = {0, 0, 0};
    fits_get_img_param(f, 3, &bitpix, &naxis, naxes, &status);
    if (status) return cfitsio_fail(err, status, "the primary HDU is not an image");
    if (naxis != 3)
        return err_set(err, -EINVAL,
                       "the primary image has NAXIS = %d, need a cube of 3 axes (sub-frame "
                       "columns x rows x points)", naxis);
    for (int a = 0; a < 3; a++)
        if (naxes[a] < 1 || naxes[a] > INT32_MAX)
            return err_set(err, -EINVAL, "the primary image has NAXIS%d = %ld, need >= 1", a + 1,
                           naxes[a]);
    s->ncol = (int)naxes[0];
    s->nrow = (int)naxes[1];
    s->n = (size_t)naxes[2];
    if (s->n > max_points) /* before anything is allocated: the header says how many */
        return err_set(err, -E2BIG, "the cube has %zu points (NAXIS3), more than %zu", s->n,
                       max_points);
    static const char *const scales[2] = {"BSCALE", "BZERO"};
    for (int k = 0; k < 2; k++) {
        char value[FLEN_VALUE];
        double v;
        fits_read_keyword(f, scales[k], value, NULL, &status);
        if (status == KEY_NO_EXIST) {
            fits_clear_errmsg();
            status = 0;
            continue;
        }
        if (status || !finite_number(value, &v) || (k == 0 && v == 0))
            return err_set(err, -EINVAL, "keyword %s must be a finite number%s", scales[k],
                           k ? "" : ", not 0");
    }
    /* every value takes at least a byte of the file: a header claiming more is not this file's */
    double values = (double)naxes[0] * (double)naxes[1] * (double)naxes[2];
    if (values > (double)len)
        return err_set(err, -EINVAL, "the cube's %.0f values do not fit in the file's %zu bytes",
                       values, len);
    if ((rc = data_inside(f, values * abs(bitpix) / 8, len, "the cube", err))) return rc;
    double v;
    if ((rc = key_checked(f, "PITCH", "[um] pixel pitch", 1, &s->pitch_um, err)) ||
        (rc = key_checked(f, "SPOTRAD", "[um] Airy first-zero radius", 1, &s->spot_radius_um,
                          err)) ||
        (rc = key_checked(f, "BIAS", "[DN] ADC offset", 0, &s->bias_dn, err)) ||
        (rc = key_checked(f, "GAIN", "[e-/DN] conversion gain", 1, &s->gain_e_per_dn, err)) ||
        (rc = key_checked(f, "RDNOISE", "[e-] read noise", -1, &s->read_noise_e, err)))
        return rc;
    int have;
    if ((rc = key_num(f, "POICOL", "pixel of interest, FITS column", &v, NULL, err)) ||
        (rc = whole("POICOL", "pixel of interest, FITS column", v, 1, s->ncol, err)))
        return rc;
    s->poi_col = (int)v - 1;
    if ((rc = key_num(f, "POIROW", "pixel of interest, FITS row", &v, NULL, err)) ||
        (rc = whole("POIROW", "pixel of interest, FITS row", v, 1, s->nrow, err)))
        return rc;
    s->poi_row = (int)v - 1;
    s->full_scale_dn = FULL_SCALE_DEFAULT;
    if ((rc = key_num(f, "SATURATE", "[DN] ADC full scale", &v, &have, err))) return rc;
    if (have) s->full_scale_dn = v;
    s->exptime_s = NAN;
    if ((rc = key_num(f, "EXPTIME", "[s] exposure", &v, &have, err))) return rc;
    if (have && !(v >= 0))
        return err_set(err, -EINVAL, "keyword EXPTIME ([s] exposure) must not be negative");
    if (have) s->exptime_s = v;
    s->frames = 0;
    if ((rc = key_num(f, "NCOMBINE", "frames averaged per point", &v, &have, err))) return rc;
    if (have) {
        if ((rc = whole("NCOMBINE", "frames averaged per point", v, 1, INT32_MAX, err))) return rc;
        s->frames = (int)v;
    }
    /* the cube: undefined pixels (BLANK, NaN) as NaN, which the scan file writes as null */
    size_t count = s->n * (size_t)s->nrow * (size_t)s->ncol;
    s->mean_dn = malloc(sizeof(double) * count);
    if (!s->mean_dn) return err_set(err, -ENOMEM, "out of memory for a cube of %zu values", count);
    long first[3] = {1, 1, 1};
    double nulval = NAN;
    int anynul = 0;
    fits_read_pix(f, TDOUBLE, first, (LONGLONG)count, &nulval, s->mean_dn, &anynul, &status);
    if (status) return cfitsio_fail(err, status, "cannot read the cube");
    return 0;
}

static int read_positions(fitsfile *f, size_t len, fitsscan_t *s, err_t *err)
{
    int status = 0, rc;
    fits_movnam_hdu(f, BINARY_TBL, "POSITIONS", 0, &status);
    if (status == BAD_HDU_NUM) {
        fits_clear_errmsg();
        return err_set(err, -EINVAL,
                       "no binary table extension EXTNAME = 'POSITIONS' (the spot positions)");
    }
    if (status) return cfitsio_fail(err, status, "cannot reach table POSITIONS");
    LONGLONG rows = 0;
    long rowlen = 0, heap = 0;
    fits_get_num_rowsll(f, &rows, &status);
    fits_read_key(f, TLONG, "NAXIS1", &rowlen, NULL, &status);
    fits_read_key(f, TLONG, "PCOUNT", &heap, NULL, &status);
    if (status) return cfitsio_fail(err, status, "table POSITIONS: cannot count its rows");
    if ((rc = data_inside(f, (double)rows * rowlen + heap, len, "table POSITIONS", err)) ||
        (rc = table_width(f, rowlen, err)))
        return rc;
    if (rows != (LONGLONG)s->n)
        return err_set(err, -EINVAL, "table POSITIONS has %lld rows but the cube %zu points (NAXIS3)",
                       (long long)rows, s->n);
    const char *names[2] = {"X_UM", "Y_UM"};
    double **arrays[2] = {&s->x_um, &s->y_um};
    for (int a = 0; a < 2; a++) {
        int col;
        if ((rc = column(f, names[a], 1, &col, err))) return rc;
        if (!col) return err_set(err, -EINVAL, "table POSITIONS has no column %s", names[a]);
        if ((rc = read_column(f, col, names[a], s->n, arrays[a], err))) return rc;
        for (size_t k = 0; k < s->n; k++)
            if (!isfinite((*arrays[a])[k]))
                /* cfitsio reads an IEEE NaN or infinity as undefined: which one is not known */
                return err_set(err, -EINVAL, "table POSITIONS: %s in row %zu is not a finite "
                               "number (NaN, infinite or undefined)", names[a], k + 1);
    }
    double frames = s->frames;
    int have = s->frames > 0;
    if ((rc = constant_column(f, "NCOMBINE", s->n, &frames, &have, err))) return rc;
    if (!have)
        return err_set(err, -EINVAL,
                       "keyword NCOMBINE (frames averaged per point) is missing from the primary "
                       "header");
    if ((rc = whole("NCOMBINE", "frames averaged per point", frames, 1, INT32_MAX, err))) return rc;
    s->frames = (int)frames;
    have = isfinite(s->exptime_s);
    if ((rc = constant_column(f, "EXPTIME", s->n, &s->exptime_s, &have, err))) return rc;
    if (have && !(s->exptime_s >= 0))
        return err_set(err, -EINVAL, "table POSITIONS: EXPTIME must not be negative");
    return 0;
}

int fitsscan_read(const void *buf, size_t len, fitsscan_t *out, err_t *err)
{
    return fitsscan_read_capped(buf, len, SIZE_MAX, out, err);
}

int fitsscan_read_capped(const void *buf, size_t len, size_t max_points, fitsscan_t *out,
                         err_t *err)
{
    memset(out, 0, sizeof *out);
    /* cfitsio reads a read-only memory file in place; it neither writes nor frees the buffer.
     * Its memory driver reads whole 2880-byte records, so a file whose length is not a whole
     * number of records (a conforming one always is) is read from a zero-padded copy; len stays
     * the file's own length, so a cut file still reads as cut (data_inside). */
    void *mem = (void *)buf, *padded = NULL;
    size_t size = len;
    fitsfile *f = NULL;
    int status = 0, rc;
    if (len < 2880 || memcmp(buf, "SIMPLE  =", 9) != 0)
        return err_set(err, -EINVAL, "not a FITS file (it must begin with a 2880-byte header "
                                     "whose first card is SIMPLE)");
    if ((rc = fitshdr_check(buf, len, err))) return rc; /* before cfitsio reads any header */
    if (len % 2880) {
        size = len + (2880 - len % 2880);
        if (!(padded = calloc(1, size)))
            return err_set(err, -ENOMEM, "out of memory for a %zu-byte FITS file", len);
        memcpy(padded, buf, len);
        mem = padded;
    }
    if (fits_open_memfile(&f, "scan.fits", READONLY, &mem, &size, 0, NULL, &status)) {
        free(padded);
        return cfitsio_fail(err, status, "not a readable FITS file");
    }
    int simple = 0;
    fits_read_key(f, TLOGICAL, "SIMPLE", &simple, NULL, &status);
    rc = status || !simple
             ? err_set(err, -EINVAL, "SIMPLE = F: the file says it does not conform to FITS")
             : read_primary(f, len, max_points, out, err);
    if (rc == 0) rc = read_positions(f, len, out, err);
    status = 0;
    fits_close_file(f, &status);
    fits_clear_errmsg();
    free(padded);
    if (rc) fitsscan_free(out);
    return rc;
}

void fitsscan_free(fitsscan_t *s)
{
    if (!s) return;
    free(s->mean_dn);
    free(s->x_um);
    free(s->y_um);
    memset(s, 0, sizeof *s);
}
