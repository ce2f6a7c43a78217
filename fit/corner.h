/* corner.h (internal to fit/): how a rectangle's Airy integral is assembled from corner terms.
 *
 * With the spot at the origin, the integral over the corner rectangle [0,u] x [0,v] (u, v >= 0)
 * is F(u,v) = (2/a^2) [Wp(a u, atan(v/u)) + Wp(a v, atan(u/v))] where the wedge integral
 * Wp(w, T) = int_0^T P(w sec t) dt integrates the encircled-energy fraction P (airy.h) along the
 * rays that leave the rectangle through the side x = u (numerics note 2). The flux of the quarter
 * plane outside the rectangle is G(u,v) = pi/a^2 - F(u,v), built the same way from Q = 1 - P.
 * Substituting s = asinh(tan t) makes sec t = cosh s and dt = ds / cosh s, so
 *     W(w, T) = int_0^S f(w cosh s) / cosh s ds,   S = asinh(tan T) = asinh(v/u),
 * whose integrand is smooth, bounded by 1 and decays like 1/cosh s (no trig, no singularity).
 *
 * Any rectangle is the signed sum of its four corners' F (inclusion-exclusion about the spot).
 * When the spot is inside the closed rectangle every sign is + and the F sum has no cancellation.
 * Otherwise the constant pi/a^2 parts cancel exactly and the box is minus the signed sum of the
 * G, which are tail fluxes: comparable to the box itself, not to the whole spot, so boxes far
 * from the spot keep their relative precision. */
#ifndef IPSD_FIT_CORNER_H
#define IPSD_FIT_CORNER_H

#include <math.h>

/* Below this a*u (dimensionless), a side is taken to pass through the spot (u = 0); the error
 * this makes is below a*u times the box's flux. */
#define FIT_CORNER_TINY 1e-13

static inline double corner_sgn(double x) { return (x > 0) - (x < 0); }

/* Combines corner terms into the box integral (without the 2/a^2 factor). u[0] <= u[1] and
 * v[0] <= v[1] are the box edges relative to the spot; fq[j][i] = G, fp[j][i] = F at corner
 * (|u[i]|, |v[j]|), both divided by 2/a^2. *magnitude (may be NULL): the sum of the magnitudes
 * of the terms combined, the scale of the rounding error. */
static inline double corner_combine(const double u[2], const double v[2], double fq[2][2],
                                    double fp[2][2], double *magnitude)
{
    int inside = u[0] <= 0 && u[1] >= 0 && v[0] <= 0 && v[1] >= 0;
    double sum = 0, mag = 0;
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            double s = (i ? 1.0 : -1.0) * (j ? 1.0 : -1.0) * corner_sgn(u[i]) * corner_sgn(v[j]);
            if (s == 0) continue;
            double t = inside ? fp[j][i] : fq[j][i];
            sum += inside ? s * t : -s * t;
            mag += fabs(t);
        }
    if (magnitude) *magnitude = mag;
    return sum;
}

#endif
