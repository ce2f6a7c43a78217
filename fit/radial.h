/* radial.h (internal to fit/): inline evaluation of the Airy radial flux fractions from the
 * build-time tables, for the hot loops of design.c; airy.h's fit_radial is the public wrapper. */
#ifndef IPSD_FIT_RADIAL_H
#define IPSD_FIT_RADIAL_H

#include <math.h>

#include "radial_table.h"

/* Sum of c_k T_k(t), k = 0..order, by Clenshaw's recurrence, t in [-1, 1] (also used by the
 * design matrix's spectral sweeps). Plain multiply-adds: fma() is a library call on baseline
 * x86-64 and would cost more than the whole sum. */
static inline double radial_clenshaw(const double *c, int order, double t)
{
    double b1 = 0, b2 = 0, t2 = 2 * t;
    for (int k = order; k >= 1; k--) {
        double b0 = t2 * b1 + (c[k] - b2);
        b2 = b1;
        b1 = b0;
    }
    return t * b1 + (c[0] - b2);
}

/* J0^2 + J1^2 for v >= RADIAL_Q_VMAX from Hankel's expansions (DLMF 10.17.3)
 * J_nu = sqrt(2 / (pi v)) (P_nu cos chi - Q_nu sin chi), chi = v - (nu/2 + 1/4) pi, which give
 * J0^2 + J1^2 = (2 / (pi v)) [(P0^2 + Q1^2 + Q0^2 + P1^2)/2
 *               + (P0^2 + Q1^2 - Q0^2 - P1^2)/2 sin 2v - (P1 Q1 - P0 Q0) cos 2v]:
 * one sincos instead of two Bessel evaluations, error below 1e-18 relative. */
static inline double radial_hankel_q(double v)
{
    double pq[2][2] = {{0, 0}, {0, 0}}, iv = 1 / v, pw = 1; /* [nu][P or Q] */
    for (int k = 0; k < RADIAL_HANKEL_TERMS; k++) {
        double sgn = (k / 2) % 2 ? -1.0 : 1.0; /* P: sum (-1)^m a_2m / v^2m; Q: (-1)^m a_2m+1 */
        for (int nu = 0; nu < 2; nu++) pq[nu][k % 2] += sgn * radial_hankel[nu][k] * pw;
        pw *= iv;
    }
    double P0 = pq[0][0], Q0 = pq[0][1], P1 = pq[1][0], Q1 = pq[1][1];
    double s2 = sin(2 * v), c2 = cos(2 * v);
    double mean = 0.5 * (P0 * P0 + Q1 * Q1 + Q0 * Q0 + P1 * P1);
    double osc = 0.5 * (P0 * P0 + Q1 * Q1 - Q0 * Q0 - P1 * P1) * s2 - (P1 * Q1 - P0 * Q0) * c2;
    return 2 / (M_PI * v) * (mean + osc);
}

/* *q = J0(v)^2 + J1(v)^2, *p = 1 - *q (see fit_radial in airy.h). */
static inline void radial_eval(double v, double *q, double *p)
{
    if (v < RADIAL_SMALL_V) { /* P = v^2 (P/v^2): full relative precision as v -> 0 */
        double pv = v * v * radial_clenshaw(radial_small[0], RADIAL_SMALL_ORDER,
                                            v * (2.0 / RADIAL_SMALL_V) - 1.0);
        *p = pv;
        *q = 1.0 - pv;
    } else if (v < RADIAL_Q_VMAX) {
        double x = (v - RADIAL_SMALL_V) * (1.0 / RADIAL_Q_WIDTH);
        int i = (int)x;
        if (i >= RADIAL_Q_COUNT) i = RADIAL_Q_COUNT - 1;
        double qv = radial_clenshaw(radial_q[i], RADIAL_Q_ORDER, 2.0 * (x - i) - 1.0);
        *q = qv;
        *p = 1.0 - qv;
    } else { /* beyond the table: Hankel's asymptotic expansion */
        *q = radial_hankel_q(v);
        *p = 1.0 - *q;
    }
}

#endif
