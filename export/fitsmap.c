/* fitsmap.c: IPS maps as a FITS file in memory with cfitsio (the layout and keywords: fitsmap.h,
 * docs/api.md "FITS"). cfitsio, not our own writer: it is the reference implementation of the
 * standard (header cards, padding to 2880-byte blocks, the long-string convention). */
#include <errno.h>
#include <malloc.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <fitsio.h>

#include "export/fitsmap.h"

/* ---- header cards ---- */

/* A real keyword with 17 significant digits (G format), so every double reads back exactly;
 * left out when the value is NaN or infinite (unknown). */
static void key_dbl(fitsfile *f, const char *key, double v, const char *comment, int *status)
{
    if (isfinite(v)) fits_write_key_dbl(f, key, v, -17, comment, status);
}

/* A string keyword. A header holds printable ASCII only, so a value with any other byte (a UTF-8
 * sensor model) is written percent-encoded (RFC 3986: every byte outside 0x20..0x7e and % itself
 * as %XX), which any reader can undo, and the comment says so; cfitsio would write such bytes as
 * spaces. Strings past a card's 68 characters continue on CONTINUE cards (LONGSTRN). */
static void key_str(fitsfile *f, const char *key, const char *v, const char *comment, int *status)
{
    if (!v || *status) return;
    int plain = 1;
    for (const unsigned char *p = (const unsigned char *)v; *p; p++) plain &= *p >= 0x20 && *p <= 0x7e;
    char *enc = NULL, note[FLEN_COMMENT];
    if (!plain) {
        size_t n = strlen(v), k = 0;
        if (!(enc = malloc(3 * n + 1))) {
            *status = MEMORY_ALLOCATION;
            return;
        }
        for (const unsigned char *p = (const unsigned char *)v; *p; p++)
            if (*p < 0x20 || *p > 0x7e || *p == '%')
                k += (size_t)snprintf(enc + k, 4, "%%%02X", *p);
            else
                enc[k++] = (char)*p;
        enc[k] = '\0';
        snprintf(note, sizeof note, "%s (UTF-8, percent-encoded)", comment);
        v = enc;
        comment = note;
    }
    if (strlen(v) > 68)
        fits_write_key_longstr(f, key, v, comment, status);
    else
        fits_write_key_str(f, key, v, comment, status);
    free(enc);
}

static void key_int(fitsfile *f, const char *key, long long v, const char *comment, int *status)
{
    fits_write_key_lng(f, key, (LONGLONG)v, comment, status);
}

/* ISO 8601 UTC with milliseconds, as the FITS DATE keywords want ("2026-11-23T17:40:01.250"). */
static void iso_date(int64_t ms, char *out, size_t n)
{
    time_t s = (time_t)(ms / 1000);
    struct tm tm;
    gmtime_r(&s, &tm);
    size_t at = strftime(out, n, "%Y-%m-%dT%H:%M:%S", &tm);
    snprintf(out + at, n - at, ".%03d", (int)(ms % 1000));
}

/* The two WCS of an r x r map of pixel (col, row): micrometres in the pixel (primary), sensor
 * pixels (alternate 'P', Kepler's PRF convention). axis 1 x, axis 2 y. */
static void key_wcs(fitsfile *f, const fitsmap_t *m, int *status)
{
    const double d = m->pitch_um / m->r;
    const char *ctype[2] = {"PIXX", "PIXY"}, *ptype[2] = {"RAWX", "RAWY"};
    const double origin[2] = {m->pixel_col, m->pixel_row};
    char key[16];
    key_str(f, "WCSNAME", "pixel um", "micrometres from the pixel's top-left corner", status);
    for (int a = 0; a < 2; a++) {
        snprintf(key, sizeof key, "CTYPE%d", a + 1);
        key_str(f, key, ctype[a], a ? "y in the pixel, downward" : "x in the pixel", status);
        snprintf(key, sizeof key, "CUNIT%d", a + 1);
        key_str(f, key, "um", NULL, status);
        /* FITS pixel 0.5 is the outer edge of the first sample: the pixel's corner */
        snprintf(key, sizeof key, "CRPIX%d", a + 1);
        key_dbl(f, key, 0.5, "reference: the edge of the first sample", status);
        snprintf(key, sizeof key, "CRVAL%d", a + 1);
        key_dbl(f, key, 0.0, "um at the reference: the pixel's edge", status);
        snprintf(key, sizeof key, "CDELT%d", a + 1);
        key_dbl(f, key, d, "um per sample (sub-pixel size)", status);
    }
    key_str(f, "WCSNAMEP", "sensor pixels", "sensor pixel coordinates (PRF files' P)", status);
    for (int a = 0; a < 2; a++) {
        snprintf(key, sizeof key, "CTYPE%dP", a + 1);
        key_str(f, key, ptype[a], NULL, status);
        snprintf(key, sizeof key, "CUNIT%dP", a + 1);
        key_str(f, key, "pixel", NULL, status);
        snprintf(key, sizeof key, "CRPIX%dP", a + 1);
        key_dbl(f, key, 0.5, NULL, status);
        snprintf(key, sizeof key, "CRVAL%dP", a + 1);
        key_dbl(f, key, origin[a], a ? "the pixel's row (its top edge)" : "the pixel's column",
                status);
        snprintf(key, sizeof key, "CDELT%dP", a + 1);
        key_dbl(f, key, 1.0 / m->r, "pixels per sample: 1 / OVERSAMP", status);
    }
}

