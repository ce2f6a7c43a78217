/* noise.h: the uncertainty sigma_k of a measured mean pixel value, two models.
 *
 * paper:      sigma_k = sqrt(I_obs - B + (R/G)^2) / sqrt(frames), eq. 5 as the paper writes it
 *             (a signal in DN added to a read noise in DN^2, shot term without the gain).
 * shot+read:  sigma_k = sqrt((I_obs - B)/G + (R/G)^2) / sqrt(frames), the consistent DN form:
 *             Poisson variance of (I_obs - B) G electrons is (I_obs - B) G e^2, i.e.
 *             (I_obs - B)/G DN^2, plus read noise (R/G)^2 DN^2.
 * The /sqrt(frames) is the paper's sigma_k / sqrt(12) of eq. 4 for 12 averaged frames.
 * Negative I_obs - B (noise around zero signal) counts as zero signal. Pure functions. */
#ifndef IPSD_FIT_NOISE_H
#define IPSD_FIT_NOISE_H

#include "fit/scandata.h"

typedef enum fit_noise { FIT_NOISE_PAPER = 0, FIT_NOISE_SHOT_READ = 1 } fit_noise_t;

/* "paper" or "shot+read" (static string). */
const char *fit_noise_name(fit_noise_t model);

/* Parses a model name; returns 0, or -EINVAL for an unknown name. */
int fit_noise_parse(const char *name, fit_noise_t *model);

/* sigma (DN) of a mean signal_dn of scan's sensor under the model. */
double fit_noise_sigma(fit_noise_t model, const fit_scan_t *scan, double signal_dn);

#endif
