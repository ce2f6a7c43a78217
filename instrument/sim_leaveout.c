/* sim_leaveout.c: the simulator's leave-out rule (sim.h "Integration and the leave-out rule"): the
 * map at every coarser resolution that divides it, and the rigorous bounds that decide, per pixel
 * and spot position, whether to integrate and with which resolution. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>

#include "fit/airy.h"
#include "sim_int.h"

int sim_levels_build(sim_t *s)
{
    int m = s->m;
    double cell = s->cfg.sensor.pitch_um * s->cfg.sensor.pitch_um / ((double)m * m);
    for (int k = 1; k <= m && s->nlv < SIM_MAX_LEVELS; k++) {
        if (m % k && k != m) continue;
        if (s->nlv == SIM_MAX_LEVELS - 1 && k != m) continue; /* keep room for k = m */
        int b = m / k;
        struct sim_level *L = &s->lv[s->nlv];
        L->k = k;
        L->map = calloc((size_t)k * k, sizeof(double));
        if (!L->map) return -ENOMEM;
        s->nlv++;
        /* P_k S: the mean of each b x b block of cells */
        for (int j = 0; j < m; j++)
            for (int i = 0; i < m; i++)
                L->map[(j / b) * k + i / b] += s->map[j * m + i];
        for (int c = 0; c < k * k; c++)
            L->map[c] /= (double)b * b;
        L->l1 = L->max_dev = 0;
        for (int j = 0; j < m; j++)
            for (int i = 0; i < m; i++) {
                double d = fabs(s->map[j * m + i] - L->map[(j / b) * k + i / b]);
                L->l1 += d * cell;
                if (d > L->max_dev) L->max_dev = d;
            }
    }
    return 0;
}

void sim_levels_free(sim_t *s)
{
    for (int l = 0; l < s->nlv; l++)
        free(s->lv[l].map);
    s->nlv = 0;
}

int sim_leaveout_choose(const sim_t *s, double a, double total, double tol, double u, double v,
                        double *bound)
{
    double p = s->cfg.sensor.pitch_um;
    /* d: distance from the spot centre to the nearest point of the pixel [0, p]^2 */
    double dx = u < 0 ? -u : (u > p ? u - p : 0), dy = v < 0 ? -v : (v > p ? v - p : 0);
    double d = hypot(dx, dy), q, pin;
    double env = fit_airy_envelope(a, d); /* I <= env(d) everywhere on the pixel */
    fit_radial(a * d, &q, &pin);          /* the pixel lies outside the disc of radius d */
    /* whole pixel <= max S * min(pixel area * env(d), out(d)) */
    double whole = s->st.max * fmin(p * p * env, total * q);
    if (tol > 0 && whole < tol) {
        *bound = whole;
        return SIM_LEFT_OUT;
    }
    for (int l = 0; l < s->nlv; l++) {
        /* |sum_c (S - P_k S)_c A_c| <= sum_c |S - P_k S|_c A_c, and A_c <= area_c env(d),
         * sum_c A_c <= total q */
        double b = fmin(s->lv[l].l1 * env, s->lv[l].max_dev * total * q);
        if (b == 0 || (tol > 0 && b < tol) || l == s->nlv - 1) {
            *bound = l == s->nlv - 1 ? 0 : b;
            return l;
        }
    }
    *bound = 0;
    return s->nlv - 1;
}
