/* scan_int.h: what the files of the scan procedure share (internal to instrument/): the stop and
 * progress hooks, and capturing k frames of a region at a stage position (scan_capture.c). */
#ifndef IPSD_INSTRUMENT_SCAN_INT_H
#define IPSD_INSTRUMENT_SCAN_INT_H

#include <stdint.h>

#include "instrument/scan.h"

/* Non-zero when the hooks' stop flag is set. */
int scan_stopped(const scan_hooks_t *h);

/* hooks->progress, when there is one. */
void scan_progress(const scan_hooks_t *h, const char *phase, size_t done, size_t total);

/* What one capture gives: means and variances of the region (caller's arrays). */
struct scan_capture {
    double *mean, *var; /* w*h */
    uint16_t *raw;      /* k*w*h or NULL */
    int64_t *ts_ns;     /* k frame timestamps (backend clock) or NULL */
    uint64_t *ids;      /* k camera frame ids (0: the camera gives none) or NULL */
    int64_t t0_ns;
    double left_out_dn, exposure_us, gain;
    stage_pos_t reported;
};

/* Moves to pos and averages k frames of roi into c (with use_expected, the camera's noiseless
 * expected_dn where it has one). Returns 0 or the camera's / stage's error. */
int scan_capture_at(cam_t *cam, stage_t *stage, const stage_pos_t *pos, const cam_roi_t *roi, int k,
                    int use_expected, struct scan_capture *c, err_t *err);

/* The point of a capture c of k frames of m x m pixels at commanded position pos: index of
 * count, raster cell (ix, iy) or -1, -1 off any raster. Its arrays are c's (not copied). */
scan_point_t scan_point_of_capture(const struct scan_capture *c, size_t index, size_t count,
                                   int ix, int iy, const stage_pos_t *pos, int k, int m);

#endif