/* The header of one map (the S or S_ERR extension). */
static void key_map(fitsfile *f, const fitsmap_t *m, const char *extname, int extver, int *status)
{
    char date[40];
    const char *what = "relative sensitivity, mean 1";
    if (strcmp(extname, "S_ERR") == 0) what = "1-sigma uncertainty of S (noise)";
    if (strcmp(extname, "S_RES") == 0) what = "resolution error of S, add to S_ERR in quadrature";
    key_str(f, "EXTNAME", extname, what, status);
    key_int(f, "EXTVER", extver, "map number in this file", status);
    key_str(f, "BUNIT", "", "dimensionless: sensitivity relative to the pixel mean", status);
    key_int(f, "OVERSAMP", m->r, "samples per pixel side (r of the r x r map)", status);
    key_wcs(f, m, status);
    key_dbl(f, "PITCH", m->pitch_um, "[um] pixel pitch", status);
    key_dbl(f, "SUBPIX", m->pitch_um / m->r, "[um] sub-pixel size, pitch / r", status);
    key_int(f, "PIXCOL", m->pixel_col, "sensor pixel column", status);
    key_int(f, "PIXROW", m->pixel_row, "sensor pixel row", status);
    key_dbl(f, "WAVELEN", m->wavelength_um, "[um] wavelength of the scan's spot", status);
    key_dbl(f, "NA", m->na, "numerical aperture of the scan's spot", status);
    key_dbl(f, "SPOTRAD", m->spot_radius_um, "[um] Airy first-zero radius (eq. 1)", status);
    key_dbl(f, "I0", m->I0, "[DN um-2] fitted spot intensity scale", status);
    key_dbl(f, "CHI2RED", m->chi2_red, "reduced chi-square of the fit", status);
    key_str(f, "FITSTAT", m->status, "fit status word", status);
    key_str(f, "NOISEMOD", m->noise_model, "noise model of the fit's sigma", status);
    key_str(f, "SWVERS", m->software_version, "ipsd version that fitted the map", status);
    if (m->calib_id) key_int(f, "CALIBID", m->calib_id, "calibration id", status);
    if (m->sensor_id) key_int(f, "SENSORID", m->sensor_id, "sensor id", status);
    if (m->scan_id) key_int(f, "SCANID", m->scan_id, "scan the map was fitted from", status);
    if (m->fit_id) key_int(f, "FITID", m->fit_id, "fit the map comes from", status);
    if (m->created_ms > 0) {
        iso_date(m->created_ms, date, sizeof date);
        key_str(f, "CALDATE", date, "UTC the calibration was stored", status);
        key_int(f, "CAL_MS", m->created_ms, "the same, ms since 1970-01-01", status);
    }
    if (m->current >= 0)
        fits_write_key_log(f, "CURRENT", m->current != 0, "the pixel's current calibration",
                           status);
    key_str(f, "CALBY", m->by, "who made it the calibration", status);
    key_str(f, "REASON", m->reason, "why", status);
    key_str(f, "IPSMAP", m->map, "recommended r's own, shrunk toward r - 1, or kriged", status);
}

static int check_map(const fitsmap_t *m, size_t k, err_t *err)
{
    if (m->r < 1 || m->r > 256) return err_set(err, -EINVAL, "map %zu: r %d, need 1..256", k, m->r);
    if (!m->S || !m->S_err) return err_set(err, -EINVAL, "map %zu: no S or S_err", k);
    if (!(m->pitch_um > 0) || !isfinite(m->pitch_um))
        return err_set(err, -EINVAL, "map %zu: pitch_um %g, need > 0", k, m->pitch_um);
    return 0;
}

/* ---- the file ---- */

/* realloc for cfitsio's memory file that zeroes what it adds, for the reason below: the grown
 * part may be reused heap memory too (glibc's malloc_usable_size gives the old block's size).
 * Zeroed up to the new block's usable size, not only the size asked for: the bytes between are
 * copied into the next reallocation's block, inside what cfitsio may read there. */
