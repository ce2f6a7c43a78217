/* test_airy.c: the spot model against independent values: eq. 1 by hand, Rz from GSL's zero of
 * J1, the whole-plane flux of tests/data/airy_box.json, the radial tables against GSL's Bessel
 * functions and the power series, and the envelope as a true upper bound of the intensity. */
#include <gsl/gsl_sf_bessel.h>
#include <jansson.h>

#include "fit/airy.h"
#include "check.h"

int main(void)
{
    /* eq. 1: R = 1.22 * 0.550 / (2 * 0.25) = 1.342 um (the paper rounds to 1.34) */
    CHECK_NEAR(fit_spot_radius_um(0.550, 0.25), 1.342, 1e-15, 0);
    /* j_{1,1} = 3.8317059702075123156 (DLMF table 10.21.1); GSL's zero is 3e-15 off */
    CHECK_NEAR(FIT_RZ, 3.8317059702075123156 / M_PI, 1e-16, 0);
    CHECK_NEAR(FIT_RZ, gsl_sf_bessel_zero_J1(1) / M_PI, 1e-14, 0);
    /* eq. 2 at the first zero: I(R) = 0; at the centre 1 */
    CHECK_NEAR(fit_airy_intensity(fit_airy_a(1.34), 1.34), 0, 0, 1e-28);
    CHECK_NEAR(fit_airy_intensity(fit_airy_a(1.34), 0), 1, 0, 0);

    json_error_t je;
    json_t *ref = json_load_file("airy_box.json", 0, &je);
    CHECK(ref != NULL);
    size_t i;
    json_t *w;
    json_array_foreach(json_object_get(ref, "whole_plane"), i, w)
    {
        double R = json_number_value(json_object_get(w, "R"));
        CHECK_NEAR(fit_airy_total(fit_airy_a(R)), json_number_value(json_object_get(w, "total")),
                   1e-14, 0);
    }
    json_decref(ref);

    /* radial tables: Q = J0^2 + J1^2 against GSL; P = 1 - Q where that does not cancel */
    double worst_q = 0, worst_p = 0;
    for (int k = 0; k < 200000; k++) {
        double v = 0.001 + k * 0.00103, q, p;
        fit_radial(v, &q, &p);
        double j0 = gsl_sf_bessel_J0(v), j1 = gsl_sf_bessel_J1(v), Q = j0 * j0 + j1 * j1;
        worst_q = fmax(worst_q, fabs(q - Q) / Q);
        if (v > 2.5) worst_p = fmax(worst_p, fabs(p - (1 - Q)) / (1 - Q));
        CHECK(fabs(p + q - 1) < 4e-16);
    }
    for (int k = 0; k < 100000; k++) { /* beyond the table: Hankel's expansion */
        double v = 100 + k * 0.0491, q, p;
        fit_radial(v, &q, &p);
        double j0 = gsl_sf_bessel_J0(v), j1 = gsl_sf_bessel_J1(v), Q = j0 * j0 + j1 * j1;
        worst_q = fmax(worst_q, fabs(q - Q) / Q);
    }
    CHECK(worst_q < 5e-15);
    CHECK(worst_p < 5e-15);
    /* small v: P(v) = v^2/4 - v^4/32 + 5 v^6/2304 - ... (1 - J0^2 - J1^2 from the products of
     * the Bessel series, DLMF 10.8.3) */
    for (double v = 1e-6; v < 0.05; v *= 3) {
        double q, p, series = v * v / 4 - pow(v, 4) / 32 + 5 * pow(v, 6) / 2304;
        fit_radial(v, &q, &p);
        CHECK_NEAR(p, series, 1e-13, 0);
    }
    /* the envelope bounds the intensity everywhere (dense sampling to v = 5000) */
    double a = fit_airy_a(1.0), worst_ratio = 0;
    for (int k = 1; k < 2000000; k++) {
        double rho = k * 0.0008, in = fit_airy_intensity(a, rho), env = fit_airy_envelope(a, rho);
        worst_ratio = fmax(worst_ratio, in / env);
    }
    CHECK(worst_ratio <= 1.0);
    CHECK(worst_ratio > 0.8); /* and it is tight (numerics note 3: worst ratio 0.86) */
    CHECK_DONE();
}
