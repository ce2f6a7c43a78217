/* test_design.c: the fast design matrix against the accurate box integral (an independent
 * algorithm: polar rays, adaptive Gauss-Kronrod) for the reference scan positions at every r of
 * the sweep and for the extreme spots, conservation (each row sums to the whole-pixel box),
 * spots on sub-pixel edges and corners, and the leave-out rule's bound. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "fit/airy.h"
#include "fit/box.h"
#include "check.h"
#include "fit/design.h"

/* Largest |A - box| relative to the largest entry of the row, over all rows. */
static double design_error(double R, int r, const double *x, const double *y, int n, double tol,
                           fit_design_stats_t *st)
{
    double *A = malloc(sizeof(double) * n * r * r), worst = 0;
    fit_design_opts_t o = fit_design_opts_for_tol(tol);
    CHECK(fit_design_build(R, 6.0, r, x, y, (size_t)n, &o, A, st, NULL) == 0);
    for (int k = 0; k < n; k++) {
        double rowmax = 0, err = 0;
        for (int c = 0; c < r * r; c++) {
            fit_rect_t b = {6.0 * (c % r) / r, 6.0 * (c % r + 1) / r, 6.0 * (c / r) / r,
                            6.0 * (c / r + 1) / r};
            double v, e;
            fit_box_integral(R, &b, x[k], y[k], 1e-13, &v, &e, NULL);
            rowmax = fmax(rowmax, v);
            err = fmax(err, fabs(A[k * r * r + c] - v));
        }
        worst = fmax(worst, err / rowmax);
    }
    free(A);
    return worst;
}

static void grid(double *x, double *y, int ng, double x0, double step)
{
    for (int q = 0; q < ng * ng; q++) {
        x[q] = x0 + step * (q % ng);
        y[q] = x0 + step * (q / ng);
    }
}

