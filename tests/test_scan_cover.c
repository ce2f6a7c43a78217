/* test_scan_cover.c: which pixels a raster covers (instrument/scan_cover.h), on rasters whose
 * coverage is plain arithmetic: the paper's 5 x 5-pixel raster in 0.6 um steps on 6 um pixels
 * covers exactly its 25 pixels with 9 x 9 positions inside each; a 1-pixel raster in 3 um steps
 * has a single position inside its pixel (too few); a raster shifted by 2 um misses an edge. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "instrument/scan_cover.h"

/* An n x n raster of step s centred on (cx, cy). */
static size_t grid(int n, double s, double cx, double cy, double **x, double **y)
{
    size_t k = 0;
    *x = malloc((size_t)n * n * sizeof **x);
    *y = malloc((size_t)n * n * sizeof **y);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++, k++) {
            (*x)[k] = cx + (i - (n - 1) / 2.0) * s;
            (*y)[k] = cy + (j - (n - 1) / 2.0) * s;
        }
    return k;
}

int main(void)
{
    scan_setup_t su;
    memset(&su, 0, sizeof su);
    su.pitch_um = 6;
    su.centre.x_um = 100;
    su.centre.y_um = 200;
    double *x, *y;
    scan_cover_t c;
    /* the paper's raster: 51 x 51 points over 5 x 5 pixels */
    size_t n = grid(51, 0.6, 100, 200, &x, &y);
    int covered = 0;
    for (int dr = -4; dr <= 4; dr++)
        for (int dc = -4; dc <= 4; dc++) {
            scan_pixel_cover(&su, dc, dr, 0.6, x, y, n, &c);
            int inner = abs(dc) <= 2 && abs(dr) <= 2;
            CHECK(c.covered == inner);
            CHECK(!inner || c.n_inside == 81);
            CHECK(inner == (c.reason[0] == 0));
            covered += c.covered;
        }
    CHECK(covered == 25);
    scan_pixel_cover(&su, 3, 0, 0.6, x, y, n, &c);
    CHECK(strstr(c.reason, "right edge") != NULL && c.n_inside == 0);
    scan_pixel_cover(&su, 0, -3, 0.6, x, y, n, &c);
    CHECK(strstr(c.reason, "top edge") != NULL);
    free(x);
    free(y);
    /* shifted by 2 um to the right: the POI's left edge is not reached within half a step */
    n = grid(51, 0.6, 102, 200, &x, &y);
    scan_pixel_cover(&su, -2, 0, 0.6, x, y, n, &c);
    CHECK(!c.covered && strstr(c.reason, "left edge") != NULL);
    scan_pixel_cover(&su, 0, 0, 0.6, x, y, n, &c);
    CHECK(c.covered && c.n_inside == 10 * 9); /* 97.2 .. 102.6 in x, 9 rows in y */
    free(x);
    free(y);
    /* 3 x 3 points in 3 um steps over one pixel: edges reached, one position inside */
    n = grid(3, 3, 100, 200, &x, &y);
    scan_pixel_cover(&su, 0, 0, 3, x, y, n, &c);
    CHECK(!c.covered && c.n_inside == 1 && strstr(c.reason, "only 1") != NULL);
    free(x);
    free(y);
    scan_pixel_cover(&su, 0, 0, 0.6, NULL, NULL, 0, &c);
    CHECK(!c.covered && c.reason[0]);
    CHECK_DONE();
}
