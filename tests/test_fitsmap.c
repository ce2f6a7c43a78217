/* test_fitsmap.c: the FITS files fitsmap_write builds in memory, read back by a minimal reader
 * written here (80-byte cards in 2880-byte blocks, FITS standard 4.0 sections 3-4; independent
 * of cfitsio): the HDU count is 1 + 2 x NMAPS + NRESMAPS, the extensions S and S_ERR alternate
 * with EXTVER 1..n, then S_RES of the maps that have one, and each holds its map's values
 * (big-endian float64). A regression test: a file written
 * after another into reused heap memory once held an old extension (cfitsio's memory file took
 * a stale header left in the uninitialised buffer for an HDU of the new file; the API's
 * calibrations.fits showed it in one run of ten on a busy machine). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "export/fitsmap.h"

/* The card's value after "KEY     = " as text (NULL when the header has no such card). */
static const char *card(const char *hdr, size_t ncards, const char *key, char *out, size_t n)
{
    for (size_t c = 0; c < ncards; c++) {
        const char *k = hdr + 80 * c;
        size_t kl = strlen(key);
        if (strncmp(k, key, kl) == 0 && (k[kl] == ' ' || k[kl] == '=') && k[8] == '=') {
            size_t len = 70 < n - 1 ? 70 : n - 1;
            memcpy(out, k + 10, len);
            out[len] = 0;
            return out;
        }
    }
    return NULL;
}

