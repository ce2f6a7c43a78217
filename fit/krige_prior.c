/* krige_prior.c: the prior of the kriged map the fit job stores (krige.h,
 * fit_krige_prior_for_sweep), the one place the pipeline (pipeline.c) and the fidelity harness
 * (instrument/fidelity.c) take it from. Of the piecewise part sum_q tau_q^2 B_q B_q^T of K
 * (docs/numerics.md "The kriged map", eq. for K), it holds the recommended r's divisor grids
 * q >= 2 on the fine grid F, the smallest multiple of r >= FIT_KRIGE_CELLS, so each grid lies
 * exactly on fine cells. Priors with every grid of the sweep (2..r_max on F = 24, each with its
 * own tau_q) and with the recommended r's neighbours added were measured against the truth and
 * rejected: their extra grids fit the noise of exactly piecewise pixels (a flat pixel, a dead
 * corner) and cost 2x (docs/numerics.md "The prior from the sweep"). */
#include "fit/krige.h"

fit_krige_prior_t fit_krige_prior_for_sweep(const fit_sweep_t *sw)
{
    int r = sw ? sw->recommended_r : 0;
    return fit_krige_prior_divisors(r >= 1 && r <= 32 ? r : 1);
}
