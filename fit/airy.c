/* airy.c: the Airy spot model (eq. 1, eq. 2), its encircled-energy functions from the tables
 * built by gen_radial_table.c, and the envelope bound. */
#include "fit/airy.h"

#include <gsl/gsl_sf_bessel.h>
#include <math.h>

#include "radial.h"

double fit_spot_radius_um(double wavelength_um, double na) { return 1.22 * wavelength_um / (2 * na); }

double fit_airy_a(double R_um) { return M_PI * FIT_RZ / R_um; }

double fit_airy_intensity(double a, double rho)
{
    double v = a * fabs(rho);
    if (v < 1e-4) /* 2 J1(v)/v = 1 - v^2/8 + O(v^4): avoids 0/0 at the centre */
        return (1 - v * v / 8) * (1 - v * v / 8);
    double t = 2 * gsl_sf_bessel_J1(v) / v;
    return t * t;
}

double fit_airy_total(double a) { return 4 * M_PI / (a * a); }

double fit_airy_envelope(double a, double rho)
{
    double v = a * fabs(rho);
    /* (2 J1/v)^2 <= 4 * 0.7858^2 v^(-2/3) / v^2 = 2.47 v^(-8/3); 4 * 0.7858^2 = 2.4700 < 2.4701 */
    double b = v > 0 ? 2.4701 * pow(v, -8.0 / 3.0) : 1.0;
    return b < 1.0 ? b : 1.0;
}

void fit_radial(double v, double *q, double *p) { radial_eval(v, q, p); }

/* Eq. 1, R NA = 1.22 lambda / 2, solved for NA: the same expression with R and NA swapped. */
double fit_spot_na(double wavelength_um, double R_um)
{
    return fit_spot_radius_um(wavelength_um, R_um);
}