static double be_double(const unsigned char *p)
{
    uint64_t u = 0;
    for (int i = 0; i < 8; i++) u = (u << 8) | p[i];
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* Walks the file: checks every HDU against maps (n of them); returns the HDUs found. */
static int walk(const unsigned char *buf, size_t len, const fitsmap_t *maps, int n)
{
    size_t at = 0;
    int hdus = 0;
    while (at + 2880 <= len) {
        const char *hdr = (const char *)buf + at;
        size_t ncards = 0;
        while (at + 80 * (ncards + 1) <= len && strncmp(hdr + 80 * ncards, "END     ", 8) != 0)
            ncards++;
        size_t hbytes = (80 * (ncards + 1) + 2879) / 2880 * 2880;
        char v[80];
        long naxis = card(hdr, ncards, "NAXIS", v, sizeof v) ? atol(v) : -1;
        long n1 = naxis >= 1 && card(hdr, ncards, "NAXIS1", v, sizeof v) ? atol(v) : 0;
        long n2 = naxis >= 2 && card(hdr, ncards, "NAXIS2", v, sizeof v) ? atol(v) : 0;
        size_t dbytes = naxis > 0 ? ((size_t)n1 * (size_t)n2 * 8 + 2879) / 2880 * 2880 : 0;
        if (hdus > 2 * n) { /* after the pairs: S_RES of the maps that have one, in order */
            int m = 0, seen = 0;
            while (m < n && seen <= hdus - 2 * n - 1) seen += maps[m++].S_res != NULL;
            char name[80] = "", word[80] = "";
            card(hdr, ncards, "EXTNAME", name, sizeof name);
            sscanf(name, "'%79[^' ]", word);
            long ver = card(hdr, ncards, "EXTVER", v, sizeof v) ? atol(v) : 0;
            CHECK(strcmp(word, "S_RES") == 0 && ver == m && m >= 1 && maps[m - 1].S_res);
            if (m >= 1 && maps[m - 1].S_res && at + hbytes + (size_t)n1 * n2 * 8 <= len) {
                const fitsmap_t *f = &maps[m - 1];
                CHECK(n1 == f->r && n2 == f->r);
                for (long q = 0; q < n1 * n2 && n1 == f->r && n2 == f->r; q++)
                    CHECK(be_double(buf + at + hbytes + 8 * (size_t)q) == f->S_res[q]);
            }
        } else if (hdus > 0) { /* extension k: S or S_ERR of map (k + 1) / 2 */
            int m = (hdus + 1) / 2, err = hdus % 2 == 0;
            char name[80] = "", word[80] = "";
            card(hdr, ncards, "EXTNAME", name, sizeof name); /* 'S       ': quoted, padded */
            sscanf(name, "'%79[^' ]", word);
            long ver = card(hdr, ncards, "EXTVER", v, sizeof v) ? atol(v) : 0;
            CHECK(strcmp(word, err ? "S_ERR" : "S") == 0 && ver == m);
            if (m <= n && at + hbytes + (size_t)n1 * n2 * 8 <= len) {
                const fitsmap_t *f = &maps[m - 1];
                CHECK(n1 == f->r && n2 == f->r);
                const double *want = err ? f->S_err : f->S;
                for (long q = 0; q < n1 * n2 && n1 == f->r && n2 == f->r; q++)
                    CHECK(be_double(buf + at + hbytes + 8 * (size_t)q) == want[q]);
            }
        } else {
            long nmaps = card(hdr, ncards, "NMAPS", v, sizeof v) ? atol(v) : -1;
            CHECK(nmaps == n);
            long nres = card(hdr, ncards, "NRESMAPS", v, sizeof v) ? atol(v) : -1, want = 0;
            for (int m = 0; m < n; m++) want += maps[m].S_res != NULL;
            CHECK(nres == want);
        }
        hdus++;
        at += hbytes + dbytes;
    }
    CHECK(at == len);
    return hdus;
}

int main(void)
{
    enum { R = 7, N = 3 };
    double S[N][R * R], E[N][R * R];
    fitsmap_t maps[N];
    for (int k = 0; k < N; k++) {
        for (int j = 0; j < R * R; j++) S[k][j] = 1 + 0.01 * (j - 24) * (k + 1), E[k][j] = 0.01;
        maps[k] = (fitsmap_t){.r = k == 2 ? R : 1 + 3 * k, .S = S[k], .S_err = E[k],
                              .pitch_um = 6, .pixel_col = 10 + k, .pixel_row = 11,
                              .wavelength_um = NAN, .na = NAN, .spot_radius_um = NAN,
                              .I0 = 4000, .chi2_red = 1, .status = "ok", .noise_model = "paper",
                              .calib_id = k + 1, .sensor_id = 1};
    }
    fitsmap_t big = maps[2];
    big.pixel_col = 40, big.pixel_row = 30;
    fitsmap_file_t file = {.creator = "test", .sensor_id = 1, .sensor_model = "M",
                           .sensor_serial = "s", .pitch_um = 6, .date_ms = 0};
    /* one map, freed, then three, as the API answers map.fits then calibrations.fits: the second
     * buffer is the first's memory again */
    for (int round = 0; round < 20; round++) {
        void *buf;
        size_t len;
        err_t err;
        CHECK(fitsmap_write(&file, &big, 1, &buf, &len, &err) == 0);
        CHECK(walk(buf, len, &big, 1) == 3);
        free(buf);
        CHECK(fitsmap_write(&file, maps, N, &buf, &len, &err) == 0);
        int h = walk(buf, len, maps, N);
        if (h != 1 + 2 * N) fprintf(stderr, "round %d: %d HDUs, want %d\n", round, h, 1 + 2 * N);
        CHECK(h == 1 + 2 * N);
        free(buf);
    }
    /* resolution errors on the first and the last map: two S_RES extensions after the three
     * pairs, which keep their places */
    {
        double RS[N][R * R];
        fitsmap_t wr[N];
        for (int k = 0; k < N; k++) {
            wr[k] = maps[k];
            for (int j = 0; j < R * R; j++) RS[k][j] = 0.001 * (j + 1) * (k + 1);
        }
        wr[0].S_res = RS[0], wr[2].S_res = RS[2];
        void *buf;
        size_t len;
        err_t err;
        CHECK(fitsmap_write(&file, wr, N, &buf, &len, &err) == 0);
        CHECK(walk(buf, len, wr, N) == 1 + 2 * N + 2);
        free(buf);
    }
    /* larger maps (r = 30: three data blocks each), so the file outgrows the first buffer and
     * cfitsio reallocates it: the grown part must hold no old header either */
    enum { RB = 30 };
    static double SB[N][RB * RB], EB[N][RB * RB];
    fitsmap_t bigs[N];
    for (int k = 0; k < N; k++) {
        for (int j = 0; j < RB * RB; j++) SB[k][j] = 1 + 1e-4 * j * (k + 1), EB[k][j] = 0.02;
        bigs[k] = maps[k];
        bigs[k].r = RB, bigs[k].S = SB[k], bigs[k].S_err = EB[k];
    }
    for (int round = 0; round < 20; round++) {
        void *buf;
        size_t len;
        err_t err;
        int n = round % 2 ? N : 1; /* alternately one map and three */
        const fitsmap_t *mp = n == 1 ? &bigs[round % N] : bigs;
        CHECK(fitsmap_write(&file, mp, (size_t)n, &buf, &len, &err) == 0);
        int h = walk(buf, len, mp, n);
        if (h != 1 + 2 * n) fprintf(stderr, "r = %d, round %d: %d HDUs, want %d\n", RB, round, h,
                                    1 + 2 * n);
        CHECK(h == 1 + 2 * n);
        free(buf);
    }
    /* the heap full of old FITS headers before each file: blocks of many sizes (below glibc's
     * mmap threshold, so they stay in the heap) filled with copies of a written file, freed; then
     * a file with S_RES extensions, whose growth takes several reallocations (each may land on
     * such a block, and bytes past the size cfitsio asked for are still inside the next
     * reallocation's copy) */
    {
        double RS[N][RB * RB];
        fitsmap_t wr[N];
        for (int k = 0; k < N; k++) {
            wr[k] = bigs[k];
            for (int j = 0; j < RB * RB; j++) RS[k][j] = 1e-3 * (j % 17 + 1);
            wr[k].S_res = RS[k];
        }
        void *old;
        size_t olen;
        err_t err;
        CHECK(fitsmap_write(&file, bigs, N, &old, &olen, &err) == 0);
        for (int round = 0; round < 40; round++) {
            void *junk[24];
            for (int b = 0; b < 24; b++) {
                size_t sz = 2880 * (size_t)(3 + (b * 7 + round) % 40);
                junk[b] = malloc(sz);
                for (size_t at = 0; junk[b] && at < sz; at += olen)
                    memcpy((char *)junk[b] + at, old, sz - at < olen ? sz - at : olen);
            }
            for (int b = 0; b < 24; b += 2) free(junk[b]); /* holes between live blocks */
            void *buf;
            size_t len;
            int n = 1 + round % N;
            CHECK(fitsmap_write(&file, wr, (size_t)n, &buf, &len, &err) == 0);
            int h = walk(buf, len, wr, n);
            if (h != 1 + 3 * n)
                fprintf(stderr, "dirty heap, round %d: %d HDUs, want %d\n", round, h, 1 + 3 * n);
            CHECK(h == 1 + 3 * n);
            free(buf);
            for (int b = 1; b < 24; b += 2) free(junk[b]);
        }
        free(old);
    }
    CHECK_DONE();
}