int main(void)
{
    double x[81], y[81];
    grid(x, y, 9, 0.6, 0.6); /* the paper's 9 x 9 positions inside the pixel */
    fit_design_stats_t st;
    for (int r = 1; r <= 8; r++) CHECK(design_error(1.34, r, x, y, 81, 1e-12, &st) < 1e-12);
    CHECK(design_error(1.34, 7, x, y, 81, 1e-9, &st) < 1e-9);
    CHECK(design_error(30, 7, x, y, 81, 1e-12, &st) < 1e-11);
    CHECK(design_error(0.05, 7, x, y, 81, 1e-10, &st) < 1e-10);
    /* spots exactly on sub-pixel edges and corners (e = 6 i / r) */
    double xe[4] = {0, 3, 6, 1.5}, ye[4] = {0, 3, 1.5, 6};
    CHECK(design_error(1.34, 4, xe, ye, 4, 1e-12, &st) < 1e-12);
    CHECK(design_error(0.3, 4, xe, ye, 4, 1e-12, &st) < 1e-12);
    /* spots outside the pixel: every entry is a small difference of tail fluxes, and still
     * within the setting's tolerance of the row's largest */
    double xo[3] = {-2, 8, 3}, yo[3] = {7, -1, -0.75};
    CHECK(design_error(1.34, 4, xo, yo, 3, 1e-12, &st) < 1e-12);
    /* the raster of a fit of the whole scan (`--region all`): spots up to 12 um (18 cells) from
     * the pixel beside it and across its corners, in one batch: lines at the same distance share
     * a sweep from the foot, or, beyond an edge, have their own from the nearest node. Before
     * sweeps were kept as offsets from their origin, with short segments near it (wedge_sweep.c's
     * sweep_extend), these rows lost up to 9e-11 (R = 1.34 and 5, r = 7: now 5e-14 and 3e-13)
     * and 4e-8 at the 1e-9 setting (R = 0.3: now 6e-11) */
    {
        enum { NO = 24 };
        double xa[NO * NO], ya[NO * NO];
        int na = 0;
        for (int q = 0; q < NO * NO; q++) {
            double xq = -12 + 1.3 * (q % NO), yq = -12 + 1.3 * (q / NO);
            if (xq >= 0 && xq <= 6 && yq >= 0 && yq <= 6) continue; /* outside only */
            xa[na] = xq, ya[na++] = yq;
        }
        CHECK(design_error(1.34, 3, xa, ya, na, 1e-12, &st) < 1e-12);
        CHECK(design_error(1.34, 7, xa, ya, na, 1e-12, &st) < 1e-12);
        CHECK(design_error(5.0, 7, xa, ya, na, 1e-12, &st) < 1e-12);
        CHECK(design_error(0.3, 7, xa, ya, na, 1e-9, &st) < 1e-9);
    }

    /* conservation: each row sums to the box integral of the whole pixel */
    double A[81 * 64];
    fit_design_opts_t o = fit_design_opts_for_tol(1e-12);
    CHECK(fit_design_build(1.34, 6.0, 8, x, y, 81, &o, A, &st, NULL) == 0);
    for (int k = 0; k < 81; k++) {
        double sum = 0, v, e;
        for (int c = 0; c < 64; c++) sum += A[k * 64 + c];
        fit_rect_t pix = {0, 6, 0, 6};
        fit_box_integral(1.34, &pix, x[k], y[k], 1e-14, &v, &e, NULL);
        CHECK_NEAR(sum, v, 1e-12, 0);
    }
    CHECK(st.skipped == 0 && st.entries == 81 * 64);

    /* leave-out: a tiny spot with a loose skip tolerance leaves out far sub-pixels; every one of
     * them is truly below the reported largest bound, and the rest stay accurate */
    o.skip_tol = 1e-3;
    CHECK(fit_design_build(0.05, 6.0, 8, x, y, 81, &o, A, &st, NULL) == 0);
    CHECK(st.skipped > 1000 && st.max_skipped_bound > 0);
    CHECK(st.max_skipped_bound < 1e-3 * fit_airy_total(fit_airy_a(0.05)));
    int bound_holds = 1;
    for (int k = 0; k < 81; k++)
        for (int c = 0; c < 64; c++) {
            fit_rect_t b = {0.75 * (c % 8), 0.75 * (c % 8 + 1), 0.75 * (c / 8), 0.75 * (c / 8 + 1)};
            double v, e;
            fit_box_integral(0.05, &b, x[k], y[k], 1e-12, &v, &e, NULL);
            if (A[k * 64 + c] == 0) bound_holds &= v <= st.max_skipped_bound;
            else CHECK_NEAR(A[k * 64 + c], v, 1e-6, 1e-14);
        }
    CHECK(bound_holds);

    /* a uniform map with the spot deep inside a large pixel collects the whole-plane flux but
     * for the tail beyond the pixel, which lies between the flux outside the circumscribed and
     * the inscribed disc of the centred square: total Q(a L sqrt 2) and total Q(a L) */
    for (int r = 1; r <= 3; r++) {
        double xc = 150, yc = 150, row[9], sum = 0, a = fit_airy_a(1.34), qi, qo, p;
        fit_design_opts_t od = fit_design_opts_for_tol(1e-12);
        CHECK(fit_design_build(1.34, 300, r, &xc, &yc, 1, &od, row, NULL, NULL) == 0);
        for (int c = 0; c < r * r; c++) sum += row[c];
        fit_radial(a * 150, &qi, &p);
        fit_radial(a * 150 * sqrt(2), &qo, &p);
        double total = fit_airy_total(a);
        CHECK(total - sum <= total * qi * (1 + 1e-9) && total - sum >= total * qo * (1 - 1e-9));
        CHECK_NEAR(sum, total, 2e-3, 0); /* the tail beyond 150 um is ~ 2/(pi a 150) = 1.5e-3 */
    }

    /* the sweep cache (design.h): one cache serving every r of a sweep, in the order a sweep runs
     * them and again (as the F-test refits an r), gives exactly the matrix of a call without one,
     * on the paper's grid and on an irregular raster (positions from a fixed LCG, inside and
     * just outside the pixel), and both stay within the tolerance of the box integral (the
     * independent reference). A cache built for other options is bypassed, not misused. */
    {
        double xi[60], yi[60];
        unsigned long long s = 12345;
        for (int k = 0; k < 60; k++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            xi[k] = -0.8 + 7.6 * (double)(s >> 11) / 9007199254740992.0;
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            yi[k] = -0.8 + 7.6 * (double)(s >> 11) / 9007199254740992.0;
        }
        const double *px[2] = {x, xi}, *py[2] = {y, yi};
        int pn[2] = {81, 60};
        for (int set = 0; set < 2; set++) {
            fit_design_cache_t *cache = fit_design_cache_new();
            CHECK(cache != NULL);
            int order[10] = {1, 2, 3, 4, 5, 6, 7, 8, 7, 4}, same = 1;
            for (int q = 0; q < 10; q++) {
                int r = order[q], n = pn[set];
                double *A1 = malloc(sizeof(double) * n * r * r), *A2 = malloc(sizeof(double) * n * r * r);
                fit_design_opts_t oc = fit_design_opts_for_tol(1e-12), on = oc;
                oc.cache = cache;
                CHECK(fit_design_build(1.34, 6.0, r, px[set], py[set], (size_t)n, &oc, A1, NULL, NULL) == 0);
                CHECK(fit_design_build(1.34, 6.0, r, px[set], py[set], (size_t)n, &on, A2, NULL, NULL) == 0);
                for (int i = 0; i < n * r * r; i++) same &= A1[i] == A2[i];
                free(A1);
                free(A2);
            }
            CHECK(same);
            fit_design_cache_stats_t cs = fit_design_cache_stats(cache);
            CHECK(cs.hits > cs.misses && cs.sweeps == cs.misses && cs.bytes > 0);
            /* other options: bypassed (no new sweeps), still right */
            double Ab[81 * 9];
            fit_design_opts_t ob = fit_design_opts_for_tol(1e-6);
            ob.cache = cache;
            CHECK(fit_design_build(1.34, 6.0, 3, px[set], py[set], (size_t)pn[set], &ob, Ab, NULL, NULL) == 0);
            CHECK(fit_design_cache_stats(cache).sweeps == cs.sweeps);
            /* the other shape of sweeps (set 0 has every spot inside the pixel, set 1 some
             * outside: short segments near the foot, design.h): bypassed too, and the matrix
             * is the one of a call without a cache, bit for bit */
            int other = 1 - set, no = pn[other];
            double *Ao = malloc(sizeof(double) * no * 16), *An = malloc(sizeof(double) * no * 16);
            fit_design_opts_t oo = fit_design_opts_for_tol(1e-12), onc = oo;
            oo.cache = cache;
            CHECK(fit_design_build(1.34, 6.0, 4, px[other], py[other], (size_t)no, &oo, Ao, NULL,
                                   NULL) == 0);
            CHECK(fit_design_build(1.34, 6.0, 4, px[other], py[other], (size_t)no, &onc, An, NULL,
                                   NULL) == 0);
            int same_other = 1;
            for (int i = 0; i < no * 16; i++) same_other &= Ao[i] == An[i];
            CHECK(same_other && fit_design_cache_stats(cache).sweeps == cs.sweeps);
            free(Ao);
            free(An);
            fit_design_cache_free(cache);
        }
        for (int r = 3; r <= 8; r += 5) CHECK(design_error(1.34, r, xi, yi, 60, 1e-12, &st) < 1e-12);
    }

    /* a raster too large for one batch of rows (r = 40: some 600 spots a batch, design.c): every
     * row is the row of its spot designed alone (no row of wedges shared with another spot, no
     * batch boundary), bit for bit, at the batches' edges and inside them, and a column and a
     * row of cells through the spot (near a node: four cells hold it) are within the tolerance
     * of the box integral. Rows are shared within a batch, not across: a spot's row must not depend on
     * which others share its batch. */
    {
        enum { NG = 37, R = 40 };
        double *xr = malloc(sizeof(double) * NG * NG), *yr = malloc(sizeof(double) * NG * NG);
        double *Ar = malloc(sizeof(double) * NG * NG * R * R), one[R * R];
        CHECK(xr && yr && Ar);
        grid(xr, yr, NG, 0.3, 0.15);
        fit_design_opts_t od = fit_design_opts_for_tol(1e-12);
        CHECK(fit_design_build(1.34, 6.0, R, xr, yr, NG * NG, &od, Ar, NULL, NULL) == 0);
        int rows[] = {0, 1, 300, 611, 612, 613, 614, 900, 1225, 1226, NG * NG - 1}, same = 1;
        for (size_t q = 0; q < sizeof rows / sizeof rows[0]; q++) {
            int k = rows[q];
            CHECK(fit_design_build(1.34, 6.0, R, &xr[k], &yr[k], 1, &od, one, NULL, NULL) == 0);
            for (int c = 0; c < R * R; c++) same &= Ar[(size_t)k * R * R + c] == one[c];
        }
        CHECK(same);
        int k = 700; /* grid (34, 18): x 5.4, y 3.0, about a node of the 40 x 40 grid */
        double worst = 0, rowmax = 0;
        for (int q = 0; q < 2 * R; q++) { /* the cells of column i = 36, then of row j = 20 */
            int c = q < R ? q * R + 36 : 20 * R + (q - R);
            fit_rect_t b = {6.0 * (c % R) / R, 6.0 * (c % R + 1) / R, 6.0 * (c / R) / R,
                            6.0 * (c / R + 1) / R};
            double v, e;
            fit_box_integral(1.34, &b, xr[k], yr[k], 1e-13, &v, &e, NULL);
            rowmax = fmax(rowmax, v);
            worst = fmax(worst, fabs(Ar[(size_t)k * R * R + c] - v));
        }
        CHECK(worst < 1e-12 * rowmax);
        free(xr);
        free(yr);
        free(Ar);
    }

    /* sweeps from a line's nearest needed node (design.c's sweep_offset_pays): a batch that
     * mixes, at the same distances from the lines, spots beyond an edge of the pixel (every node
     * of a line on one side of the spot's foot: a sweep of their own, the prefix below the nearest
     * node left out, which cancels in every cell) and spots across from the pixel (their lines
     * straddle the foot: the shared sweep from it), against the box integral */
    {
        double xm[20], ym[20];
        const double across[2] = {-2.5, 8.5}, along[5] = {-1.5, 0.7, 3.0, 5.2, 7.5};
        for (int q = 0; q < 10; q++) {
            xm[q] = across[q / 5], ym[q] = along[q % 5];
            xm[10 + q] = along[q % 5], ym[10 + q] = across[q / 5];
        }
        fit_design_stats_t sm;
        CHECK(design_error(0.3, 5, xm, ym, 20, 1e-12, &sm) < 1e-11);
        CHECK(design_error(1.34, 4, xm, ym, 20, 1e-12, &sm) < 1e-11);
        /* a 0.012 um spot 0.5 mm away, about 1e5 Airy rings between it and the pixel: its sweeps
         * cross only the rings between each line's nodes, a twentieth of those from the foot
         * (counted here from the segment rule: e^0.5 in E or 2 in a rho per segment, 16 points
         * each at 1e-12), and its entries are within 1e-11 of the box integral (5e-12 at r = 4;
         * 5e-11 before the sweeps were kept as offsets from their origin; from the foot, 2.8e6
         * evaluations, they lost 2e-10 to 2e-9: each a difference of two large prefixes) */
        double xf = 500, yf = 300, a = fit_airy_a(0.0122), foot = 0;
        for (int r = 2; r <= 4; r += 2) {
            fit_design_stats_t sf;
            CHECK(design_error(0.0122, r, &xf, &yf, 1, 1e-12, &sf) < 1e-11);
            foot = 0;
            for (int dir = 0; dir < 2; dir++) {
                double ac = dir ? yf : xf, al = dir ? xf : yf, other = fmax(fabs(al), fabs(6 - al));
                for (int l = 0; l <= r; l++) {
                    double dist = fabs(6.0 * l / r - ac), w = a * dist;
                    double E = (other + sqrt(other * other + dist * dist)) / dist;
                    foot += 16 * (ceil(log(E) / 0.5) + ceil((w * (E + 1 / E) / 2 - w) / 2) + 1);
                }
            }
            CHECK(sf.radial_evals > 0 && 20.0 * (double)sf.radial_evals < foot);
        }
    }

    /* fit_design_cost, the bound a caller puts on a build before running it (the jitter API),
     * against the radial evaluations a build of the one spot reports having taken (nothing
     * shared, no cache): never below them, at most three times them, for the reference spot
     * inside the pixel, a small spot outside it, and a 0.012 um spot 0.5 mm away (1e5 Airy
     * rings between it and the pixel, though its sweeps cross only those over the pixel: nearly
     * all of its cost beyond the radial table, none of the reference spot's); bad arguments
     * cost 0 */
    {
        struct {
            double R, x, y;
            int r;
        } cs[] = {{1.34, 3.1, 2.7, 8}, {0.05, -5, 9, 4}, {0.0122, 500, 300, 2}};
        for (int i = 0; i < 3; i++) {
            double Ac[64], far;
            fit_design_opts_t oc = fit_design_opts_for_tol(1e-10);
            fit_design_stats_t sc;
            CHECK(fit_design_build(cs[i].R, 6.0, cs[i].r, &cs[i].x, &cs[i].y, 1, &oc, Ac, &sc,
                                   NULL) == 0);
            double cost = fit_design_cost(cs[i].R, 6.0, cs[i].r, &cs[i].x, &cs[i].y, 1, &oc, &far);
            CHECK(sc.radial_evals > 0 && cost >= (double)sc.radial_evals &&
                  cost <= 3.0 * (double)sc.radial_evals);
            if (i == 0) CHECK(far == 0);                      /* a rho <= 30 over the pixel */
            if (i == 2) CHECK(far > 0.9 * cost && cost < 1e6); /* a rho ~ 1.5e5 */
        }
        double xb = NAN, yb = 1, far = 1;
        CHECK(fit_design_cost(1.34, 6.0, 4, &xb, &yb, 1, NULL, &far) == 0 && far == 0);
    }

    /* bad arguments */
    err_t err;
    CHECK(fit_design_build(0, 6, 3, x, y, 81, NULL, A, NULL, &err) == -EINVAL);
    CHECK(fit_design_build(1, -6, 3, x, y, 81, NULL, A, NULL, &err) == -EINVAL);
    CHECK(fit_design_build(1, 6, 0, x, y, 81, NULL, A, NULL, &err) == -EINVAL);
    x[5] = NAN;
    CHECK(fit_design_build(1, 6, 3, x, y, 81, NULL, A, NULL, &err) == -EINVAL);
    CHECK_DONE();
}
