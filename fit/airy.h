/* airy.h: the spot model of the paper. The Airy intensity (eq. 2) of first-zero radius R
 * (eq. 1), its radial flux functions, and a rigorous envelope used to leave out what a scene
 * does not need. Pure functions, thread-safe. Units: micrometres. */
#ifndef IPSD_FIT_AIRY_H
#define IPSD_FIT_AIRY_H

/* Rz = j_{1,1} / pi, the first zero of J1 in units of pi (eq. 2; the paper rounds it to 1.219). */
#define FIT_RZ 1.2196698912665045

/* Eq. 1: first-zero radius R = 1.22 lambda / (2 NA) of a diffraction-limited spot. */
double fit_spot_radius_um(double wavelength_um, double na);

/* The scale a = pi Rz / R (1/um): the unit-peak intensity is [2 J1(a rho) / (a rho)]^2. */
double fit_airy_a(double R_um);

/* Eq. 2 with I0 = 1: intensity at distance rho (um) from the spot centre. */
double fit_airy_intensity(double a, double rho);

/* Whole-plane integral of the unit-peak Airy: 4 pi / a^2 (um^2). */
double fit_airy_total(double a);

/* Rigorous upper bound of fit_airy_intensity: min(1, 2.47 (a rho)^(-8/3)), from Landau's bound
 * |J1(v)| <= 0.7858 v^(-1/3) (numerics note 3). Non-increasing in rho. */
double fit_airy_envelope(double a, double rho);

/* Radial flux fractions at v = a rho: *q = J0(v)^2 + J1(v)^2, the fraction of the whole flux
 * outside the disc of radius rho, and *p = 1 - *q, the fraction inside, each to about 1e-16
 * relative (p keeps its relative precision as v -> 0). v >= 0. */
void fit_radial(double v, double *q, double *p);

/* Eq. 1 solved for the aperture: NA = 1.22 lambda / (2 R), the NA whose spot has first-zero
 * radius R (the inverse of fit_spot_radius_um). */
double fit_spot_na(double wavelength_um, double R_um);

#endif