static void *realloc_zeroed(void *p, size_t n)
{
    size_t old = p ? malloc_usable_size(p) : 0;
    void *q = realloc(p, n);
    size_t now = q ? malloc_usable_size(q) : 0;
    if (q && now > old) memset((char *)q + old, 0, now - old);
    return q;
}

int fitsmap_write(const fitsmap_file_t *file, const fitsmap_t *maps, size_t n, void **buf,
                  size_t *len, err_t *err)
{
    *buf = NULL;
    *len = 0;
    if (n < 1 || !maps) return err_set(err, -EINVAL, "no map to write");
    for (size_t k = 0; k < n; k++) {
        int ret = check_map(&maps[k], k, err);
        if (ret) return ret;
    }
    /* zeroed: cfitsio's memory driver reads what lies past the end of the file it writes, and
     * takes an old FITS header left there in reused heap memory (an earlier file's extension)
     * for an HDU of the new file, keeping it and appending after it (test_fitsmap) */
    size_t size = 4 * 2880;
    void *mem = calloc(size, 1);
    if (!mem) return err_set(err, -ENOMEM, "out of memory");
    fitsfile *f = NULL;
    int status = 0;
    char date[40];
    LONGLONG head, data, end = 0;
    if (fits_create_memfile(&f, &mem, &size, 2880 * 8, realloc_zeroed, &status)) {
        free(mem);
        return err_set(err, -ENOMEM, "cfitsio: could not open a memory file (status %d)", status);
    }
    /* the primary HDU: no data, what the whole file shares */
    fits_create_img(f, DOUBLE_IMG, 0, NULL, &status);
    key_str(f, "ORIGIN", "ipsd", "intra-pixel sensitivity maps", &status);
    key_str(f, "CREATOR", file ? file->creator : NULL, "software that wrote the file", &status);
    if (file && file->date_ms > 0) {
        iso_date(file->date_ms, date, sizeof date);
        key_str(f, "DATE", date, "UTC the file was written", &status);
    }
    long long n_res = 0;
    for (size_t k = 0; k < n; k++) n_res += maps[k].S_res != NULL;
    key_int(f, "NMAPS", (long long)n, "maps: extensions ('S', k) and ('S_ERR', k)", &status);
    key_int(f, "NRESMAPS", n_res, "maps with a resolution error: extensions ('S_RES', k)",
            &status);
    if (file && file->sensor_id) key_int(f, "SENSORID", file->sensor_id, "sensor id", &status);
    if (file) {
        key_str(f, "SENSMOD", file->sensor_model, "sensor model", &status);
        key_str(f, "SENSSER", file->sensor_serial, "sensor serial number", &status);
        key_dbl(f, "PITCH", file->pitch_um, "[um] pixel pitch", &status);
    }
    for (size_t k = 0; k < n && !status; k++) {
        const fitsmap_t *m = &maps[k];
        long naxes[2] = {m->r, m->r};
        const char *names[2] = {"S", "S_ERR"};
        const double *arrays[2] = {m->S, m->S_err};
        for (int e = 0; e < 2 && !status; e++) {
            fits_create_img(f, DOUBLE_IMG, 2, naxes, &status);
            key_map(f, m, names[e], (int)k + 1, &status);
            fits_write_img(f, TDOUBLE, 1, (LONGLONG)m->r * m->r, (void *)arrays[e], &status);
        }
    }
    /* the resolution errors after every map's pair, so the pairs keep their places (HDUs 2k - 1
     * and 2k) in files read by position as before they existed */
    for (size_t k = 0; k < n && !status; k++) {
        const fitsmap_t *m = &maps[k];
        if (!m->S_res) continue;
        long naxes[2] = {m->r, m->r};
        fits_create_img(f, DOUBLE_IMG, 2, naxes, &status);
        key_map(f, m, "S_RES", (int)k + 1, &status);
        fits_write_img(f, TDOUBLE, 1, (LONGLONG)m->r * m->r, (void *)m->S_res, &status);
    }
    /* the file ends where the last HDU's padded data end */
    fits_flush_file(f, &status);
    fits_get_hduaddrll(f, &head, &data, &end, &status);
    if (status) {
        char text[FLEN_STATUS];
        fits_get_errstatus(status, text);
        int close_status = 0;
        fits_close_file(f, &close_status);
        free(mem);
        return err_set(err, -EIO, "cfitsio: %s (status %d)", text, status);
    }
    fits_close_file(f, &status);
    if (status || end <= 0 || (size_t)end > size) {
        free(mem);
        return err_set(err, -EIO, "cfitsio: closing the memory file failed (status %d)", status);
    }
    *buf = mem;
    *len = (size_t)end;
    return 0;
}
