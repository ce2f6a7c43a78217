/* fuzz_scanfile.c: the scan-file reader (instrument/scanfile.c, the `ips fit` input and the API's
 * upload format) on any bytes. A file it accepts must hold what the contract promises: equal
 * arrays of n points, finite positive constants; and it must write back (scanfile_dump) as a file
 * that reads back to the same points. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_api.h"
#include "instrument/scanfile.h"

static void must(int ok, const char *what)
{
    if (ok) return;
    fprintf(stderr, "fuzz_scanfile: %s\n", what);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    scanfile_t sf, back;
    const char *field = NULL;
    err_t err = {{0}};
    int ret = scanfile_parse((const char *)data, size, &sf, &field, &err);
    if (ret) {
        must(err.msg[0] != 0, "an error without a message");
        return 0;
    }
    const fit_scan_t *s = &sf.scan;
    must(s->n == 0 || (s->x_um && s->y_um && s->signal_dn), "points without arrays");
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    must(f != NULL, "open_memstream");
    int dumped = scanfile_dump(f, s, NULL, &err);
    fclose(f);
    if (dumped == 0) {
        must(scanfile_parse(text, len, &back, &field, &err) == 0, "its dump does not read back");
        must(back.scan.n == s->n, "its dump reads back another number of points");
        for (size_t i = 0; i < s->n; i++) {
            double a = s->signal_dn[i], b = back.scan.signal_dn[i];
            must((isnan(a) && isnan(b)) || a == b || (!isfinite(a) && isnan(b)),
                 "its dump reads back another signal");
            must(s->x_um[i] == back.scan.x_um[i] || (isnan(s->x_um[i]) && isnan(back.scan.x_um[i])) ||
                     !isfinite(s->x_um[i]),
                 "its dump reads back another x");
        }
        scanfile_free(&back);
    }
    free(text);
    scanfile_free(&sf);
    return 0;
}
