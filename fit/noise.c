/* noise.c: the two noise models of noise.h (eq. 5 and its DN-consistent form). */
#include "fit/noise.h"

#include <errno.h>
#include <math.h>
#include <string.h>

const char *fit_noise_name(fit_noise_t model)
{
    return model == FIT_NOISE_SHOT_READ ? "shot+read" : "paper";
}

int fit_noise_parse(const char *name, fit_noise_t *model)
{
    if (name && strcmp(name, "paper") == 0) *model = FIT_NOISE_PAPER;
    else if (name && strcmp(name, "shot+read") == 0) *model = FIT_NOISE_SHOT_READ;
    else return -EINVAL;
    return 0;
}

double fit_noise_sigma(fit_noise_t model, const fit_scan_t *scan, double signal_dn)
{
    double s = signal_dn - scan->bias_dn, rg = scan->read_noise_e / scan->gain_e_per_dn;
    if (s < 0) s = 0;
    double var = model == FIT_NOISE_SHOT_READ ? s / scan->gain_e_per_dn + rg * rg /* DN^2 */
                                              : s + rg * rg; /* eq. 5 as printed */
    return sqrt(var / (scan->frames > 0 ? scan->frames : 1));
}
