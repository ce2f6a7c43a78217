/* sim_optics.c: the simulated spot's size (sim.h "Optics"): the in-focus radius by eq. 1 (the one
 * formula, fit/airy.h's fit_spot_radius_um), the defocus model, and the focus tolerance. */
#include <math.h>

#include "fit/airy.h"
#include "sim_int.h"

void sim_optics_init(sim_t *s)
{
    const sim_config_t *c = &s->cfg;
    s->R0 = c->radius_um > 0 ? c->radius_um : fit_spot_radius_um(c->wavelength_um, c->na);
    /* with R0 given, NA follows from eq. 1: R NA = 1.22 lambda / 2 is fixed, so
     * NA = R(NA = 1) / R0 */
    double na = c->radius_um > 0 ? fit_spot_radius_um(c->wavelength_um, 1) / c->radius_um : c->na;
    /* quarter-wave depth of focus lambda / (2 NA^2) */
    s->zR = c->depth_um > 0 ? c->depth_um : c->wavelength_um / (2 * na * na);
}

double sim_spot_radius0(const sim_t *s)
{
    return s->R0;
}

double sim_spot_radius(const sim_t *s, double z_um)
{
    /* R(z) = R0 sqrt(1 + ((z - z_focus) / zR)^2), the defocus model of sim.h */
    double dz = (z_um - s->cfg.z_focus_um) / s->zR;
    return s->R0 * sqrt(1 + dz * dz);
}

double sim_focus_tolerance(const sim_t *s)
{
    /* the |z - z_focus| at which R(z) = 1.01 R0 */
    return s->zR * sqrt(1.01 * 1.01 - 1);
}
