/* test_box.c: the accurate box integral against the 60 published boxes of
 * tests/data/airy_box.json (1e-12 relative, 1e-18 absolute), its error bound against the true
 * error, conservation (additivity over splits), symmetry, the whole-plane flux as the limit of
 * a growing box, and bad arguments. */
#include <errno.h>
#include <jansson.h>

#include "fit/airy.h"
#include "fit/box.h"
#include "check.h"

static double box(double R, double x0, double x1, double y0, double y1, double xk, double yk)
{
    fit_rect_t b = {x0, x1, y0, y1};
    double v, e;
    err_t err;
    if (fit_box_integral(R, &b, xk, yk, 1e-13, &v, &e, &err) != 0)
        fprintf(stderr, "box R=%g [%g,%g]x[%g,%g] at (%g,%g): %s\n", R, x0, x1, y0, y1, xk, yk, err.msg);
    return v;
}

static void test_reference(void)
{
    json_error_t je;
    json_t *ref = json_load_file("airy_box.json", 0, &je), *b;
    CHECK(ref != NULL);
    size_t i, count = 0;
    json_array_foreach(json_object_get(ref, "boxes"), i, b)
    {
#define F(k) json_number_value(json_object_get(b, k))
        fit_rect_t r = {F("x0"), F("x1"), F("y0"), F("y1")};
        double v, e, want = F("value");
        CHECK(fit_box_integral(F("R"), &r, F("xk"), F("yk"), 1e-13, &v, &e, NULL) == 0);
        CHECK_NEAR(v, want, 1e-12, 1e-18);
        CHECK(fabs(v - want) <= e + F("abs_err_bound")); /* the returned bound holds */
        CHECK(e <= 1e-12 * want + 1e-18);                /* and is useful */
        count++;
#undef F
    }
    CHECK(count == 60);
    json_decref(ref);
}

static void test_conservation_and_symmetry(void)
{
    double Rs[] = {0.05, 1.34, 30};
    for (int q = 0; q < 3; q++) {
        double R = Rs[q];
        /* additivity: a box split at a line through, beside and far from the spot */
        double whole = box(R, 0, 6, 0, 6, 2.2, 3.1);
        double parts = box(R, 0, 2.2, 0, 3.1, 2.2, 3.1) + box(R, 2.2, 6, 0, 3.1, 2.2, 3.1) +
                       box(R, 0, 2.2, 3.1, 6, 2.2, 3.1) + box(R, 2.2, 6, 3.1, 6, 2.2, 3.1);
        CHECK_NEAR(parts, whole, 1e-13, 0);
        double strips = box(R, 0, 1, 0, 6, 2.2, 3.1) + box(R, 1, 4.5, 0, 6, 2.2, 3.1) +
                        box(R, 4.5, 6, 0, 6, 2.2, 3.1);
        CHECK_NEAR(strips, whole, 1e-13, 0);
        /* mirror symmetry of the Airy */
        CHECK_NEAR(box(R, 1, 2, 3, 5, -4, 0.5), box(R, -2, -1, 3, 5, 4, 0.5), 1e-13, 0);
        CHECK_NEAR(box(R, 1, 2, 3, 5, -4, 0.5), box(R, 3, 5, 1, 2, 0.5, -4), 1e-13, 0);
        /* a spot on an edge and on a corner: halves and quarters of symmetric boxes */
        CHECK_NEAR(box(R, 0, 2, -1, 1, 0, 0), box(R, -2, 2, -1, 1, 0, 0) / 2, 1e-13, 0);
        CHECK_NEAR(box(R, 0, 2, 0, 2, 0, 0), box(R, -2, 2, -2, 2, 0, 0) / 4, 1e-13, 0);
        /* whole-plane limit: the flux outside a centred square of half-side L lies between the
         * flux outside its circumscribed and inscribed discs, Q(a L sqrt 2) and Q(a L) */
        double a = fit_airy_a(R), total = fit_airy_total(a);
        for (double L = 5 * R; L < 400 * R; L *= 4) {
            double in = box(R, -L, L, -L, L, 0, 0), qi, pi_, qo, po;
            fit_radial(a * L, &qi, &pi_);
            fit_radial(a * L * sqrt(2), &qo, &po);
            CHECK(total - in <= total * qi * (1 + 1e-12));
            CHECK(total - in >= total * qo * (1 - 1e-12));
        }
    }
}

static void test_bad_arguments(void)
{
    fit_rect_t b = {0, 1, 0, 1};
    double v, e;
    err_t err;
    CHECK(fit_box_integral(0, &b, 0, 0, 1e-12, &v, &e, &err) == -EINVAL);
    CHECK(fit_box_integral(-1, &b, 0, 0, 1e-12, &v, &e, &err) == -EINVAL);
    CHECK(fit_box_integral(NAN, &b, 0, 0, 1e-12, &v, &e, &err) == -EINVAL);
    CHECK(fit_box_integral(1, &b, INFINITY, 0, 1e-12, &v, &e, &err) == -EINVAL);
    fit_rect_t flat = {1, 1, 0, 1};
    CHECK(fit_box_integral(1, &flat, 0, 0, 1e-12, &v, &e, &err) == 0 && v == 0);
    fit_rect_t swapped = {1, 0, 0, 1};
    CHECK(fit_box_integral(1, &swapped, 0.3, 0.2, 1e-12, &v, &e, &err) == 0);
    CHECK_NEAR(v, -box(1, 0, 1, 0, 1, 0.3, 0.2), 1e-14, 0);
}

int main(void)
{
    test_reference();
    test_conservation_and_symmetry();
    test_bad_arguments();
    CHECK_DONE();
}
