/* scandata.h: a spot scan of one pixel as the fit sees it: spot positions and the pixel's mean
 * response, with the sensor constants the noise model needs (the scan-file contract of
 * docs/contracts.md, without any I/O). The arrays are borrowed, not owned. */
#ifndef IPSD_FIT_SCANDATA_H
#define IPSD_FIT_SCANDATA_H

#include <stddef.h>

typedef struct fit_scan {
    size_t n;                 /* number of spot positions */
    const double *x_um;       /* spot centres; the pixel spans [0, pitch]^2, y downward */
    const double *y_um;
    const double *signal_dn;  /* mean of `frames` frames, DN, bias included */
    double pitch_um;
    double spot_radius_um;    /* R of eq. 1: first-zero radius of the Airy spot */
    double bias_dn;           /* B: ADC offset */
    double gain_e_per_dn;     /* G */
    double read_noise_e;      /* R of eq. 5 (read noise, electrons) */
    int frames;               /* frames averaged per point */
    double full_scale_dn;     /* points at or above are saturated and left out; <= 0: no limit */
} fit_scan_t;

/* Default ADC full scale (14 bit), used when a scan does not say. */
#define FIT_FULL_SCALE_DEFAULT 16383.0

#endif
